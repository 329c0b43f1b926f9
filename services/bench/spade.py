"""Part 3 of ``roco bench``: SPADE (the Python agent platform, XMPP) on this machine, in the
same run as roco's messaging benchmark.

SPADE is installed from PyPI into its own virtual environment, ``.bench/spade-venv`` in the
repository (gitignored; made here when absent: ``python3 -m venv`` then ``pip install spade
greenlet``; greenlet because pyjabber's SQLAlchemy asyncio engine needs it and spade 4.1.4 does
not pull it in), never into roco's. Then, all on 127.0.0.1:

1. SPADE's own XMPP server: ``spade run --host localhost --memory --client_port P
   --server_port P+1`` (pyjabber, in-memory database; ``--host localhost`` so that
   ``*@localhost`` is its own domain),
2. ``scripts/bench_spade.py --role responder`` (one process, one agent),
3. ``scripts/bench_spade.py --role initiator`` (another process, one agent), which prints
   the figures as JSON.

Only the processes started here are ended, by PID (each in a session of its own).
"""

from __future__ import annotations

import contextlib
import json
import select
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from services.bench.children import end_child
from services.bench.platform_figures import PlatformFigures
from services.fleet.launcher import free_port

ROOT = Path(__file__).resolve().parents[2]
VENV = ROOT / ".bench" / "spade-venv"
SCRIPT = ROOT / "scripts" / "bench_spade.py"
PACKAGES = ("spade", "greenlet")


class SpadeFigures(PlatformFigures):
    """What the SPADE run gave (:class:`PlatformFigures`)."""


def ensure_venv(log: Path, timeout: float = 600.0) -> str:
    """Make ``.bench/spade-venv`` with SPADE when it is not there; '' when ready, else why not."""
    python = VENV / "bin" / "python"
    if python.exists():
        check = subprocess.run(
            [str(python), "-c", "import spade, greenlet"], capture_output=True, timeout=120, check=False
        )
        if check.returncode == 0:
            return ""
    VENV.parent.mkdir(parents=True, exist_ok=True)
    with log.open("ab") as out:
        for cmd in (
            ["python3", "-m", "venv", str(VENV)],
            [str(python), "-m", "pip", "install", "-q", *PACKAGES],
        ):
            try:
                done = subprocess.run(cmd, stdout=out, stderr=subprocess.STDOUT, timeout=timeout, check=False)
            except subprocess.TimeoutExpired:
                return f"`{' '.join(cmd)}` did not finish within {timeout:.0f} s"
            if done.returncode != 0:
                return f"`{' '.join(cmd)}` failed (exit {done.returncode}; log {log})"
    return ""


def _wait_port(port: int, proc: subprocess.Popen[bytes], timeout: float) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            return False
        try:
            with socket.create_connection(("127.0.0.1", port), timeout=0.2):
                return True
        except OSError:
            time.sleep(0.1)  # polling a port that is not open yet: no event to wait on
    return False


def _spawn(cmd: list[str], work: Path, stdout: Any, stderr: Any) -> subprocess.Popen[Any]:
    """One process of the measure, in ``work``, in a session of its own, no stdin."""
    return subprocess.Popen(
        cmd, cwd=work, stdout=stdout, stderr=stderr, stdin=subprocess.DEVNULL, start_new_session=True
    )


def _initiator(cmd: list[str], work: Path, timeout: float) -> dict[str, Any] | SpadeFigures:
    """The initiator's figures (its last line, JSON), or the SpadeFigures of its failure."""
    try:
        initiator = subprocess.run(
            cmd, cwd=work, capture_output=True, timeout=timeout, check=False, start_new_session=True
        )
    except subprocess.TimeoutExpired:
        return SpadeFigures(error=f"the SPADE initiator did not finish within {timeout:.0f} s")
    lines = initiator.stdout.decode(errors="replace").strip().splitlines()
    try:
        got: dict[str, Any] = json.loads(lines[-1])
    except (IndexError, ValueError):
        tail = initiator.stderr.decode(errors="replace").strip().splitlines()[-1:]
        return SpadeFigures(error=f"the SPADE initiator printed no figures: {tail}")
    return got


