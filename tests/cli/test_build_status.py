"""scripts/live_status.sh, the status line of scripts/build_image.sh's phases: the
command's output goes to its log and its exit status comes back; a status line is drawn and
erased on a terminal only."""

from __future__ import annotations

import os
import pty
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "scripts" / "live_status.sh"
ERASE = b"\r\x1b[K"


def call(log: Path, command: str) -> str:
    return f'. {SCRIPT}; live_status "phase test" {log} sh -c "{command}"; echo "status=$?"'


def test_off_a_terminal_the_log_fills_and_nothing_is_drawn(tmp_path: Path) -> None:
    log = tmp_path / "phase.log"
    done = subprocess.run(
        ["bash", "-c", call(log, "echo one; echo two >&2; exit 3")], capture_output=True, check=False
    )
    assert done.stdout == b"status=3\n"
    assert log.read_text().split() == ["one", "two"]


def test_on_a_terminal_the_status_line_is_erased_and_the_status_kept(tmp_path: Path) -> None:
    log = tmp_path / "phase.log"
    pid, fd = pty.fork()
    if pid == 0:  # the child: bash on the pseudo-terminal
        os.execvp("bash", ["bash", "-c", call(log, "echo building; exit 0")])
    out = b""
    while True:
        try:
            chunk = os.read(fd, 1024)
        except OSError:  # EIO: the child closed the terminal
            break
        if not chunk:
            break
        out += chunk
    os.waitpid(pid, 0)
    os.close(fd)
    assert out.replace(b"\r\n", b"\n").endswith(ERASE + b"status=0\n"), out
    assert log.read_text() == "building\n"
