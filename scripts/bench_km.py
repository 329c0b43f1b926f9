"""Benchmark of a_km's knowledge base (services/agents/knowledge/world_model.py): answer times of the
L_WM queries, update times, and the whole query set of a plan, on the on-disk Oxigraph store
and in memory.

Builds a :class:`WorldModel` on a fresh store in a temporary directory ("disk") and one in
memory ("memory"), gives each ``roco run``'s default kitchen (services/bench/scene.py), then
times with ``time.perf_counter`` over ``--repeats`` calls each (after 10 warm-up calls):

- the structured queries a_pl sends: ObjectQuery (a gripper, the jar), SceneQuery,
  GraspQuery, PlacementQuery, PourQuery;
- a SPARQL ASK, and the HypotheticalQuery a_pl sends to check plan #1 (its steps, each one's
  preconditions checked in a copy of the knowledge, then its goal);
- ``plan #1 query set``: every query a_pl sends for "pour the jar into the bowl", in a row, as
  a_pl makes them in this process on the same kitchen (services/bench/plan_check.py
  ``plan1_queries``), answered directly (no transport);
- ``apply``: one observation of two poses (one transaction; "disk": written to the WAL),
  and on disk ``apply + flush`` (memtables to fsynced table files);
- ``open (kept)``: opening the existing on-disk store again (the restart of a_km);
- for reference, the same SPARQL ASK on rdflib's own in-memory store and engine.

Prints p50 / p99 / mean in milliseconds, the msgpack sizes of the answers, and the machine.
Figures, not checks: nothing is asserted (the planner's budget is 2 s for plan #1 with all
its queries; the query set is reported against it).

Usage: ``python scripts/bench_km.py [--repeats 200]``
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import benchlib  # scripts/benchlib.py, beside this file
import msgspec
from rdflib import Graph

from services.agents.knowledge.world_model import ROCO, Query, WorldModel
from services.bench.plan_check import plan1_check, plan1_queries
from services.bench.scene import kitchen_update
from shared.fipa_codec.languages.common import Pose
from shared.fipa_codec.languages.l_wm import (
    GraspQuery,
    ObjectQuery,
    ObjectUpdate,
    PlacementQuery,
    PourQuery,
    SceneQuery,
    SparqlQuery,
    WorldUpdate,
)

ASK = SparqlQuery("ASK { roco:jar roco:in roco:cabinet . roco:jar roco:hasPose ?p }")


def observation(stamp: float) -> WorldUpdate:
    return WorldUpdate(
        stamp=stamp,
        objects=(
            ObjectUpdate(name="jar", pose=Pose((0.80, 0.22, 0.90)), particles=18),
            ObjectUpdate(name="bowl", pose=Pose((0.80, -0.20, 0.90)), particles=0),
        ),
        total_particles=18,
    )


def timed(fn: Callable[[], object], repeats: int, warmup: int = 10) -> list[float]:
    """Milliseconds per call."""
    for _ in range(warmup):
        fn()
    out = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        out.append((time.perf_counter() - t0) * 1e3)
    return out


def row(label: str, ms: list[float]) -> str:
    ordered = sorted(ms)
    p99 = ordered[min(len(ordered) - 1, round(0.99 * (len(ordered) - 1)))]
    return f"  {label:<34} {statistics.median(ms):9.3f} {p99:9.3f} {statistics.fmean(ms):9.3f}"


def machine() -> str:
    return benchlib.machine(("pyoxigraph", "oxrdflib", "rdflib"))


def bench(name: str, world: WorldModel, repeats: int, plan_1: tuple[Query, ...]) -> None:
    check = plan1_check(plan_1)
    print(f"\n{name}: {len(world)} triples            p50 ms    p99 ms   mean ms")
    queries: list[tuple[str, Query]] = [
        ("ObjectQuery(left_gripper)", ObjectQuery("left_gripper")),
        ("ObjectQuery(jar)", ObjectQuery("jar")),
        ("SceneQuery", SceneQuery()),
        ("GraspQuery(bowl, right)", GraspQuery(object="bowl", arm="right")),
        ("PlacementQuery(bowl, table)", PlacementQuery(object="bowl", surface="table")),
        ("PourQuery(jar, bowl)", PourQuery(source="jar", target="bowl")),
        ("SparqlQuery ASK", ASK),
        (f"HypotheticalQuery (plan #1's check, {len(check.steps)} steps)", check),
    ]
    for label, query in queries:
        print(row(label, timed(lambda q=query: world.answer(q), repeats)))  # type: ignore[misc]
    plan = timed(lambda: [world.answer(q) for q in plan_1], max(20, repeats // 10))
    print(row(f"plan #1 query set ({len(plan_1)} queries)", plan))
    stamp = [10.0]

    def apply() -> None:
        stamp[0] += 0.1
        world.apply(observation(stamp[0]))

    print(row("apply (2 poses)", timed(apply, repeats)))
    if world.path is not None:
        world.flush_each_update = True
        print(row("apply + flush (2 poses)", timed(apply, max(20, repeats // 10))))
        world.flush_each_update = False
    sizes = {
        label: len(msgspec.msgpack.encode(world.answer(q)))
        for label, q in (("left_gripper", ObjectQuery("left_gripper")), ("jar", ObjectQuery("jar")))
    }
    sizes["scene"] = len(msgspec.msgpack.encode(world.answer(SceneQuery())))
    print("  answer sizes (msgpack, B): " + ", ".join(f"{k} {v}" for k, v in sizes.items()))
    print(f"  plan #1 budget: the query set takes {statistics.median(plan):.1f} ms of the 2000 ms")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=200)
    args = parser.parse_args()
    print(machine())
    plan_1 = plan1_queries()
    with tempfile.TemporaryDirectory() as tmp:
        store = Path(tmp) / "km_store"
        t0 = time.perf_counter()
        disk = WorldModel(store)
        created_ms = (time.perf_counter() - t0) * 1e3
        disk.apply(kitchen_update())
        bench(f"disk ({store.name}, created and filled in {created_ms:.0f} ms)", disk, args.repeats, plan_1)
        disk.close()

        def reopen() -> None:
            WorldModel(store).close()

        print(row("open (kept) + close", timed(reopen, 10, warmup=1)))
    memory = WorldModel()
    memory.apply(kitchen_update())
    bench("memory (Oxigraph, no directory)", memory, args.repeats, plan_1)

    reference = Graph()
    for t in memory.triples():
        reference.add(t)
    text = ASK.query
    print("\nreference: rdflib's Memory store and SPARQL engine      p50 ms    p99 ms   mean ms")
    print(row("SparqlQuery ASK", timed(lambda: reference.query(text, initNs={"roco": ROCO}).askAnswer, 50)))
    memory.close()


if __name__ == "__main__":
    main()