def _ping_pong(
    work: Path,
    procs: list[subprocess.Popen[Any]],
    ports: tuple[int, int],
    size: int,
    messages: int,
    round_trips: int,
    timeout: float,
) -> dict[str, Any] | SpadeFigures:
    """The server, then the responder (kept in ``procs``), then the initiator: its figures, or
    the SpadeFigures of the first step that failed."""
    python, spade = str(VENV / "bin" / "python"), str(VENV / "bin" / "spade")
    port, server_port = ports
    serve = ["run", "--host", "localhost", "--memory", "--client_port", str(port)]
    server = _spawn(
        [spade, *serve, "--server_port", str(server_port)],
        work,
        (work / "server.log").open("wb"),
        subprocess.STDOUT,
    )
    procs.append(server)
    if not _wait_port(port, server, 60):
        return SpadeFigures(error=f"`spade run` did not listen on {port} (log {work}/server.log)")
    common = ["--port", str(port), "--size", str(size), "--messages", str(messages)]
    responder = _spawn(
        [python, str(SCRIPT), "--role", "responder", *common],
        work,
        subprocess.PIPE,
        (work / "responder.log").open("wb"),
    )
    procs.append(responder)
    assert responder.stdout is not None
    started = select.select([responder.stdout], [], [], 60)[0]
    if not started or responder.stdout.readline().strip() != b"ready":
        return SpadeFigures(error=f"the SPADE responder did not start (log {work}/responder.log)")
    return _initiator(
        [python, str(SCRIPT), "--role", "initiator", *common, "--round-trips", str(round_trips)],
        work,
        timeout,
    )


def measure(round_trips: int, messages: int, size: int = 200, timeout: float = 300.0) -> SpadeFigures:
    """Run SPADE's ping-pong (``round_trips`` after 50 warm-up ones) and throughput
    (``messages`` informs) with ``size``-character bodies; never raises for SPADE's own
    failures (they are returned in ``error``)."""
    work = Path(tempfile.mkdtemp(prefix="roco-bench-spade-"))
    why = ensure_venv(work / "install.log")
    settings = (
        f"body {size} characters; {round_trips} round trips after 50 warm-up; {messages} messages; "
        "server `spade run --host localhost --memory` (pyjabber, in-memory database); "
        "auto_register=True (in-band registration), password auth; "
        "two agents in two processes (no in-container shortcut); all on 127.0.0.1"
    )
    if why:
        return SpadeFigures(error=why, settings=settings)
    port = free_port()
    server_port = free_port()
    procs: list[subprocess.Popen[Any]] = []
    measured = False
    try:
        got = _ping_pong(work, procs, (port, server_port), size, messages, round_trips, timeout)
        if isinstance(got, SpadeFigures):
            return got
        if "error" in got:
            return SpadeFigures(error=str(got["error"]), settings=settings)
        versions: dict[str, str] = {
            k: str(got[k]) for k in ("spade", "pyjabber", "slixmpp", "python") if k in got
        }
        measured = True
        return SpadeFigures(
            samples_s=list(got["samples_s"]),
            count=int(got["count"]),
            sent=messages,
            span_s=float(got["span_s"]),
            versions=versions,
            settings=settings,
        )
    except OSError as exc:
        return SpadeFigures(error=f"could not start SPADE: {exc}", settings=settings)
    finally:
        for proc in reversed(procs):
            with contextlib.suppress(OSError):
                end_child(proc)
        if measured:  # the logs are kept when something went wrong (error messages name them)
            shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":  # a quick look: python -m services.bench.spade
    fig = measure(200, 2000)
    print(fig.error or f"{len(fig.samples_s)} round trips, {fig.rate:.0f} msg/s", file=sys.stderr)
