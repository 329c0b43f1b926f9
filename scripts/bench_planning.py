"""Planning benchmark: how long a_pl takes to produce plan #1 of the pour, including every
knowledge query to a_km (the target: services/bench/report.py ``TARGET_PLAN_1_S``; the paper's
took 55 s with ~1,600 C4 communicates; docs/benchmarks.md).

Starts a Zenoh router and the a_km and a_pl processes only (``services.runtime.main``, a
run folder in a temporary directory, a_km on its on-disk Oxigraph store), gives a_km the
initial observation of the kitchen as a_ta would (C6 inform, the poses of kitchen.xml), then
plays a_co: sends ``--runs`` plan requests for ``pour(jar, bowl)`` (C3 fipa-request) one
after another and times each from the request's publication to the plan's arrival (wall
clock of this process). Prints per run the time, a_pl's own planning time and its count of
a_km queries, then min/median/max.

Usage: ``python scripts/bench_planning.py [--runs 20]``
"""

from __future__ import annotations

import argparse
import queue
import statistics
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import benchlib  # noqa: E402  (scripts/benchlib.py, beside this file)

from services.fleet.launcher import Fleet, free_port  # noqa: E402
from services.runtime import keys  # noqa: E402
from services.runtime.session import open_client  # noqa: E402
from shared.fipa_codec import AgentIdentifier, Communicate, Performative, decode, encode  # noqa: E402
from shared.fipa_codec.batch import unpack  # noqa: E402
from shared.fipa_codec.languages import decode_content, encode_content  # noqa: E402
from shared.fipa_codec.languages.common import Pose  # noqa: E402
from shared.fipa_codec.languages.l_hc import TaskAtom  # noqa: E402
from shared.fipa_codec.languages.l_hfsm import GroundTaskNetwork, HierarchicalPlan  # noqa: E402
from shared.fipa_codec.languages.l_wm import ObjectUpdate, WorldUpdate  # noqa: E402

SCENE = {"jar": (0.7, 0.2, 0.85), "bowl": (0.7, -0.2, 0.85), "cup": (0.9, 0.0, 0.85)}


def communicate(sender: str, receiver: str, perf: Performative, content: object, **kw: object) -> bytes:
    language, body = encode_content(content)  # type: ignore[arg-type]
    msg = Communicate(
        performative=perf,
        sender=AgentIdentifier(sender),
        receiver=(AgentIdentifier(receiver),),
        content=body,
        language=language,
        encoding="msgpack",
        ontology="O_RoCo",
        **kw,  # type: ignore[arg-type]
    )
    return encode(msg)


def measure(runs: int) -> list[tuple[float, float, int, int]]:
    """Start router, a_km and a_pl, give a_km the scene, request plan #1 ``runs`` times; per
    run (request → plan wall time s, a_pl's own planning time s, a_km queries, plan leaves).
    Raises RuntimeError when a_pl answers without a plan (also used by ``roco bench``)."""
    with tempfile.TemporaryDirectory() as tmp:
        run_dir = Path(tmp)
        (run_dir / "logs").mkdir()
        endpoint = f"tcp/127.0.0.1:{free_port()}"
        fleet = Fleet(run_dir, endpoint)
        answers: queue.SimpleQueue[tuple[float, bytes]] = queue.SimpleQueue()
        try:
            fleet.start_router()
            session = open_client(endpoint)

            def on_answer(s: Any) -> None:  # a zenoh.Sample; a batch: each of its communicates
                for p in unpack(s.payload.to_bytes()):
                    answers.put((time.perf_counter(), p))

            session.declare_subscriber(
                keys.fipa_key("C3", "a_pl", "a_co"),
                on_answer,
            )
            session.declare_subscriber(keys.inbox_key("a_ta"), lambda s: None)  # a_km's subscribe
            fleet.start_agents(["a_km", "a_pl"])
            fleet.wait_alive(session, ["a_km", "a_pl"], timeout=60)
            update = WorldUpdate(
                stamp=0.0, objects=tuple(ObjectUpdate(name=n, pose=Pose(p)) for n, p in SCENE.items())
            )
            session.put(
                keys.fipa_key("C6", "a_ta", "a_km"),
                communicate(
                    "a_ta",
                    "a_km",
                    Performative.INFORM,
                    update,
                    protocol="fipa-subscribe",
                    conversation_id="km-environment",
                ),
            )
            rows = []
            for i in range(1, runs + 1):
                gtn = GroundTaskNetwork(task_id=f"bench-{i}", tasks=(TaskAtom("pour", ("jar", "bowl")),))
                payload = communicate(
                    "a_co",
                    "a_pl",
                    Performative.REQUEST,
                    gtn,
                    protocol="fipa-request",
                    conversation_id=f"bench-{i}",
                    reply_with=f"bench-{i}",
                )
                t0 = time.perf_counter()
                session.put(keys.fipa_key("C3", "a_co", "a_pl"), payload)
                while True:
                    t1, raw = answers.get(timeout=60)
                    msg = decode(raw)
                    if msg.conversation_id == f"bench-{i}" and msg.performative is not Performative.AGREE:
                        break
                plan = decode_content(msg.language, msg.content) if msg.language else None
                if not isinstance(plan, HierarchicalPlan):
                    raise RuntimeError(f"run {i}: no plan ({msg.performative.value}: {msg.content[:200]!r})")
                rows.append((t1 - t0, plan.planning_time_s, plan.km_queries, len(plan.root.leaves())))
            session.close()
        finally:
            fleet.stop()
    return rows


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--runs", type=int, default=20)
    args = parser.parse_args()
    from services.bench.messaging import no_access_control

    try:
        with no_access_control():  # this Zenoh session plays a_co, which the fleet's ACL would refuse
            rows = measure(args.runs)
    except RuntimeError as exc:
        print(exc)
        return 1
    print(
        f"# a_pl plan #1 of pour(jar, bowl), {args.runs} requests over Zenoh (router + a_km + a_pl processes)"
    )
    print(f"Machine: {benchlib.machine(('eclipse-zenoh', 'pyoxigraph', 'gtpyhop-core'))}")
    print()
    print("| run | request → plan (s) | a_pl planning time (s) | a_km queries | plan leaves |")
    print("|---|---|---|---|---|")
    for i, (wall, own, queries, leaves) in enumerate(rows, 1):
        print(f"| {i} | {wall:.3f} | {own:.3f} | {queries} | {leaves} |")
    walls = [r[0] for r in rows]
    print()
    print(
        f"request → plan: min {min(walls):.3f} s, median {statistics.median(walls):.3f} s, "
        f"max {max(walls):.3f} s; a_km queries per plan: {rows[0][2]}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
