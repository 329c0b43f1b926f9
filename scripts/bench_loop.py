"""Benchmark of ag_ex's 1 kHz control loop: per-cycle compute time, lateness and overruns
(velma/executor/timing.py), in two conditions, printed as a table.

1. ``alone``: the loop process paced in real time (``ExecutorProcess(realtime=True)``, as ag_ex
   runs it) executes the scripted pour of velma/scenario.py; nothing else runs.
2. ``fleet``: ``roco run "pour the jar into the bowl" --realtime``: router, recorder and the six
   agent processes on the same machine; the figures are the ``ag_ex_timing.json`` that ag_ex
   wrote into the run folder.

``--camera`` adds ``alone + head camera`` after each ``alone`` run: the same, with the loop
publishing its whole state for the camera (``world_state=True``) and ag_ex's head-camera
thread (services/viewer/camera.py) rendering 320×240 frames at 1 Hz into a Rerun recording in
a temporary folder, as ag_ex does with ``ROCO_RERUN=1``.

``--camera-feed`` adds two runs after each ``alone`` run: the loop publishing its whole state,
with ag_ex's camera feed for ``roco ros2 --camera`` (services/agents/executor/camera_feed.py) on
a Zenoh session of its own, first with no subscriber (nothing rendered: the feed waits), then
with a subscriber on another session over loopback TCP (320×240 frames at ``ROCO_CAMERA_HZ``,
default 5 Hz).

Beside the loop's figures, each row gives the world process's own cycle (velma/world/timing.py)
as ag_ex read it from the robot link: late cycles and schedule resets, stalls, stale commands,
held steps (``-`` where the physics ran in the loop, as in ``alone``).

Usage: ``python scripts/bench_loop.py [--repeat N] [--skip-fleet] [--camera] [--camera-feed]
[--runs-dir DIR]``.
Percentiles are over the last 120 000 cycles of each run (the whole pour is ≈ 56 000).
"""

from __future__ import annotations

import argparse
import multiprocessing
import multiprocessing.queues
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import benchlib  # noqa: E402  (scripts/benchlib.py, beside this file)
import msgspec  # noqa: E402
import numpy as np  # noqa: E402

from velma.executor.timing import STALL_OFF_CPU, TimingStats  # noqa: E402
from velma.world.timing import DT, LATE_AFTER_S, MAX_BEHIND_S, STALL_PERIODS  # noqa: E402


def run_alone(
    seed: int, spin: float | None, camera: bool = False, feed: str | None = None
) -> tuple[TimingStats, str]:
    """The scripted pour through ExecutorProcess in real time, with the head camera rendering
    at 1 Hz if ``camera``, with ag_ex's camera feed if ``feed`` (``idle``: no subscriber,
    ``subscribed``: one); returns timing and outcome."""
    from shared.fipa_codec.languages.l_ex import CommandResult
    from velma.executor import ExecutorProcess
    from velma.executor.loop_wire import DEFAULT_SPIN
    from velma.scenario import run_pour

    ex = ExecutorProcess(
        realtime=True,
        seed=seed,
        spin=DEFAULT_SPIN if spin is None else spin,
        world_state=camera or feed is not None,
    )
    ex.start()
    cam = None
    fed: CameraFeedRun | None = None
    try:
        if feed is not None:
            fed = CameraFeedRun(ex.world, seed, subscribed=feed == "subscribed")
        if camera:
            from services.viewer.camera import HeadCamera
            from services.viewer.recording import Recording

            rec = Recording("ag_ex", Path(tempfile.mkdtemp(prefix="roco-bench-camera-")), "bench")
            cam = HeadCamera(rec, ex.world, seed=seed)
            cam.start()
        _, results = run_pour(ex.submit)
        timing = ex.timing()
    finally:
        if fed is not None:
            fed.close()
        if cam is not None:
            cam.stop()
            rec.close()
        ex.stop()
    failed = next((r for r in results if isinstance(r, CommandResult) and not r.ok), None)
    outcome = "ok" if failed is None else f"{failed.command} failed: {failed.reason}"
    if cam is not None:
        ms = sorted(1e3 * x for x in cam.render_s)
        median = f"{ms[len(ms) // 2]:.0f} ms" if ms else "-"
        outcome += f"; {cam.frames} frames, {cam.skipped} skipped, render median {median}"
        if cam.failed:
            outcome += f"; camera failed: {cam.failed}"
    if fed is not None:
        outcome += f"; {fed.describe()}"
    return timing, outcome


