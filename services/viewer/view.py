"""Opening a Rerun viewer on a run's recording (``roco view``, ``roco run --view``).

The viewer is the ``rerun`` CLI of the installed rerun-sdk, started as a process of its own
(its own session: it outlives the command that opened it):

- native (a display: ``DISPLAY`` or ``WAYLAND_DISPLAY`` is set): ``rerun FILES --port G``;
- web (no display, or asked): ``rerun FILES --serve-web --bind 127.0.0.1
  --web-viewer-port W --port G``: the web viewer is served on localhost (no browser is opened);
  open the printed URL.

Either way the viewer accepts logging SDKs on ``rerun+http://127.0.0.1:G/proxy``; giving that
URL to the processes of a run as ``ROCO_RERUN_CONNECT`` streams the run to the viewer live
(services/viewer/recording.py). G and W are free ports unless given (``roco view --grpc-port
--web-port``); a port given that something listens on already is refused before the viewer
starts (:class:`PortInUse`).
"""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
import time
import urllib.parse
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

from services.viewer.recording import RECORDING_FILE, merge_parts, parts, rerun_cli, rerun_cli_missing

READY_TIMEOUT = 15.0  # s, for the viewer's port to accept connections


class PortInUse(OSError):
    """A port asked of the viewer is in use on 127.0.0.1 (``port``); nothing was started."""

    def __init__(self, port: int) -> None:
        super().__init__(f"cannot listen on 127.0.0.1:{port}: the port is in use")
        self.port = port


@dataclass(frozen=True)
class Viewer:
    """A started viewer: its process id, the gRPC URL SDKs connect to, and (web) the URL to open."""

    pid: int
    grpc_url: str
    web_url: str | None
    files: tuple[Path, ...]


def has_display(env: Mapping[str, str] | None = None) -> bool:
    """Whether a native viewer can open a window (``DISPLAY`` or ``WAYLAND_DISPLAY`` set)."""
    env = os.environ if env is None else env
    return bool(env.get("DISPLAY") or env.get("WAYLAND_DISPLAY"))


def free_port() -> int:
    """A free TCP port on the loopback interface."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _port(asked: int | None) -> int:
    """``asked`` when nothing listens on it on 127.0.0.1 (else :class:`PortInUse`); None: a
    free port."""
    if asked is None:
        return free_port()
    with socket.socket() as s:
        s.settimeout(1.0)
        if s.connect_ex(("127.0.0.1", asked)) == 0:
            raise PortInUse(asked)
    return asked


def recording_files(target: Path | None) -> tuple[Path, ...]:
    """What to load for ``target``: a file as it is; a run folder's ``recording.rrd``
    (merged from its parts first if it is missing), else its part files; None: nothing."""
    if target is None:
        return ()
    if target.is_dir():
        merged = target / RECORDING_FILE
        if merged.exists() or merge_parts(target) is not None:
            return (merged,)
        found = tuple(parts(target))
        if not found:
            raise FileNotFoundError(f"no Rerun recording in {target} (was the run made with ROCO_RERUN=1?)")
        return found
    if not target.exists():
        raise FileNotFoundError(f"no such recording: {target}")
    return (target,)


def _wait_port(port: int, proc: subprocess.Popen[bytes], timeout: float) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            raise RuntimeError(f"the Rerun viewer exited with code {proc.returncode}")
        with socket.socket() as s:
            s.settimeout(0.2)
            if s.connect_ex(("127.0.0.1", port)) == 0:
                return
        time.sleep(0.05)
    raise TimeoutError(f"the Rerun viewer did not listen on port {port} within {timeout} s")


def _rerun_cli_here() -> list[str]:
    """:func:`rerun_cli`; RuntimeError with :func:`rerun_cli_missing`'s line when it cannot run."""
    if (missing := rerun_cli_missing()) is not None:
        raise RuntimeError(missing)
    return rerun_cli()


def start_viewer(
    rrd: Path | None,
    *,
    web: bool | None = None,
    log_file: Path | None = None,
    web_port: int | None = None,
    grpc_port: int | None = None,
) -> Viewer:
    """Start a viewer on ``rrd`` (a .rrd file, a run folder, or None for an empty viewer that
    waits for SDKs); ``web`` None: web when there is no display. ``grpc_port``, ``web_port``
    (web only): the ports on 127.0.0.1 (None: free ones). Returns once its ports listen.
    Raises :class:`PortInUse` for a port given that is in use, FileNotFoundError when ``rrd``
    holds no recording, RuntimeError when there is no Rerun CLI here (:func:`rerun_cli_missing`,
    its one line) or the viewer exits, TimeoutError when it does not come up."""
    cli = _rerun_cli_here()
    files = recording_files(rrd)
    use_web = (not has_display()) if web is None else web
    grpc_port = _port(grpc_port)
    cmd = [*cli, *map(str, files), "--port", str(grpc_port)]
    web_url = None
    if use_web:
        web_port = _port(web_port)
        cmd += ["--serve-web", "--bind", "127.0.0.1", "--web-viewer-port", str(web_port)]
    grpc_url = f"rerun+http://127.0.0.1:{grpc_port}/proxy"
    out = log_file.open("ab") if log_file is not None else subprocess.DEVNULL
    try:
        proc = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=out, stderr=out, start_new_session=True)
    finally:
        if log_file is not None and not isinstance(out, int):
            out.close()
    try:
        _wait_port(grpc_port, proc, READY_TIMEOUT)
        if use_web:
            assert web_port is not None
            _wait_port(web_port, proc, READY_TIMEOUT)
    except BaseException:  # nothing of a viewer that did not come up is left running
        stop_viewer(Viewer(pid=proc.pid, grpc_url="", web_url=None, files=files), timeout=2.0)
        raise
    if use_web:
        web_url = f"http://127.0.0.1:{web_port}/?url={urllib.parse.quote(grpc_url, safe='')}"
    return Viewer(pid=proc.pid, grpc_url=grpc_url, web_url=web_url, files=files)


def open_viewer(rrd: Path | None, *, web: bool | None = None) -> str:
    """Open a viewer on ``rrd`` (see :func:`start_viewer`) and return where to look: the web
    viewer's URL (also printed) in web mode, else the native viewer's gRPC URL (give it to a
    run as ``ROCO_RERUN_CONNECT`` to stream to it live)."""
    viewer = start_viewer(rrd, web=web)
    if viewer.web_url is not None:
        print(f"Rerun web viewer: {viewer.web_url}", flush=True)
        return viewer.web_url
    return viewer.grpc_url


def stop_viewer(viewer: Viewer, timeout: float = 5.0) -> bool:
    """Stop a viewer :func:`start_viewer` started: SIGTERM to its process group (its own
    session; the ``rerun`` wrapper runs the viewer as a child), SIGKILL if anything of it is
    left after ``timeout`` s. Returns whether it had gone by then (before the SIGKILL)."""
    with contextlib.suppress(ProcessLookupError):
        os.killpg(viewer.pid, signal.SIGTERM)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        with contextlib.suppress(ChildProcessError):  # reap it if it is this process's child
            os.waitpid(viewer.pid, os.WNOHANG)
        try:
            os.killpg(viewer.pid, 0)
        except ProcessLookupError:
            return True
        time.sleep(0.05)
    with contextlib.suppress(ProcessLookupError):
        os.killpg(viewer.pid, signal.SIGKILL)
    with contextlib.suppress(ChildProcessError):
        os.waitpid(viewer.pid, 0)
    return False
