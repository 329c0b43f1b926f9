"""Zenoh's own log in the router process: captured, read, and passed on at the operator's level.

Zenoh (a Rust library) writes its log to file descriptor 1 at the levels ``RUST_LOG`` names
(tracing's EnvFilter syntax; :data:`DEFAULT_LEVEL` when unset). The router turns on more than
that for its refusal watch (services/runtime/refusal_watch.py: the ACL's decisions at TRACE,
accepted connections at DEBUG); those lines are read, never passed on. What goes on to the
router's standard output (``docker compose logs router``) is every line the reader does not
take whose level is at least the least severe level ``RUST_LOG`` itself names, its terminal
colours removed: with ``RUST_LOG=info`` no DEBUG or TRACE line reaches the log, whatever the
watch turned on. Used by services/runtime/router.py only.
"""

from __future__ import annotations

import os
import re
import sys
import threading
from collections.abc import Callable
from typing import IO

import zenoh

__all__ = ["DEFAULT_LEVEL", "capture_zenoh_log", "least_level", "level_of", "passes"]

DEFAULT_LEVEL = "info"
"""Zenoh's log level in the router when ``RUST_LOG`` is unset (deploy/compose.yaml sets it too)."""
LEVELS = ("trace", "debug", "info", "warn", "error")
"""tracing's levels, least severe first."""

_ANSI = re.compile(r"\x1b\[[0-9;]*m")
_LINE_LEVEL = re.compile(r"^\S+\s+(TRACE|DEBUG|INFO|WARN|ERROR)\s")


def least_level(rust_log: str) -> str:
    """The least severe level (of :data:`LEVELS`) that the directives ``rust_log`` name, bare
    (``info``) or for a target (``zenoh_link_tls=debug``); :data:`DEFAULT_LEVEL` when they name
    none. ``off`` and unknown words name no level."""
    named = [d.rpartition("=")[2].strip().lower() for d in rust_log.split(",") if d.strip()]
    found = [LEVELS.index(level) for level in named if level in LEVELS]
    return LEVELS[min(found)] if found else DEFAULT_LEVEL


def level_of(line: str) -> str | None:
    """The level (lower case) of one line of Zenoh's log, colours removed; None for a line
    that does not start as a record does (time, level)."""
    found = _LINE_LEVEL.match(_ANSI.sub("", line))
    return found.group(1).lower() if found else None


def passes(line: str, least: str) -> bool:
    """Whether ``line`` goes on to the router's log at level ``least``: a line of no level
    does, a record at or above ``least`` does."""
    level = level_of(line)
    return level is None or LEVELS.index(level) >= LEVELS.index(least)


def capture_zenoh_log(on_line: Callable[[str], bool], turn_on: str = "") -> None:
    """Start Zenoh's log at ``RUST_LOG`` (:data:`DEFAULT_LEVEL` when unset) plus the directives
    ``turn_on`` and hand every line Zenoh writes to ``on_line`` on a thread of its own; a line
    it does not take (returns False) goes on to this process's standard output, colours
    removed, when :func:`passes` at ``RUST_LOG``'s least level. Zenoh writes its log to file
    descriptor 1, which becomes a pipe; Python's own ``sys.stdout`` keeps the original output.
    Call once, before the first session."""
    read_fd, write_fd = os.pipe()
    saved = os.dup(1)
    os.dup2(write_fd, 1)
    os.close(write_fd)
    sys.stdout.flush()
    sys.stdout = os.fdopen(saved, "w", buffering=1)
    rust_log = os.environ.get("RUST_LOG", "").strip() or DEFAULT_LEVEL
    least = least_level(rust_log)
    os.environ["RUST_LOG"] = f"{rust_log},{turn_on}" if turn_on else rust_log
    zenoh.try_init_log_from_env()

    def pump(out: IO[str]) -> None:
        # must never stop: Zenoh would block on a full pipe, and the router with it
        with os.fdopen(read_fd, "r", errors="replace") as lines:
            for line in lines:
                try:
                    taken = on_line(line)
                except Exception as exc:  # a line the reader chokes on is passed on, noted
                    taken = False
                    out.write(f"roco router: reading Zenoh's log: {exc!r}\n")
                if not taken and passes(line, least):
                    out.write(_ANSI.sub("", line))
                    out.flush()

    threading.Thread(target=pump, args=(sys.stdout,), name="zenoh-log", daemon=True).start()