class CameraFeedRun:
    """ag_ex's camera feed of ``world`` on a peer session listening on loopback TCP, and with
    ``subscribed`` a second session connected to it that subscribes to the images."""

    def __init__(self, world: object, seed: int, *, subscribed: bool) -> None:
        import json

        import zenoh

        from services.agents.executor.camera_feed import CameraPublisher
        from services.fleet.launcher import free_port
        from services.runtime import keys
        from shared.settings import Settings

        endpoint = f"tcp/127.0.0.1:{free_port()}"

        def peer(key: str) -> zenoh.Session:
            conf = zenoh.Config()
            conf.insert_json5("mode", '"peer"')
            conf.insert_json5(key, json.dumps([endpoint]))
            conf.insert_json5("scouting/multicast/enabled", "false")
            return zenoh.open(conf)

        self.sessions = [peer("listen/endpoints")]
        self.received = 0
        self.cpu_s = 0.0
        self.publisher = CameraPublisher(
            self.sessions[0], world, Settings.from_env(only=("camera_hz",)).camera_hz, seed=seed
        )  # type: ignore[arg-type]
        if subscribed:
            self.sessions.append(peer("connect/endpoints"))
            self.sessions[1].declare_subscriber(keys.camera_key("ag_ex"), self._count)

    def _count(self, sample: object) -> None:
        self.received += 1

    def describe(self) -> str:
        f = self.publisher.feed
        ms = sorted(1e3 * x for x in f.render_s)
        median = f"{ms[len(ms) // 2]:.0f} ms" if ms else "-"
        failed = f"; feed failed: {f.failed}" if f.failed else ""
        return (
            f"feed: {f.frames} frames rendered, {self.received} received, render median {median}, "
            f"its thread's CPU {self.cpu_s:.2f} s{failed}"
        )

    def _thread_cpu_s(self) -> float:
        """CPU time (user + system, s) of the feed's thread so far (Linux /proc; 0 elsewhere)."""
        import os

        tid = self.publisher.feed._thread.native_id
        try:
            fields = Path(f"/proc/self/task/{tid}/stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            return 0.0
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")  # utime, stime

    def close(self) -> None:
        self.cpu_s = self._thread_cpu_s()
        self.publisher.close()
        for s in reversed(self.sessions):
            s.close()


def _fixed_work(reps: int, a: np.ndarray, out: np.ndarray) -> None:
    """The baseline's cycle: the same few small matrix products every time."""
    for _ in range(reps):
        np.matmul(a, a, out=out)


def _baseline_child(seconds: float, work_us: float, out: multiprocessing.queues.Queue[bytes]) -> None:
    """In a spawned process: the loop's real-time setup (enter_realtime, Pacer, spin,
    DeadlineMonitor) around a fixed calculation calibrated to ≈ ``work_us`` per cycle."""
    from velma.executor.loop_wire import DEFAULT_SPIN, DT
    from velma.executor.timing import DeadlineMonitor, Pacer
    from velma.realtime import enter_realtime

    a = np.random.default_rng(0).standard_normal((48, 48))
    tmp = np.empty_like(a)
    t0 = time.perf_counter()
    _fixed_work(2000, a, tmp)
    reps = max(1, round(work_us * 1e-6 / ((time.perf_counter() - t0) / 2000)))
    setup = enter_realtime()
    monitor = DeadlineMonitor(DT, realtime=True)
    monitor.setup = setup
    pacer = Pacer(DT, realtime=True, spin=DEFAULT_SPIN)
    end_at = time.perf_counter() + seconds
    while time.perf_counter() < end_at:
        start = pacer.begin()
        cpu = time.thread_time()
        _fixed_work(reps, a, tmp)
        cpu = time.thread_time() - cpu
        monitor.record(pacer.release, start, time.perf_counter(), None, cpu)
        pacer.wait()
    out.put(msgspec.json.encode(monitor.stats()))


def run_baseline(seconds: float, work_us: float) -> tuple[TimingStats, str]:
    """The machine's own stalls, for comparison with the loop's long cycles: the loop's
    real-time setup around a fixed calculation of ≈ ``work_us`` for ``seconds`` (a cycle of
    it that takes over 1 ms is the machine's doing, the work never changes)."""
    ctx = multiprocessing.get_context("spawn")
    queue: multiprocessing.queues.Queue[bytes] = ctx.Queue()
    child = ctx.Process(target=_baseline_child, args=(seconds, work_us, queue))
    child.start()
    raw = queue.get(timeout=seconds + 120)
    child.join(30)
    return msgspec.json.decode(raw, type=TimingStats), "fixed work"


def run_fleet(runs_dir: Path) -> tuple[TimingStats, str]:
    """``roco run … --realtime``; timing from the run folder's ag_ex_timing.json."""
    before = set(runs_dir.glob("*")) if runs_dir.exists() else set()
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "services.cli",
            "run",
            "pour the jar into the bowl",
            "--realtime",
            "--quiet",
            "--runs-dir",
            str(runs_dir),
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
        check=False,
    )
    new = sorted(set(runs_dir.glob("*")) - before)
    if not new:
        raise RuntimeError(f"roco run made no run folder: {proc.stderr.strip()}")
    run_dir = new[-1]
    stats = msgspec.json.decode((run_dir / "ag_ex_timing.json").read_bytes(), type=TimingStats)
    return stats, ("ok" if proc.returncode == 0 else f"failed ({run_dir})")


