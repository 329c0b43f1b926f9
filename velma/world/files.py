"""The files a world process keeps in its run folder (velma/world/main.py): the name of its
robot link, for the controller that attaches to it, and the kitchen as the world left it, for
judging the run. Imports nothing heavy: ag_ex's communication side reads the link's name here
without loading the physics."""

from __future__ import annotations

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
