"""The files a world process keeps in its run folder (velma/world/main.py): the name of its
robot link, for the controller that attaches to it, and the kitchen as the world left it, for
judging the run. Imports nothing heavy: ag_ex's communication side reads the link's name here
without loading the physics."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

LINK_FILE = "world.link"
"""The file in the run folder that names the world's link block (one line, written whole)."""
FINAL_FILE = "world_final.f64"
"""The file in the run folder that holds the kitchen as the world left it: the time (s), then
MuJoCo's ``qpos``, as raw float64."""


def link_name(run_dir: Path) -> str | None:
    """The name of the link the world of ``run_dir`` serves, or None when no world has
    written one (not started yet, or ended)."""
    try:
        return (run_dir / LINK_FILE).read_text().strip() or None
    except FileNotFoundError:
        return None


def write_whole(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file beside it, replaced in one step: a
    reader sees the old content or the new, never a part. Raises OSError."""
    partial = path.with_name(path.name + ".tmp")
    partial.write_bytes(data)
    partial.replace(path)


WATCH_PERIOD_S = 0.5
"""How often (s) a controller reads the run folder's link name (``LinkWatch``)."""


class LinkWatch:
    """Tells a controller attached to link ``current`` when the world of ``run_dir`` names
    another link: the world process was started again (the robot's power cycle: a fresh
    kitchen, its time from 0). Reads ``LINK_FILE`` at most every ``period_s`` s of ``clock``;
    a world that is away (no file) renews nothing."""

    def __init__(
        self,
        run_dir: Path,
        current: str,
        *,
        period_s: float = WATCH_PERIOD_S,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.run_dir, self.current = run_dir, current
        self.period_s, self.clock = period_s, clock
        self._next = clock() + period_s

    def renewed(self) -> str | None:
        """The new link's name the first time the world names one other than ``current`` (it
        becomes ``current``), else None (also between two reads)."""
        now = self.clock()
        if now < self._next:
            return None
        self._next = now + self.period_s
        name = link_name(self.run_dir)
        if name is None or name == self.current:
            return None
        self.current = name
        return name
