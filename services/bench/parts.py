"""Parts 1, 4, 5, 6, 6b, 7, 10 and 11 of ``roco bench``: codec, knowledge, planning, fleet,
memory, task, stop and reading.

Each function measures and returns plain figures; services/bench/report.py turns them into
tables. Existing benchmark scripts are imported, not copied: ``scripts/bench_km.py`` (the
planner's query set, the observation, the timer), ``scripts/bench_planning.py``
(:func:`measure`: plan #1 through a_km and a_pl processes), ``scripts/bench_memory.py``,
``scripts/bench_stop.py`` and ``scripts/bench_reading.py`` (their :func:`measure`).
"""

from __future__ import annotations

import contextlib
import functools
import queue
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import msgspec

from services.bench.messaging import no_access_control, percentile, process_rss_mib
from services.bench.setup_check import check_fleet, check_run_folder
from services.scenario.model import DEFAULT_COMMAND
from shared.fipa_codec import AgentIdentifier, Communicate, Performative, decode, encode
from shared.fipa_codec.batch import unpack

ROOT = Path(__file__).resolve().parents[2]
SCRIPTS = ROOT / "scripts"
POUR = DEFAULT_COMMAND


def scripts_module(name: str) -> Any:
    """Import ``scripts/<name>.py`` (the scripts directory is not a package)."""
    if str(SCRIPTS) not in sys.path:
        sys.path.insert(0, str(SCRIPTS))
    return __import__(name)


# --------------------------------------------------------------------------------- 1. codec
@dataclass
class CodecRow:
    """Per-communicate encode/decode time (µs) for one content size."""

    label: str
    content_bytes: int
    encoded_bytes: int
    encode_us: float
    decode_us: float
    calls: int