def parts(name: str, s: TimingStats) -> str:
    """The compute time's parts (p50 / p99 / max µs each) of one row, as one line."""
    split = "; ".join(f"{p.name} {p.p50_us:.0f} / {p.p99_us:.0f} / {p.max_us:.0f}" for p in s.parts)
    return f"- {name}: {split or 'parts not measured'}"


def row(name: str, s: TimingStats, outcome: str) -> str:
    setup = s.setup
    sched = "?" if setup is None else setup.describe()
    if s.control_law:
        sched += f", {s.control_law} law"
    if s.plant == "world process":
        sched += ", physics in the world process"
    elif s.plant:
        sched += f", {s.plant} plant"
    return (
        f"| {name} | {s.cycles} | {s.compute_p50_us:.0f} | {s.compute_p99_us:.0f} | {s.compute_max_us:.0f} | "
        f"{s.long_cycles} ({s.stalls}) | "
        f"{s.lateness_p99_us:.0f} | {s.overruns} ({s.overrun_share * 100:.3f} %) | "
        f"{s.max_consecutive_overruns} | {world(s)} | {sched} | {outcome} |"
    )


def world(s: TimingStats) -> str:
    """The world process's own cycle in one cell (velma/world/timing.py): late (resets) /
    stalls / stale (worst age) / held (while attached); ``-`` when the physics ran in the loop."""
    w = s.world
    if w is None:
        return "-"
    return (
        f"{w.late} ({w.resets}) / {w.stalls} / {w.stale} ({w.stale_worst_age}) / {w.held} ({w.held_attached})"
    )


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=1, help="runs per condition")
    ap.add_argument("--spin-us", type=float, default=None, help="alone: busy-wait before each release (µs)")
    ap.add_argument("--skip-fleet", action="store_true", help="only the loop alone")
    ap.add_argument("--skip-alone", action="store_true", help="only the fleet run")
    ap.add_argument("--camera", action="store_true", help="alone: also run with the head camera at 1 Hz")
    ap.add_argument(
        "--camera-feed",
        action="store_true",
        help="alone: also run with ag_ex's camera feed, without and with a subscriber",
    )
    ap.add_argument(
        "--baseline",
        type=float,
        default=0.0,
        metavar="SECONDS",
        help="first, the machine alone: the loop's real-time setup around a fixed ≈ 220 µs "
        "calculation for SECONDS (its cycles over 1 ms are the machine's stalls)",
    )
    ap.add_argument(
        "--runs-dir", type=Path, default=None, help="where the fleet runs go (default: a temp dir)"
    )
    ap.add_argument(
        "--out",
        type=Path,
        default=None,
        help="also write the output to this Markdown file as its current run (earlier runs kept "
        "under its '## Earlier runs'), once every run finished: docs/bench/loop.md",
    )
    args = ap.parse_args()
    with benchlib.recorded(args.out):
        return measure(args)


