"""Screenshot of the Rerun web viewer on a run's recording, taken in headless Chromium.

The viewer is served exactly as ``roco view RUN --web`` serves it
(:func:`services.viewer.view.start_viewer`); Chromium (Debian's ``chromium``, found on PATH)
is started headless and driven over the Chrome DevTools Protocol on a pipe
(``--remote-debugging-pipe``: no extra Python package). The script polls, each wait with a
deadline: until the page has started the viewer app (``window._handle`` set by the viewer's
index.html, no panic, no loading error); until the viewer's own state (its recordings and
their time ranges) has not changed for ``--settle`` s, i.e. the recording has streamed in,
with the page small (``--load-size``: the viewer ingests between frames, and small frames are
drawn faster); then, at ``--width`` × ``--height``, until two screenshots in a row are
(nearly) the same; and saves the last one as a PNG.

WebGL runs in software (WebGL 2 by ANGLE on SwiftShader); no GPU or display is needed.

Usage::

    python scripts/viewer_screenshot.py [RUN_OR_RRD] [--out viewer.png] [--width 1600 --height 1000]

RUN_OR_RRD: a run folder, or a .rrd file (default: the newest run under ``runs/`` with a
``recording.rrd``). Exit code 0 when a screenshot of a started viewer was saved, 1 otherwise
(one line on stderr saying why), 2 when Chromium is not installed.
"""

from __future__ import annotations

import argparse
import base64
import contextlib
import fcntl
import io
import json
import os
import select
import shutil
import signal
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from PIL import Image, ImageChops  # noqa: E402  (Pillow: a dependency of matplotlib)

from services.viewer.recording import RECORDING_FILE  # noqa: E402
from services.viewer.view import start_viewer, stop_viewer  # noqa: E402

CHROMIUM_NAMES = ("chromium", "chromium-browser")
# Headless as root on a machine without a display, GPU or outside network. Chromium then
# renders WebGL 2 with ANGLE on SwiftShader (software Vulkan); the viewer picks its WebGL
# backend by itself (no WebGPU here). No host name resolves: the page reaches only the viewer
# on 127.0.0.1 (the web viewer also asks for Google's fonts, GitHub's latest release, Rerun's
# examples and telemetry; those fail at once, here and in CI alike, and it works without them).
CHROMIUM_FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-dev-shm-usage",
    "--hide-scrollbars",
    "--mute-audio",
    "--host-resolver-rules=MAP * ~NOTFOUND, EXCLUDE 127.0.0.1",
)
# What the viewer's index.html shows in the page: whether the app started (it sets
# window._handle), whether it panicked, and the text it puts in #center_text on errors.
PAGE_STATE_JS = """JSON.stringify({
  started: typeof window._handle === "object" && window._handle !== null,
  panicked: !!(window._handle && window._handle.has_panicked()),
  panic: window._handle && window._handle.has_panicked() ? String(window._handle.panic_message()) : "",
  message: (document.getElementById("center_text") || {}).innerText || "",
  canvas: !!document.getElementById("the_canvas_id"),
})"""
VIEWER_STATE_JS = 'Array.from(window._handle.viewer_state(), (b) => b.toString(16).padStart(2, "0")).join("")'
LOAD_SIZE = (400, 250)  # px, the page's size while the recording streams in


class BrowserError(RuntimeError):
    """The browser, or the page in it, did not do what was expected."""


def find_chromium() -> str | None:
    """Path of a Chromium executable on PATH, or None."""
    for name in CHROMIUM_NAMES:
        found = shutil.which(name)
        if found:
            return found
    return None


def newest_run(runs_dir: Path) -> Path | None:
    """The run folder under ``runs_dir`` whose ``recording.rrd`` was written last, or None."""
    recordings = sorted(runs_dir.glob(f"*/{RECORDING_FILE}"), key=lambda p: p.stat().st_mtime)
    return recordings[-1].parent if recordings else None


def _high_fd(fd: int) -> int:
    """``fd`` moved to a number above 4 (close-on-exec), so that the child's dup2 onto 3 and 4
    always makes a new, inheritable descriptor."""
    moved = fcntl.fcntl(fd, fcntl.F_DUPFD_CLOEXEC, 5)
    os.close(fd)
    return moved


