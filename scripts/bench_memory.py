"""Resident memory of roco's processes once started and idle (docs/benchmarks.md, part 6b).

- **fleet**: ``roco up --port P --runs-dir TMP --no-realtime`` in a subprocess, exactly as an
  operator starts it (router on a free loopback port, recorder, the six agents; access control
  on, as ``roco up`` does by default; every process started by ``subprocess``: a fresh
  interpreter, spawn semantics) and their children by name (ag_ex's ``velma-loop`` and
  ``velma-camera``), measured twice: settled after start (the camera process running: it has
  answered a_ta's first Observe) and again at rest, once the camera process has ended
  (``ROCO_CAMERA_IDLE_S`` after its last Observe); then ``roco down``: only the processes it
  started end.
- **synthetic**: an idle pair of the benchmark's synthetic agents (``b_ini0``/``b_par0``,
  services/bench/messaging.py: a real ``Agent`` on a ``ZenohTransport``) on a router of their
  own on a free loopback port, started as ``roco bench`` starts them (multiprocessing spawn).

Memory: ``VmRSS`` of ``/proc/<pid>/status`` (MiB = 2**20 bytes), and beside it ``Pss`` of
``/proc/<pid>/smaps_rollup`` (each shared page — Zenoh's and Python's libraries, shared
memory — divided among the processes that map it): the sum of VmRSS counts a library every
process maps once per process, the sum of PSS counts it once, so PSS's total is the memory a
fleet takes in all. A process counts as idle once
its VmRSS changed by less than ``--tolerance-mib`` over ``--quiet-s`` seconds (sampled every
0.1 s, at most ``--max-wait-s``): start-up allocations are over, nothing is being sent.
Also ``--imports``: the heavy libraries (physics, plotting, RDF, numerics) each agent's process
has in ``sys.modules`` once its module is imported, as ``services.runtime.main`` imports it.

Usage: ``python scripts/bench_memory.py [--only fleet,synthetic,imports] [--json]``
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from services.bench.messaging import process_pss_mib as pss_mib  # noqa: E402  (PSS, MiB)
from services.bench.messaging import process_rss_mib as rss_mib  # noqa: E402  (VmRSS, MiB)
from velma.executor.camera_process import PROCESS_NAME as CAMERA_PROCESS  # noqa: E402
from velma.executor.camera_process import camera_idle_s  # noqa: E402

HEAVY = ("mujoco", "pinocchio", "matplotlib", "rerun", "rdflib", "pyoxigraph", "numpy", "scipy", "typer")
"""Libraries whose presence in an agent's process is reported by ``--imports``."""


def settled_rss(
    pids: dict[str, int], quiet_s: float, tolerance_mib: float, max_wait_s: float
) -> dict[str, float]:
    """VmRSS (MiB) of every process in ``pids`` once none changed by more than
    ``tolerance_mib`` over the last ``quiet_s`` seconds (or after ``max_wait_s``)."""
    history: list[tuple[float, dict[str, float]]] = []
    t0 = time.monotonic()
    while True:
        now = time.monotonic()
        sample = {name: rss_mib(pid) for name, pid in pids.items()}
        history.append((now, sample))
        window = [s for t, s in history if now - t <= quiet_s]
        steady = now - t0 >= quiet_s and all(
            max(s[n] for s in window) - min(s[n] for s in window) <= tolerance_mib for n in pids
        )
        if steady or now - t0 >= max_wait_s:
            return sample
        time.sleep(0.1)


def children(pid: int) -> list[int]:
    """The child processes of ``pid`` (from ``/proc/<pid>/task/*/children``), in pid order,
    not counting the resource tracker that multiprocessing's spawn starts beside a child."""
    found: set[int] = set()
    for task in Path(f"/proc/{pid}/task").glob("*"):
        try:
            found.update(int(c) for c in (task / "children").read_text().split())
        except OSError:
            continue
    out = []
    for child in sorted(found):
        try:
            cmdline = Path(f"/proc/{child}/cmdline").read_bytes()
        except OSError:
            continue
        if b"resource_tracker" not in cmdline:
            out.append(child)
    return out


def with_pss(rss: dict[str, float], pids: dict[str, int]) -> dict[str, tuple[float, float]]:
    """(VmRSS, PSS) in MiB of every process of ``rss`` (PSS read now)."""
    return {name: (v, pss_mib(pids[name])) for name, v in rss.items()}


def comm(pid: int) -> str:
    """The process's name (``/proc/<pid>/comm``; ag_ex names its children ``velma-loop`` and
    ``velma-camera``), or "" when it is gone."""
    try:
        return Path(f"/proc/{pid}/comm").read_text().strip()
    except OSError:
        return ""


