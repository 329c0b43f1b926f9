"""How long ``roco export RUN --mcap`` takes on a default pour's run folder: the command timed
as a user runs it (a fresh ``python -m services.cli export`` process each time, interpreter
start and imports included, wall time by ``time.perf_counter`` around ``subprocess.run``) into
a new folder under a temporary directory, and the export's parts timed in this process after
one warm-up (reading recording.rrd, making the robot-state messages, the traffic messages,
writing CDR and MCAP). Target: the command under 10 s.

The setup is checked first (exit 2 when it is not a real default pour with all its topics):
``run.json`` says ``roco run "pour the jar into the bowl"`` succeeded, the folder holds
``recording.rrd`` and its traffic record, and the bag holds every topic of the export with
messages on it, as many communicates on /roco/traffic as the record has, and ``roco spec
verify`` gives the bag the run folder's verdict.

Usage: ``python scripts/bench_export.py RUN [--repeats N]`` (default 5), RUN a folder of
``roco run "pour the jar into the bowl"``.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import benchlib  # noqa: E402  (scripts/benchlib.py, beside this file)

from services.recorder.record import read_records  # noqa: E402
from services.ros2 import export, messages, state  # noqa: E402
from services.ros2.recording import read_recording  # noqa: E402
from services.runtime.run_folder import read_run_info  # noqa: E402
from services.spec_check.conformance import verify_report  # noqa: E402
from services.viewer.recording import RECORDING_FILE  # noqa: E402

TARGET_S = 10.0
"""``roco export`` of a default pour takes less than this, process start included (exit 1 if not)."""
POUR = "pour the jar into the bowl"
TOPICS = {
    export.TRAFFIC_TOPIC,
    state.JOINT_STATES,
    state.TF,
    state.TF_STATIC,
    state.wrench_topic("left"),
    state.wrench_topic("right"),
    state.IMAGE,
    state.CAMERA_INFO,
}
"""Every topic the export of a default pour has."""
PACKAGES = ("rosbags", "mcap", "mcap-ros2-support", "rerun-sdk")


def setup_problems(run: Path, done: export.Exported) -> list[str]:
    """Why ``run`` (exported as ``done``) is not a real default pour with all its topics, or its
    bag not verified as the run is."""
    problems = []
    run_ok, _ = verify_report(run)
    bag_ok, _ = verify_report(done.out)
    if run_ok != bag_ok:
        problems.append(f"spec verify: full conformance {run_ok} for the run, {bag_ok} for its bag")
    info = read_run_info(run)
    if info.command != POUR or not info.succeeded:
        problems.append(
            f"run.json: {info.command!r}, succeeded {info.succeeded}: not a default pour that succeeded"
        )
    if not (run / RECORDING_FILE).is_file():
        problems.append(f"no {RECORDING_FILE}")
    missing = sorted(TOPICS - {t for t, n in done.counts.items() if n > 0})
    if missing:
        problems.append(f"topics without messages: {', '.join(missing)}")
    records = len(read_records(run))
    if done.counts.get(export.TRAFFIC_TOPIC) != records:
        problems.append(
            f"{done.counts.get(export.TRAFFIC_TOPIC)} communicates exported of {records} recorded"
        )
    if done.notes:
        problems.append(f"notes: {'; '.join(done.notes)}")
    return problems


def parts(run: Path, into: Path) -> dict[str, float]:
    """Seconds of each part of an export of ``run`` into the new folder ``into``, in this process."""
    took: dict[str, float] = {}
    began = time.perf_counter()
    recording = read_recording(run / RECORDING_FILE)
    took["read recording.rrd (rerun.chunk.RrdReader)"] = time.perf_counter() - began
    began = time.perf_counter()
    items = list(state.state_messages(recording))
    took["robot-state messages (JPEG decoded)"] = time.perf_counter() - began
    began = time.perf_counter()
    traffic, _ = export.traffic_messages(run, recording.sim_clock())
    took["traffic messages"] = time.perf_counter() - began
    began = time.perf_counter()
    items = sorted(items + traffic, key=lambda o: o.log_time)
    into.mkdir()
    export.write_bag(into, messages.typestore(), items, None, export.Exported(into))
    took["CDR (rosbags) and MCAP (mcap) written"] = time.perf_counter() - began
    return took


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0] if __doc__ else None)
    parser.add_argument("run", type=Path, help='a run folder of roco run "pour the jar into the bowl"')
    parser.add_argument("--repeats", type=int, default=5, help="timed commands")
    args = parser.parse_args()
    if args.repeats < 1:
        parser.error("--repeats is at least 1")
    with tempfile.TemporaryDirectory(prefix="bench_export_") as tmp:
        first = export.export_run(args.run, Path(tmp) / "setup")  # warm-up, and the setup's check
        problems = setup_problems(args.run, first)
        if problems:
            print(
                f"bench_export: {args.run} is not a default pour with all its topics: {'; '.join(problems)}"
            )
            return 2
        took = []
        for k in range(args.repeats):
            out = Path(tmp) / f"bag{k}"
            began = time.perf_counter()
            subprocess.run(
                [sys.executable, "-m", "services.cli", "export", str(args.run), str(out), "--mcap"],
                cwd=ROOT,
                check=True,
                capture_output=True,
            )
            took.append(time.perf_counter() - began)
        split = parts(args.run, Path(tmp) / "parts")
        size = sum(p.stat().st_size for p in (Path(tmp) / "setup").iterdir())
    rrd = (args.run / RECORDING_FILE).stat().st_size
    print(f"# roco export --mcap of {args.run.name} ({time.strftime('%Y-%m-%d')})")
    print(f"Machine: {benchlib.machine(PACKAGES)}")
    print(
        f"Run: {POUR!r}, {first.counts[export.TRAFFIC_TOPIC]} communicates, "
        f"recording.rrd {rrd / 1e6:.1f} MB; the same spec verify verdict on the run and the bag; "
        f"bag: {first.messages} messages on {len(first.counts)} topics, {size / 1e6:.1f} MB"
    )
    for topic, count in first.counts.items():
        print(f"  {topic}: {count} ({first.types[topic]})")
    print(
        f"{args.repeats} commands (process start included): min {min(took):.2f} s, "
        f"median {statistics.median(took):.2f} s, max {max(took):.2f} s (target < {TARGET_S:.0f} s)"
    )
    print("Parts, in this process after a warm-up: " + ", ".join(f"{k} {v:.2f} s" for k, v in split.items()))
    return 0 if max(took) < TARGET_S else 1


if __name__ == "__main__":
    sys.exit(main())