def codec(quick: bool) -> list[CodecRow]:
    """msgpack encode and decode (shared/fipa_codec ``encode``/``decode``, strict decoding with
    its size check) of a request communicate with all addressing parameters set, for 200 B,
    10 kB and 1 MB of content. Time per call = a batch's ``perf_counter`` time / its calls;
    the median of 5 batches (after one warm-up batch) is reported."""
    rows = []
    for label, size, calls in (("200 B", 200, 20000), ("10 kB", 10_000, 5000), ("1 MB", 1_000_000, 100)):
        calls = max(10, calls // 10) if quick else calls
        msg = Communicate(
            performative=Performative.REQUEST,
            sender=AgentIdentifier("a_pl"),
            receiver=(AgentIdentifier("a_km"),),
            content=b"x" * size,
            language="L_WM",
            encoding="msgpack",
            ontology="O_RoCo",
            protocol="fipa-query",
            conversation_id="c-0123456789ab",
            reply_with="a_pl-0123456789ab",
            reply_by=1.8e9,
        )
        data = encode(msg)

        def batch(fn: Callable[[], object], n: int) -> float:
            t0 = time.perf_counter()
            for _ in range(n):
                fn()
            return (time.perf_counter() - t0) / n * 1e6

        enc = [batch(lambda m=msg: encode(m), calls) for _ in range(6)][1:]  # type: ignore[misc]
        dec = [batch(lambda d=data: decode(d), calls) for _ in range(6)][1:]  # type: ignore[misc]
        rows.append(CodecRow(label, size, len(data), sorted(enc)[2], sorted(dec)[2], calls))
    return rows


# ----------------------------------------------------------------------------- 4. knowledge
@dataclass
class QueryRow:
    """Answer times (ms) of one query: in a_km's world model, and over Zenoh via a_km."""

    label: str
    local_p50_ms: float
    local_p99_ms: float
    zenoh_p50_ms: float | None = None
    zenoh_p99_ms: float | None = None
    answer_bytes: int = 0


def knowledge(quick: bool, update: Any = None) -> tuple[list[QueryRow], str]:
    """The planner's typical queries and the whole scene (SceneQuery) on the default kitchen
    of ``roco run`` (``update``: another scene; services/bench/scene.py): (a)
    ``WorldModel.answer`` in this process on a fresh on-disk store holding that scene (bench_km's
    timer: 10 warm-up calls, then ``repeats``), (b) the same as a C4 ``query-ref`` (fipa-query,
    L_WM) from a session playing a_pl to a real a_km process through a router, a_km given the
    scene as a_ta gives it (its C6 fipa-subscribe agreed, then informed), timed from the put
    to the ``inform-ref``'s arrival. Returns rows and the store description. Raises
    SetupRefused (services/bench/setup_check.py) when a_km refused, did not understand or
    counted as a protocol violation anything, or answers a query without an ``inform-ref``
    that carries an answer (the jar's and the bowl's poses among them)."""
    km = scripts_module("bench_km")
    from services.agents.knowledge.world_model import WorldModel
    from services.bench.plan_check import Query, plan1_check, plan1_queries
    from services.bench.scene import kitchen_update
    from shared.fipa_codec.languages.l_wm import (
        GraspQuery,
        ObjectQuery,
        PlacementQuery,
        PourQuery,
        SceneQuery,
    )

    scene = update if update is not None else kitchen_update()
    plan_1 = plan1_queries(scene)
    check = plan1_check(plan_1)
    queries: list[tuple[str, Query]] = [
        ("ObjectQuery(jar)", ObjectQuery("jar")),
        ("ObjectQuery(left_gripper)", ObjectQuery("left_gripper")),
        ("GraspQuery(bowl, right)", GraspQuery(object="bowl", arm="right")),
        ("PlacementQuery(bowl, table)", PlacementQuery(object="bowl", surface="table")),
        ("PourQuery(jar, bowl)", PourQuery(source="jar", target="bowl")),
        (f"HypotheticalQuery (plan #1's check, {len(check.steps)} steps)", check),
        ("SceneQuery (whole scene)", SceneQuery()),
    ]
    repeats = 30 if quick else 200
    rows: list[QueryRow] = []
    with tempfile.TemporaryDirectory() as tmp:
        world = WorldModel(Path(tmp) / "km_store")
        world.apply(scene)
        for label, q in queries:
            ms = km.timed(lambda q=q: world.answer(q), repeats)
            size = len(msgspec.msgpack.encode(world.answer(q)))
            rows.append(QueryRow(label, percentile(ms, 50), percentile(ms, 99), answer_bytes=size))
        plan = km.timed(lambda: [world.answer(q) for q in plan_1], max(10, repeats // 10))
        rows.append(
            QueryRow(f"plan #1 query set ({len(plan_1)} queries)", percentile(plan, 50), percentile(plan, 99))
        )
        triples = len(world)
        world.close()
    zenoh_ms = _km_over_zenoh([q for _, q in queries], repeats, scene)
    for row, ms in zip(rows, zenoh_ms, strict=False):
        row.zenoh_p50_ms, row.zenoh_p99_ms = percentile(ms, 50), percentile(ms, 99)
    return rows, f"{triples} triples after the first observation of the default kitchen"


def answer_missing(msg: Communicate) -> str:
    """Why a_km's answer ``msg`` to a query-ref carries no answer ("" when it does): not an
    ``inform-ref``, or an L_WM Answer with nothing set."""
    from shared.fipa_codec.languages import decode_content
    from shared.fipa_codec.languages.l_wm import Answer

    if msg.performative is not Performative.INFORM_REF:
        return f"{msg.performative.value} {msg.content[:120].decode('utf-8', 'replace')}"
    got = decode_content(msg.language, msg.content) if msg.language else None
    if not isinstance(got, Answer) or got == Answer():
        return "an empty answer"
    return ""


def _km_over_zenoh(queries: list[Any], repeats: int, scene: Any) -> list[list[float]]:
    from services.bench.scene import SceneSource, communicate, require_known
    from services.bench.setup_check import SetupRefused, check_agents
    from services.fleet.launcher import Fleet, free_port
    from services.runtime import keys
    from services.runtime.session import open_client

    out: list[list[float]] = []
    with no_access_control(), tempfile.TemporaryDirectory() as tmp:
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

                session.declare_subscriber(keys.fipa_key("C4", "a_km", "a_pl"), on_answer)
                source = SceneSource(session, scene)
                fleet.start_agents(["a_km"])
                fleet.wait_alive(session, ["a_km"], timeout=60)
                source.start()
                missing = source.wait_known()
                check_agents(session, ["a_km"], "giving a_km the scene")
                require_known(missing)
                key = keys.fipa_key("C4", "a_pl", "a_km")
                for qi, q in enumerate(queries):
                    times = []
                    for i in range(10 + repeats):
                        cid = f"bench-{qi}-{i}"
                        payload = encode(
                            communicate(
                                "a_pl",
                                "a_km",
                                Performative.QUERY_REF,
                                q,
                                protocol="fipa-query",
                                conversation_id=cid,
                                reply_with=cid,
                            )
                        )
                        t0 = time.perf_counter()
                        session.put(key, payload)
                        while True:
                            try:
                                t1, raw = answers.get(timeout=30)
                            except queue.Empty:
                                raise SetupRefused(f"a_km did not answer {cid} within 30 s") from None
                            msg = decode(raw)
                            if msg.conversation_id == cid:
                                break
                        if i == 0 and (why := answer_missing(msg)):
                            raise SetupRefused(f"a_km answered {type(q).__name__} with {why}")
                        if i >= 10:
                            times.append((t1 - t0) * 1e3)
                    out.append(times)
                check_agents(session, ["a_km"], "querying a_km")
            finally:
                session.close()
        finally:
            fleet.stop()
    return out


# ------------------------------------------------------------------------------ 5. planning
@dataclass
class PlanningFigures:
    """Plan #1 repeated (bench_planning) and the plans of the task run."""

    repeated: list[tuple[float, float, int, int]]
    """(request → plan s, a_pl planning time s, a_km queries, plan leaves) per request"""


def planning(quick: bool) -> PlanningFigures:
    """``scripts/bench_planning.py``'s :func:`measure`: router, a_km and a_pl processes, the
    default kitchen given to a_km through its C6 fipa-subscribe, plan #1 of pour(jar, bowl)
    requested 5 (quick: 2) times in a row, each checked to be plan #1 of ``roco run``'s pour.
    Raises SetupRefused when the set-up went wrong or another plan came."""
    bp = scripts_module("bench_planning")
    with no_access_control():
        return PlanningFigures(bp.measure(2 if quick else 5))


# --------------------------------------------------------------------------------- 6. fleet
@dataclass
class FleetFigures:
    """``roco up`` to all agents alive, and each process's memory once up."""

    command_s: float
    alive_s: float | None
    rss_mib: dict[str, float]
    output: str
    error: str = ""


def roco_cmd(*args: str) -> list[str]:
    """The command line of ``roco ARGS`` with this interpreter."""
    return [sys.executable, "-m", "services.cli", *args]


def fleet() -> FleetFigures:
    """``roco up --port P --runs-dir TMP --no-realtime`` (its own wall time from start to
    exit, and the "fleet up in X s" it prints: from starting the agents to every liveliness
    token), then VmRSS of each process it started (pids from its ``.fleet.json``), then
    ``roco down``. Raises SetupRefused when, once up, an agent counted anything refused, not
    understood or against its protocol (services/bench/setup_check.py)."""
    from services.fleet.launcher import free_port

    with tempfile.TemporaryDirectory() as tmp:
        runs = Path(tmp)
        up = roco_cmd("up", "--port", str(free_port()), "--runs-dir", str(runs), "--no-realtime")
        t0 = time.perf_counter()
        try:
            done = subprocess.run(up, cwd=ROOT, capture_output=True, text=True, timeout=240, check=False)
        except subprocess.TimeoutExpired:
            done = None
        command_s = time.perf_counter() - t0
        rss: dict[str, float] = {}
        state = runs / ".fleet.json"
        try:
            if state.exists():
                pids = msgspec.json.decode(state.read_bytes())["pids"]
                rss = {name: process_rss_mib(int(pid)) for name, pid in pids.items()}
                if done is not None and done.returncode == 0:
                    check_fleet(runs, "roco up")
        finally:
            subprocess.run(
                roco_cmd("down", "--runs-dir", str(runs)),
                cwd=ROOT,
                capture_output=True,
                timeout=120,
                check=False,
            )
        if done is None:
            return FleetFigures(command_s, None, rss, "", "roco up did not finish within 240 s")
        text = (done.stdout + done.stderr).strip()
        alive = None
        if " in " in text and "fleet up" in text:
            with contextlib.suppress(ValueError):
                alive = float(text.split("fleet up", 1)[1].split(" in ", 1)[1].split(" s", 1)[0])
        return FleetFigures(
            command_s, alive, rss, text, "" if done.returncode == 0 else f"exit {done.returncode}"
        )


# ------------------------------------------------------------------------------- 6b. memory
@dataclass
class MemoryFigures:
    """(VmRSS, PSS) in MiB per process: an idle synthetic pair and its router (``synthetic``),
    and ``roco up``'s fleet with its children, by state (``fleet, camera process running``,
    ``fleet at rest``; scripts/bench_memory.py)."""

    synthetic: dict[str, tuple[float, float]]
    fleet: dict[str, dict[str, tuple[float, float]]]


def memory() -> MemoryFigures:
    """scripts/bench_memory.py's ``synthetic`` and ``fleet`` with its default settling (VmRSS
    steady within 0.25 MiB over 1 s, at most 15 s; the camera process waited for up to
    ``ROCO_CAMERA_IDLE_S`` + 30 s). Raises RuntimeError when ``roco up`` fails."""
    bm = scripts_module("bench_memory")

    def settle(pids: dict[str, int]) -> dict[str, float]:
        return dict(bm.settled_rss(pids, 1.0, 0.25, 15.0))

    return MemoryFigures(bm.synthetic(settle), bm.fleet(settle, bm.camera_idle_s() + 30.0))


# ---------------------------------------------------------------------------------- 7. task
@dataclass
class TaskRun:
    """One ``roco run`` of the pour."""

    pacing: str
    command_s: float
    ok: bool
    detail: str
    run_dir: Path | None
    sim_time_s: float | None = None
    communicates: int | None = None
    timing: Any = None
    plans: list[Any] = field(default_factory=list)
    km_store_bytes: int | None = None
    task_s: float | None = None
    """From the command given to a_hi to the end of the run (run.json)."""


def _roco_run(args: list[str]) -> tuple[bool, list[str], float]:
    """``roco ARGS`` within 400 s: whether it succeeded, its last line of output, its wall time."""
    t0 = time.perf_counter()
    try:
        done = subprocess.run(
            roco_cmd(*args), cwd=ROOT, capture_output=True, text=True, timeout=400, check=False
        )
        ok, detail = done.returncode == 0, (done.stdout + done.stderr).strip().splitlines()[-1:]
    except subprocess.TimeoutExpired:
        ok, detail = False, ["roco run did not finish within 400 s"]
    return ok, detail, time.perf_counter() - t0


def _read_run_folder(out: TaskRun, run_dir: Path) -> None:
    """``out``'s figures from its run folder, each left unset when it cannot be read."""
    from services.report import build_report
    from services.runtime.run_folder import read_run_info

    with contextlib.suppress(Exception):
        info = read_run_info(run_dir)
        if info.command_sent is not None and info.ended is not None:
            out.task_s = info.ended - info.command_sent
    with contextlib.suppress(Exception):
        report = build_report(run_dir)
        out.communicates = report.sizes.count
        out.plans = list(report.plans)
        out.timing = report.control
        if report.control is not None:
            out.sim_time_s = report.control.sim_time
    store = run_dir / "km_store"
    if store.is_dir():
        out.km_store_bytes = sum(f.stat().st_size for f in store.rglob("*") if f.is_file())


def task(realtime: bool, runs_dir: Path) -> TaskRun:
    """``roco run "pour the jar into the bowl" --quiet --runs-dir DIR`` (``--realtime`` when
    asked); then its run folder: run.json, ag_ex_timing.json, the report's plans, and the size
    of a_km's store directory. Raises SetupRefused when an agent counted anything refused, not
    understood or against its protocol in a run that succeeded (its ``counters.json``,
    services/bench/setup_check.py); a failed run is reported as failed."""
    args = ["run", POUR, "--quiet", "--runs-dir", str(runs_dir)] + (["--realtime"] if realtime else [])
    before = set(runs_dir.glob("*")) if runs_dir.exists() else set()
    ok, detail, command_s = _roco_run(args)
    pacing = "real time (--realtime)" if realtime else "as fast as possible"
    new = sorted(p for p in set(runs_dir.glob("*")) - before if p.is_dir())
    if not new:
        return TaskRun(pacing, command_s, False, " ".join(detail) or "no run folder", None)
    run_dir = new[-1]
    out = TaskRun(pacing, command_s, ok, " ".join(detail), run_dir)
    _read_run_folder(out, run_dir)
    if ok:
        check_run_folder(run_dir, f"the pour ({pacing}, {run_dir})")
    return out


# ----------------------------------------------------------------------------------- 10. stop
def stop(halts: int) -> Any:
    """``scripts/bench_stop.py``'s :func:`measure`: a fleet as ``roco run`` starts it, ag_ex's
    loop as fast as it can, pours stopped at random moments until each condition (``plain``,
    ``long line before``) has ``halts`` halts; a line per stop on stderr as it is measured.
    Returns its ``StopFigures``; raises RuntimeError when the fleet cannot pour, SetupRefused
    when an agent counted anything refused, not understood or against its protocol in the
    first pour."""
    bs = scripts_module("bench_stop")
    return bs.measure(halts, echo=functools.partial(print, file=sys.stderr, flush=True))


# -------------------------------------------------------------------------------- 11. reading
def reading(repeats: int) -> list[Any]:
    """``scripts/bench_reading.py``'s :func:`measure`: a_hi on an in-memory bus, ``repeats``
    timed lines per shape and length. Returns its ``ReadingRow``s."""
    return list(scripts_module("bench_reading").measure(repeats))