def measure(args: argparse.Namespace) -> int:
    """Run and print the conditions ``args`` asks for (:func:`main`'s options)."""
    print(f"# ag_ex control loop at 1 kHz, real-time pacing\n\n{benchlib.header(('mujoco', 'pin'))}")
    print(
        "| condition | cycles | compute p50 µs | compute p99 µs | compute max µs "
        "| cycles over 1 ms (off-CPU stalls) | lateness p99 µs | overruns | max in a row "
        "| world: late (resets) / stalls / stale (worst age) / held (while attached) | scheduling | pour |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    runs_dir = args.runs_dir or Path(tempfile.mkdtemp(prefix="roco-bench-"))
    split: list[str] = []
    if args.baseline > 0:
        stats, outcome = run_baseline(args.baseline, 220.0)
        print(row(f"machine baseline ({args.baseline:.0f} s)", stats, outcome), flush=True)
    for k in range(args.repeat):
        if not args.skip_alone:
            t0 = time.time()
            stats, outcome = run_alone(k, None if args.spin_us is None else args.spin_us * 1e-6)
            print(row(f"alone (seed {k}, {time.time() - t0:.0f} s)", stats, outcome), flush=True)
            split.append(parts(f"alone (seed {k})", stats))
            if args.camera:
                t0 = time.time()
                stats, outcome = run_alone(k, None if args.spin_us is None else args.spin_us * 1e-6, True)
                name = f"alone + head camera (seed {k}, {time.time() - t0:.0f} s)"
                print(row(name, stats, outcome), flush=True)
                split.append(parts(name, stats))
            for feed in ("idle", "subscribed") if args.camera_feed else ():
                t0 = time.time()
                spin = None if args.spin_us is None else args.spin_us * 1e-6
                stats, outcome = run_alone(k, spin, feed=feed)
                name = f"alone + camera feed, {'no subscriber' if feed == 'idle' else 'a subscriber'}"
                print(row(f"{name} (seed {k}, {time.time() - t0:.0f} s)", stats, outcome), flush=True)
                split.append(parts(f"{name} (seed {k})", stats))
        if not args.skip_fleet:
            t0 = time.time()
            stats, outcome = run_fleet(runs_dir)
            print(row(f"fleet: roco run ({time.time() - t0:.0f} s)", stats, outcome), flush=True)
            split.append(parts(f"fleet (run {k + 1})", stats))
    print("\nThe compute time in parts, p50 / p99 / max µs (each part's own percentiles):\n")
    print("\n".join(split))
    print(
        "\nCompute: loop work per cycle (command hand-off, primitive, control law, physics step, "
        "state publication). Lateness: cycle start after its release time. Overrun: a cycle that "
        "ended after the next release time. Stall: a cycle during which the loop's thread was off "
        f"its CPU (compute time minus its thread CPU time) for more than {STALL_OFF_CPU * 1e6:.0f} µs: "
        "the machine (hypervisor, interrupts) took the CPU as Linux accounts it. The machine "
        "baseline (--baseline) runs a fixed calculation under the same real-time setup: its "
        "cycles over 1 ms are the machine's own. World: the world process's own cycle over its "
        f"run (velma/world/timing.py; '-' when the physics ran in the loop): late cycles (started "
        f"over {LATE_AFTER_S * 1e3:.0f} ms after due) with, in brackets, the schedule resets among "
        f"them (over {MAX_BEHIND_S * 1e3:.0f} ms behind: the world went on from then, no burst); "
        f"stalls (over {STALL_PERIODS * DT * 1e3:.0f} ms between two cycle starts, waits for the controller "
        "excluded); stale commands (a step applied a command older than the newest it could "
        "have had) with the worst age in cycles; held steps (no command applied: before ag_ex "
        "attached, after it ended, or its command too old) with, in brackets, those between two "
        "applied commands (ag_ex there, its command too old)."
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
