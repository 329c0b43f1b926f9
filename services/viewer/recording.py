"""One Rerun recording per run, shared by all the processes that log to it.

Design (rerun-sdk 0.41, headless): every process that logs opens its own
``rr.RecordingStream`` with the same application id (``roco``) and the same recording id
(the run folder's name), and saves it to a part file of its own,
``<run>/rerun/<process>-<pid>-<start ms>.rrd`` (a file sink needs no display, no port and no other
process). When the process closes its part it writes ``<part>.done`` beside it. The traffic
recorder, the last process the launcher stops before the router, merges the parts into
``<run>/recording.rrd`` with ``rerun rrd merge`` once every part is done (bounded wait);
:func:`merge_parts` can be called again by anyone (``roco view``) to rebuild it. Because
the parts share application and recording ids, the viewer also merges them when it is
given the part files directly.

Live viewing: when ``ROCO_RERUN_CONNECT`` holds a viewer's gRPC URL
(``rerun+http://127.0.0.1:PORT/proxy``, see services/viewer/view.py) every process also
streams to it, besides its part file.

Environment:

- ``ROCO_RERUN=1`` switches logging on (anything else, or unset: off, :func:`start` returns None);
- ``ROCO_RUN_DIR`` the run folder: where the parts and the merged recording go; its name is
  the recording id;
- ``ROCO_RERUN_ID`` overrides the recording id (optional);
- ``ROCO_RERUN_CONNECT`` a viewer's gRPC URL to stream to as well (optional);
- ``ROCO_RERUN_CAMERA=0`` ag_ex renders no head camera (services/viewer/camera.py).
"""

from __future__ import annotations

import importlib.util
import logging
import os
import subprocess
import sys
import time
from collections.abc import Mapping
from pathlib import Path

import rerun as rr

from shared.settings import Settings

APP_ID = "roco"
PARTS_DIR = "rerun"
RECORDING_FILE = "recording.rrd"
DONE_SUFFIX = ".done"

log = logging.getLogger(__name__)


def enabled(env: Mapping[str, str] | None = None) -> bool:
    """Whether Rerun logging is switched on (``ROCO_RERUN=1`` in ``env``, default
    ``os.environ``, read now)."""
    return Settings.from_env(env, only=("rerun",)).rerun


def recording_id(run_dir: Path, env: Mapping[str, str] | None = None) -> str:
    """The recording id of the run in ``run_dir``: ``ROCO_RERUN_ID`` if set, else the
    folder's name."""
    return Settings.from_env(env, only=("rerun_id",)).rerun_id or run_dir.resolve().name


class Recording:
    """One process's part of the run's recording: a ``rr.RecordingStream`` saving to
    ``path`` (and streaming to a viewer when asked). Log with :attr:`stream`; :meth:`close`
    flushes the part and marks it done."""

    def __init__(self, process: str, run_dir: Path, rec_id: str, connect: str | None = None) -> None:
        self.process = process
        self.run_dir = run_dir
        self.recording_id = rec_id
        parts = run_dir / PARTS_DIR
        parts.mkdir(parents=True, exist_ok=True)
        # the start time too: PIDs repeat in containers, and a restarted process keeps its part
        self.path = parts / f"{process}-{os.getpid()}-{time.time_ns() // 1_000_000}.rrd"
        self.stream = rr.RecordingStream(APP_ID, recording_id=rec_id)
        if connect:
            self.stream.set_sinks(rr.FileSink(str(self.path)), rr.GrpcSink(connect))
        else:
            self.stream.save(self.path)
        self.closed = False

    def close(self) -> None:
        """Flush and close the part file, then write its ``.done`` marker (idempotent)."""
        if self.closed:
            return
        self.closed = True
        try:
            self.stream.flush()
            self.stream.disconnect()
        finally:
            done_marker(self.path).write_text(f"{self.process} {os.getpid()}\n")


def done_marker(part: Path) -> Path:
    """The file that says ``part`` is complete."""
    return part.with_name(part.name + DONE_SUFFIX)