class Chromium:
    """A headless Chromium driven over the DevTools protocol on a pipe (fd 3: commands to it,
    fd 4: replies and events from it, each message JSON ending with a NUL byte), with one page.

    Started with ``posix_spawn`` (safe with threads, unlike a ``preexec_fn``) in a session of
    its own, so that its helpers (renderer, GPU process, ...) share its process group. Use as a
    context manager: leaving it closes the browser, kills what is left of its process group,
    and removes its fresh profile folder."""

    def __init__(
        self, executable: str, width: int = 1600, height: int = 1000, *, extra_flags: tuple[str, ...] = ()
    ) -> None:
        self.width = width
        self.height = height
        self.returncode: int | None = None
        self.profile = tempfile.mkdtemp(prefix="roco-chromium-")
        self.log = Path(self.profile) / "chromium.log"
        to_child, self._to_browser = os.pipe()
        self._from_browser, from_child = os.pipe()
        to_child, from_child = _high_fd(to_child), _high_fd(from_child)
        cmd = [
            executable,
            *CHROMIUM_FLAGS,
            *extra_flags,
            f"--user-data-dir={self.profile}",
            f"--window-size={width},{height}",
            "--remote-debugging-pipe",
            "about:blank",
        ]
        try:
            self.pid = os.posix_spawn(
                executable,
                cmd,
                dict(os.environ),
                file_actions=[
                    (os.POSIX_SPAWN_OPEN, 0, os.devnull, os.O_RDONLY, 0),
                    (os.POSIX_SPAWN_OPEN, 1, str(self.log), os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644),
                    (os.POSIX_SPAWN_DUP2, 1, 2),
                    (os.POSIX_SPAWN_DUP2, to_child, 3),
                    (os.POSIX_SPAWN_DUP2, from_child, 4),
                ],
                setsid=True,
            )
        except OSError:
            for fd in (self._to_browser, self._from_browser):
                os.close(fd)
            shutil.rmtree(self.profile, ignore_errors=True)
            raise
        finally:
            os.close(to_child)
            os.close(from_child)
        self._buffer = b""
        self._next_id = 0
        self.errors: list[str] = []  # console errors and uncaught exceptions of the page
        self.session = ""
        try:
            self._open_page()
        except BaseException:
            self.close()
            raise

    def poll(self) -> int | None:
        """Chromium's exit status once it has exited (and been reaped), else None."""
        if self.returncode is None:
            with contextlib.suppress(ChildProcessError):
                pid, status = os.waitpid(self.pid, os.WNOHANG)
                if pid == self.pid:
                    self.returncode = os.waitstatus_to_exitcode(status)
        return self.returncode

    def wait(self, timeout: float) -> bool:
        """Wait up to ``timeout`` s for Chromium to exit; whether it has."""
        deadline = time.monotonic() + timeout
        while self.poll() is None:
            if time.monotonic() >= deadline:
                return False
            time.sleep(0.05)
        return True

    def __enter__(self) -> Chromium:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # --- the protocol ---

    def _read_message(self, deadline: float) -> dict[str, Any]:
        while b"\0" not in self._buffer:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise BrowserError("no answer from Chromium in time")
            ready, _, _ = select.select([self._from_browser], [], [], remaining)
            if not ready:
                continue
            chunk = os.read(self._from_browser, 1 << 20)
            if not chunk:
                raise BrowserError(f"Chromium closed its pipe (exit code {self.poll()}); see {self.log}")
            self._buffer += chunk
        message, self._buffer = self._buffer.split(b"\0", 1)
        parsed: dict[str, Any] = json.loads(message)
        return parsed

    def _note_event(self, event: dict[str, Any]) -> None:
        method = event.get("method")
        params = event.get("params", {})
        if method == "Runtime.exceptionThrown":
            details = params.get("exceptionDetails", {})
            text = details.get("exception", {}).get("description") or details.get("text", "")
            self.errors.append(str(text)[:500])
        elif method == "Runtime.consoleAPICalled" and params.get("type") == "error":
            args = params.get("args", [])
            text = " ".join(str(a.get("value", a.get("description", ""))) for a in args)
            self.errors.append(text[:500])

    def send(
        self, method: str, params: dict[str, Any] | None = None, timeout: float = 30.0
    ) -> dict[str, Any]:
        """Send one command (to the page's session once there is one) and return its result."""
        self._next_id += 1
        message: dict[str, Any] = {"id": self._next_id, "method": method, "params": params or {}}
        if self.session and not method.startswith(("Target.", "Browser.")):
            message["sessionId"] = self.session
        try:
            os.write(self._to_browser, json.dumps(message).encode() + b"\0")
        except BrokenPipeError:
            raise BrowserError(f"Chromium is gone (exit code {self.poll()}); see {self.log}") from None
        deadline = time.monotonic() + timeout
        while True:
            reply = self._read_message(deadline)
            if reply.get("id") == self._next_id:
                if "error" in reply:
                    raise BrowserError(f"{method}: {reply['error'].get('message', reply['error'])}")
                result: dict[str, Any] = reply.get("result", {})
                return result
            self._note_event(reply)

    def _open_page(self) -> None:
        target = self.send("Target.createTarget", {"url": "about:blank"})["targetId"]
        self.session = self.send("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]
        self.send("Runtime.enable")
        self.send("Page.enable")
        self.resize(self.width, self.height)

    # --- the page ---

    def resize(self, width: int, height: int) -> None:
        """Give the page ``width`` × ``height`` CSS pixels (one device pixel each)."""
        self.send(
            "Emulation.setDeviceMetricsOverride",
            {"width": width, "height": height, "deviceScaleFactor": 1, "mobile": False},
        )
        self.width, self.height = width, height

    def navigate(self, url: str) -> None:
        reply = self.send("Page.navigate", {"url": url})
        if reply.get("errorText"):
            raise BrowserError(f"cannot load {url}: {reply['errorText']}")

    def evaluate(self, expression: str, timeout: float = 30.0) -> Any:
        """The value of a JavaScript expression in the page (which answers only between two of
        the viewer's frames: under load, one frame has taken up to a minute here)."""
        reply = self.send("Runtime.evaluate", {"expression": expression, "returnByValue": True}, timeout)
        if "exceptionDetails" in reply:
            raise BrowserError(f"script failed: {reply['exceptionDetails'].get('text')}")
        return reply.get("result", {}).get("value")

    def screenshot(self, timeout: float = 120.0) -> bytes:
        """The page as a PNG, ``width`` × ``height`` pixels."""
        data = self.send("Page.captureScreenshot", {"format": "png"}, timeout)["data"]
        return base64.b64decode(data)

    # --- the end ---

    def close(self, timeout: float = 10.0) -> None:
        """Ask Chromium to close, wait for it, kill its process group if anything is left."""
        if self.poll() is None:
            with contextlib.suppress(OSError, BrowserError):
                self.send("Browser.close", timeout=5.0)
            self.wait(timeout)
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(self.pid, signal.SIGKILL)  # its own group (setsid): helpers left behind, if any
        self.wait(timeout)
        for fd in (self._to_browser, self._from_browser):
            with contextlib.suppress(OSError):
                os.close(fd)
        shutil.rmtree(self.profile, ignore_errors=True)


def _left(deadline: float) -> float:
    """Seconds to ``deadline``, at least 1 (a reply to wait for at the deadline)."""
    return max(1.0, deadline - time.monotonic())


def wait_for_viewer(browser: Chromium, timeout: float) -> dict[str, Any]:
    """Poll the page until the viewer app has started; raise if it panicked, showed a loading
    error, or did not start within ``timeout`` s. Returns the page state."""
    deadline = time.monotonic() + timeout
    state: dict[str, Any] = {}
    while time.monotonic() < deadline:
        state = json.loads(browser.evaluate(PAGE_STATE_JS, _left(deadline)) or "{}")
        if state.get("panicked"):
            raise BrowserError(f"the viewer panicked: {state.get('panic', '')[:300]}")
        message = str(state.get("message", ""))
        if "error occurred" in message or "too old" in message:
            raise BrowserError(f"the viewer did not load: {' '.join(message.split())[:300]}")
        if state.get("started"):
            return state
        time.sleep(0.25)
    raise BrowserError(f"the viewer did not start within {timeout:.0f} s (page state {state})")


def viewer_state(browser: Chromium, timeout: float = 30.0) -> bytes:
    """The viewer's own account of what it holds (``WebHandle.viewer_state()``: the encoded
    ``GetStateResponse`` of its control API: open recordings with their ids, each timeline's
    time range, the time cursor). It stops changing once the recording has streamed in."""
    hexed = browser.evaluate(VIEWER_STATE_JS, timeout)
    return bytes.fromhex(hexed) if isinstance(hexed, str) else b""


def wait_until_loaded(
    browser: Chromium, settle: float, timeout: float, interval: float = 0.5
) -> tuple[bytes, bool]:
    """Poll :func:`viewer_state` until it names a recording and has not changed for
    ``settle`` s (everything sent has been ingested), or ``timeout`` s have passed. Returns
    the last state and whether it settled."""
    deadline = time.monotonic() + timeout
    last = viewer_state(browser, _left(deadline))
    since = time.monotonic()
    while time.monotonic() < deadline:
        time.sleep(interval)
        state = viewer_state(browser, _left(deadline))
        if state != last:
            last, since = state, time.monotonic()
        elif b"recording_id=" in state and time.monotonic() - since >= settle:
            return last, True
    return last, False


def changed_fraction(a: bytes, b: bytes) -> float:
    """The fraction of pixels that differ between two PNGs (1.0 when their sizes differ)."""
    first, second = (Image.open(io.BytesIO(png)).convert("RGB") for png in (a, b))
    if first.size != second.size:
        return 1.0
    changed = ImageChops.difference(first, second).convert("L").point(lambda v: 255 if v else 0)
    return changed.histogram()[255] / (first.width * first.height)


def wait_until_drawn(browser: Chromium, timeout: float, interval: float = 0.5, still: float = 0.005) -> bytes:
    """Screenshots until two in a row differ in less than ``still`` of their pixels (the viewer
    has laid itself out at the current size; a graph view's layout may go on moving a little),
    or ``timeout`` s; returns the last."""
    deadline = time.monotonic() + timeout
    last = browser.screenshot()
    while time.monotonic() < deadline:
        time.sleep(interval)
        shot = browser.screenshot()
        if shot == last or changed_fraction(shot, last) < still:
            return shot
        last = shot
    return last


@dataclass
class Shot:
    """What :func:`take_screenshot` saw."""

    png: bytes
    loaded: bool  # the viewer's state settled (the whole recording was ingested) in time
    state: bytes  # the viewer's last state (see :func:`viewer_state`)
    viewer_pid: int  # the viewer process started (and stopped)
    browser_pid: int  # the Chromium process started (and stopped)
    errors: list[str] = field(default_factory=list)  # console errors and exceptions of the page


def take_screenshot(
    target: Path,
    *,
    chromium: str,
    width: int = 1600,
    height: int = 1000,
    load_size: tuple[int, int] = LOAD_SIZE,
    start_timeout: float = 60.0,
    settle: float = 3.0,
    load_timeout: float = 300.0,
    extra_flags: tuple[str, ...] = (),
    log: Callable[[str], object] = print,
) -> Shot:
    """Serve ``target`` (run folder or .rrd) as ``roco view --web`` does, open it in headless
    Chromium and screenshot it at ``width`` × ``height``. The recording streams in while the
    page is ``load_size`` (in software rendering the viewer ingests data between frames, and a
    small frame is drawn several times faster); then the page takes its final size and is
    drawn. Stops the viewer and the browser it started."""
    viewer = start_viewer(target, web=True)
    try:
        assert viewer.web_url is not None
        log(f"viewer pid {viewer.pid} at {viewer.web_url}")
        with Chromium(chromium, *load_size, extra_flags=extra_flags) as browser:
            log(f"chromium pid {browser.pid}")
            t0 = time.monotonic()
            browser.navigate(viewer.web_url)
            wait_for_viewer(browser, start_timeout)
            log(f"viewer app started after {time.monotonic() - t0:.1f} s")
            state, loaded = wait_until_loaded(browser, settle, load_timeout)
            log(f"recording {'loaded' if loaded else 'still loading'} after {time.monotonic() - t0:.1f} s")
            browser.resize(width, height)
            png = wait_until_drawn(browser, timeout=60.0)
            log(f"screenshot taken after {time.monotonic() - t0:.1f} s")
            return Shot(
                png=png,
                loaded=loaded,
                state=state,
                viewer_pid=viewer.pid,
                browser_pid=browser.pid,
                errors=list(browser.errors),
            )
    finally:
        stop_viewer(viewer)


def _size(text: str) -> tuple[int, int]:
    width, sep, height = text.partition("x")
    if not (sep and width.isdigit() and height.isdigit()):
        raise argparse.ArgumentTypeError(f"expected WxH, e.g. 400x250, not {text!r}")
    return int(width), int(height)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0] if __doc__ else None)
    parser.add_argument("target", nargs="?", type=Path, help="run folder or .rrd (default: newest run)")
    parser.add_argument(
        "--runs-dir", type=Path, default=ROOT / "runs", help="where to look for the newest run"
    )
    parser.add_argument(
        "--out", type=Path, default=Path("viewer.png"), help="PNG to write (default: viewer.png)"
    )
    parser.add_argument("--width", type=int, default=1600)
    parser.add_argument("--height", type=int, default=1000)
    parser.add_argument("--timeout", type=float, default=60.0, help="s for the viewer app to start")
    parser.add_argument(
        "--settle",
        type=float,
        default=3.0,
        help="s the viewer's state must stay unchanged to count as loaded",
    )
    parser.add_argument("--load-timeout", type=float, default=300.0, help="s to wait for that at most")
    parser.add_argument(
        "--load-size",
        type=_size,
        default=LOAD_SIZE,
        help=f"page size WxH while the recording streams in (default: {LOAD_SIZE[0]}x{LOAD_SIZE[1]})",
    )
    parser.add_argument("--strict", action="store_true", help="exit 1 if the recording had not all loaded")
    parser.add_argument(
        "--chromium-flag", action="append", default=[], help="one more Chromium flag (repeatable)"
    )
    args = parser.parse_args(argv)

    chromium = find_chromium()
    if chromium is None:
        print("viewer_screenshot: Chromium not found on PATH (apt-get install -y chromium)", file=sys.stderr)
        return 2
    target = args.target if args.target is not None else newest_run(args.runs_dir)
    if target is None:
        print(f"viewer_screenshot: no run with a {RECORDING_FILE} under {args.runs_dir}", file=sys.stderr)
        return 1
    try:
        shot = take_screenshot(
            target,
            chromium=chromium,
            width=args.width,
            height=args.height,
            load_size=args.load_size,
            start_timeout=args.timeout,
            settle=args.settle,
            load_timeout=args.load_timeout,
            extra_flags=tuple(args.chromium_flag),
            log=lambda line: print(f"viewer_screenshot: {line}", flush=True),
        )
    except (BrowserError, OSError, RuntimeError, TimeoutError) as exc:
        print(f"viewer_screenshot: {exc}", file=sys.stderr)
        return 1
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_bytes(shot.png)
    print(f"viewer_screenshot: wrote {args.out} ({len(shot.png) // 1024} KiB)")
    if shot.errors:
        print(
            f"viewer_screenshot: {len(shot.errors)} page error(s) (requests to outside hosts are refused"
            f" on purpose), first: {shot.errors[0].splitlines()[0]}"
        )
    if not shot.loaded:
        print(
            "viewer_screenshot: the recording was still loading when the screenshot was taken",
            file=sys.stderr,
        )
        return 1 if args.strict else 0
    return 0


if __name__ == "__main__":
    sys.exit(main())
