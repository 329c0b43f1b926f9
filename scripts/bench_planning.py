"""Planning benchmark: how long a_pl takes to produce plan #1 of the pour, including every
knowledge query to a_km (the target: services/bench/report.py ``TARGET_PLAN_1_S``; the paper's
took 55 s with ~1,600 C4 communicates; docs/benchmarks.md).

Starts a Zenoh router and the a_km and a_pl processes only (``services.runtime.main``, a
run folder in a temporary directory, a_km on its on-disk Oxigraph store) and gives a_km the
default kitchen of ``roco run`` as a_ta does: it agrees to a_km's C6 fipa-subscribe, then
informs the first observation (services/bench/scene.py). Then it plays a_co: sends
``--runs`` plan requests for ``pour(jar, bowl)`` (C3 fipa-request) one after another and
times each from the request's publication to the plan's arrival (wall clock of this
process). Prints per run the time, a_pl's own planning time, its count of a_km queries and
the plan's leaves, then min/median/max.

It prints no figure (one line ``roco: …``, exit 1) when its set-up went wrong: an agent
refused, did not understand or counted as a protocol violation anything (their counters,
services/bench/setup_check.py), a_km does not know the jar's and the bowl's poses once given
the scene, or a timed plan is not plan #1 of the pour as ``roco run`` makes it (its leaves and
actions, services/bench/plan_check.py).

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

from services.bench.plan_check import expected_plan, pour_request, require_same  # noqa: E402
from services.bench.scene import SceneSource, kitchen_update, require_known  # noqa: E402
from services.bench.setup_check import SetupRefused, check_agents  # noqa: E402
from services.fleet.launcher import Fleet, free_port  # noqa: E402
from services.runtime import keys  # noqa: E402
from services.runtime.session import open_client  # noqa: E402
from shared.fipa_codec import Performative, decode  # noqa: E402
from shared.fipa_codec.batch import unpack  # noqa: E402
from shared.fipa_codec.languages import decode_content  # noqa: E402
from shared.fipa_codec.languages.l_hfsm import HierarchicalPlan  # noqa: E402
from shared.fipa_codec.languages.l_wm import WorldUpdate  # noqa: E402

AGENTS = ["a_km", "a_pl"]


def measure(
    runs: int, update: WorldUpdate | None = None, *, agree_first: bool = True
) -> list[tuple[float, float, int, int]]:
    """Start router, a_km and a_pl, give a_km the scene, request plan #1 ``runs`` times; per
    run (request → plan wall time s, a_pl's own planning time s, a_km queries, plan leaves).
    ``update``: the scene given (default: the default kitchen, ``kitchen_update``);
    ``agree_first`` False plants the broken set-up of ``SceneSource``. Raises SetupRefused
    (module docstring) when the set-up went wrong or a timed plan is not plan #1 of the pour
    (also used by ``roco bench``)."""
    expected = expected_plan()
    scene = update if update is not None else kitchen_update()
    with tempfile.TemporaryDirectory() as tmp:
        run_dir = Path(tmp)
        (run_dir / "logs").mkdir()
        endpoint = f"tcp/127.0.0.1:{free_port()}"
        fleet = Fleet(run_dir, endpoint)
        answers: queue.SimpleQueue[tuple[float, bytes]] = queue.SimpleQueue()
        try:
            fleet.start_router()
            session = open_client(endpoint)
            try:

                def on_answer(s: Any) -> None:  # a zenoh.Sample; a batch: each of its communicates
                    for p in unpack(s.payload.to_bytes()):
                        answers.put((time.perf_counter(), p))

                session.declare_subscriber(keys.fipa_key("C3", "a_pl", "a_co"), on_answer)
                source = SceneSource(session, scene, agree_first=agree_first)
                fleet.start_agents(AGENTS)
                fleet.wait_alive(session, AGENTS, timeout=60)
                source.start()
                missing = source.wait_known()
                check_agents(session, AGENTS, "giving a_km the scene")
                require_known(missing)
                rows = [_timed(session, answers, i, expected) for i in range(1, runs + 1)]
                check_agents(session, AGENTS, "planning")
            finally:
                session.close()
        finally:
            fleet.stop()
    return rows


def _timed(
    session: Any, answers: queue.SimpleQueue[tuple[float, bytes]], i: int, expected: HierarchicalPlan
) -> tuple[float, float, int, int]:
    """Request plan #1 as a_co (conversation ``bench-<i>``) and time it; its row of
    :func:`measure`. Raises SetupRefused when no plan, or another plan than ``expected``, comes."""
    t0 = time.perf_counter()
    session.put(keys.fipa_key("C3", "a_co", "a_pl"), pour_request(i))
    while True:
        try:
            t1, raw = answers.get(timeout=60)
        except queue.Empty:
            raise SetupRefused(f"run {i}: no answer from a_pl within 60 s") from None
        msg = decode(raw)
        if msg.conversation_id == f"bench-{i}" and msg.performative is not Performative.AGREE:
            break
    plan = decode_content(msg.language, msg.content) if msg.language else None
    if not isinstance(plan, HierarchicalPlan):
        raise SetupRefused(f"run {i}: no plan ({msg.performative.value}: {msg.content[:200]!r})")
    require_same(plan, expected)
    return t1 - t0, plan.planning_time_s, plan.km_queries, len(plan.root.leaves())


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
    except SetupRefused as exc:
        print(f"roco: bench_planning: {exc}", file=sys.stderr)
        return 1
    print(
        f"# a_pl plan #1 of pour(jar, bowl), {args.runs} requests over Zenoh (router + a_km + a_pl "
        "processes; a_km given the default kitchen through its C6 fipa-subscribe)"
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
        f"max {max(walls):.3f} s; a_km queries per plan: {rows[0][2]}; "
        f"leaves: {rows[0][3]} (plan #1 of roco run's pour)"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