def start(
    process_name: str, *, run_dir: Path | None = None, env: Mapping[str, str] | None = None
) -> Recording | None:
    """This process's part of the run's recording, or None when logging is off
    (``ROCO_RERUN`` unset or not ``1``) or Rerun cannot start (logged, never raised).
    ``run_dir`` defaults to ``ROCO_RUN_DIR`` (then the current directory)."""
    read = Settings.from_env(env, only=("rerun", "run_dir", "rerun_connect"))
    if not read.rerun:
        return None
    folder = run_dir if run_dir is not None else read.run_dir or Path(".")
    try:
        return Recording(process_name, folder, recording_id(folder, env), read.rerun_connect)
    except Exception:  # Rerun is an add-on: the process runs on without it
        log.exception("Rerun logging for %s could not start; going on without it", process_name)
        return None


def parts(run_dir: Path) -> list[Path]:
    """The part files of the run in ``run_dir``, sorted by name."""
    return sorted((run_dir / PARTS_DIR).glob("*.rrd"))


def rerun_cli() -> list[str]:
    """The command that runs the ``rerun`` CLI of the installed rerun-sdk."""
    return [sys.executable, "-m", "rerun_cli"]


def rerun_cli_missing() -> str | None:
    """Why :func:`rerun_cli` cannot run here, in one line, or None when it can: rerun-sdk's
    ``rerun_cli`` package holds the CLI as the binary ``rerun_cli/rerun``, which roco's
    runtime image leaves out (deploy/Dockerfile: the viewer image has it)."""
    found = importlib.util.find_spec("rerun_cli")
    if found is None or found.origin is None:
        return "no Rerun CLI here: the rerun_cli package is not installed (pip install rerun-sdk)"
    binary = Path(found.origin).with_name("rerun")
    if not binary.exists():
        return (
            f"no Rerun CLI here: {binary} is absent (roco's runtime image leaves it out; "
            f"the viewer image roco-viewer has it)"
        )
    return None


def merge_parts(run_dir: Path, *, wait: float = 0.0, poll: float = 0.05) -> Path | None:
    """Merge the run's parts into ``<run_dir>/recording.rrd`` (``rerun rrd merge``) and return
    its path; None when there is no part or the merge failed (logged).

    ``wait`` (s): how long to wait for parts that are not yet done (their process is still
    closing); after it, the merge takes them as they are. A part that is still being written
    may end in a partial chunk: the merge then continues past the error.
    """
    found, pending = _settled_parts(run_dir, wait, poll)
    if not found:
        return None
    if pending:
        log.warning("merging Rerun parts not marked done: %s", ", ".join(p.name for p in pending))
    return _merge(found, run_dir / RECORDING_FILE)


def _settled_parts(run_dir: Path, wait: float, poll: float) -> tuple[list[Path], list[Path]]:
    """The run's parts once all are done or ``wait`` seconds have passed (looking every
    ``poll`` seconds), and those not done then."""
    deadline = time.monotonic() + wait
    while True:
        found = parts(run_dir)
        pending = [p for p in found if not done_marker(p).exists()]
        if not pending or time.monotonic() >= deadline:
            return found, pending
        time.sleep(poll)


def _merge(found: list[Path], out: Path) -> Path | None:
    """``rerun rrd merge`` of the parts ``found`` into ``out`` (through a temporary file);
    None when it failed (logged)."""
    if (missing := rerun_cli_missing()) is not None:
        log.error("rerun rrd merge not run: %s", missing)
        return None
    tmp = out.with_name(out.name + ".tmp")
    cmd = [*rerun_cli(), "rrd", "merge", "--continue-on-error", "-o", str(tmp), *map(str, found)]
    env = dict(os.environ, RUST_LOG="warn")
    try:
        done = subprocess.run(cmd, capture_output=True, text=True, timeout=120, env=env, check=False)
    except (OSError, subprocess.TimeoutExpired) as exc:
        log.error("rerun rrd merge failed: %s", exc)
        return None
    if done.returncode != 0 or not tmp.exists():
        log.error("rerun rrd merge failed (%d): %s", done.returncode, done.stderr.strip()[-2000:])
        tmp.unlink(missing_ok=True)
        return None
    tmp.replace(out)
    return out