def fleet(
    settle: Callable[[dict[str, int]], dict[str, float]], rest_timeout_s: float
) -> dict[str, dict[str, tuple[float, float]]]:
    """``roco up`` on a free port into a temporary runs folder; the settled VmRSS and PSS of
    every process it started (pids from its ``.fleet.json``, and their children), first while
    ag_ex's camera process runs (it observes the kitchen for a_km's world model at start), then
    at rest, once that process has ended (after ``ROCO_CAMERA_IDLE_S`` without an Observe; at
    most ``rest_timeout_s`` waited); then ``roco down``. Raises SetupRefused (a RuntimeError)
    when an agent counted anything refused, not understood or against its protocol meanwhile
    (services/bench/setup_check.py)."""
    from services.bench.setup_check import check_fleet
    from services.fleet.launcher import free_port

    cli = [sys.executable, "-m", "services.cli"]
    with tempfile.TemporaryDirectory(prefix="roco-mem-") as tmp:
        up = [*cli, "up", "--port", str(free_port()), "--runs-dir", tmp, "--no-realtime"]
        done = subprocess.run(up, cwd=ROOT, capture_output=True, text=True, timeout=240, check=False)
        state = Path(tmp) / ".fleet.json"
        try:
            if done.returncode != 0 or not state.exists():
                raise RuntimeError(f"roco up failed: {(done.stdout + done.stderr).strip()[-400:]}")
            fleet_pids = {str(k): int(v) for k, v in json.loads(state.read_text())["pids"].items()}
            pids: dict[str, int] = {}
            while True:  # settled, with every child started by then (ag_ex's loop and camera)
                known = dict(pids)
                pids = dict(fleet_pids)
                for name, pid in fleet_pids.items():
                    for child in children(pid):
                        pids[f"{name}'s {comm(child) or child}"] = child
                running = settle(pids)
                if pids == known:
                    break
            camera = [n for n in pids if n.endswith(CAMERA_PROCESS)]
            out = {"fleet, camera process running" if camera else "fleet": with_pss(running, pids)}
            deadline = time.monotonic() + rest_timeout_s
            while any(comm(pids[n]) for n in camera) and time.monotonic() < deadline:
                time.sleep(0.5)
            if camera and not any(comm(pids[n]) for n in camera):
                rest = {n: p for n, p in pids.items() if n not in camera}
                out["fleet at rest"] = with_pss(settle(rest), rest)
            check_fleet(Path(tmp), "roco up, its memory read")
            return out
        finally:
            if state.exists():
                subprocess.run([*cli, "down", "--runs-dir", tmp], cwd=ROOT, capture_output=True, timeout=120)


def synthetic(settle: Callable[[dict[str, int]], dict[str, float]]) -> dict[str, tuple[float, float]]:
    """An idle synthetic pair (``b_ini0``, ``b_par0``) on its own router, settled VmRSS."""
    from services.bench.messaging import testbed

    with testbed(1, ["b_ini0", "b_par0"], []) as bed:
        pids = {n: c.process.pid for n, c in bed.children.items() if c.process.pid is not None}
        assert bed.fleet is not None
        pids["router"] = bed.fleet.processes["router"].pid
        return with_pss(settle(pids), pids)


def imports() -> dict[str, list[str]]:
    """Per agent of the specification: the :data:`HEAVY` libraries in ``sys.modules`` of a
    fresh interpreter after importing ``services.runtime.main`` and the agent's class."""
    from services.spec.model import default_spec

    out = {}
    for a in default_spec().agents:
        code = (
            "import sys, services.runtime.main as m; from services.spec.model import default_spec; "
            f"m.agent_class(default_spec(), {a.name!r}); "
            f"print(' '.join(n for n in {HEAVY!r} if n in sys.modules))"
        )
        got = subprocess.run(
            [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120, check=True
        )
        out[a.name] = got.stdout.split()
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--only", default="imports,synthetic,fleet", help="comma-separated: imports, synthetic, fleet"
    )
    parser.add_argument("--quiet-s", type=float, default=1.0, help="RSS steady this long counts as idle (s)")
    parser.add_argument("--tolerance-mib", type=float, default=0.25, help="largest change while steady (MiB)")
    parser.add_argument("--max-wait-s", type=float, default=15.0, help="longest wait for steadiness (s)")
    parser.add_argument(
        "--rest-timeout-s",
        type=float,
        default=camera_idle_s() + 30.0,
        help="longest wait for ag_ex's camera process to end (s; default ROCO_CAMERA_IDLE_S + 30)",
    )
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of tables")
    args = parser.parse_args()
    parts = {p.strip() for p in args.only.split(",") if p.strip()}

    def settle(pids: dict[str, int]) -> dict[str, float]:
        return settled_rss(pids, args.quiet_s, args.tolerance_mib, args.max_wait_s)

    result: dict[str, object] = {}
    if "imports" in parts:
        result["imports"] = imports()
    if "synthetic" in parts:
        result["synthetic"] = synthetic(settle)
    if "fleet" in parts:
        try:
            result.update(fleet(settle, args.rest_timeout_s))
        except RuntimeError as exc:  # roco up failed, or its set-up was refused: no figure
            raise SystemExit(f"roco: bench_memory: {exc}") from None
    if args.json:
        print(json.dumps(result, indent=1))
        return
    import benchlib  # scripts/benchlib.py, beside this file

    print(f"# {benchlib.machine(('eclipse-zenoh', 'msgspec'))}")
    if "imports" in result:
        print("\n| agent | heavy libraries imported |\n|---|---|")
        for name, libs in result["imports"].items():  # type: ignore[attr-defined]
            print(f"| {name} | {', '.join(libs) or '—'} |")
    for part in [p for p in result if p != "imports"]:
        mem: dict[str, tuple[float, float]] = result[part]  # type: ignore[assignment]
        print(f"\n| {part}: process | VmRSS MiB | PSS MiB |\n|---|---|---|")
        for name, (rss, pss) in mem.items():
            print(f"| {name} | {rss:.1f} | {pss:.1f} |")
        total_rss = sum(v[0] for v in mem.values())
        total_pss = sum(v[1] for v in mem.values())
        print(f"| **total** | **{total_rss:.1f}** | **{total_pss:.1f}** |")


if __name__ == "__main__":
    main()
