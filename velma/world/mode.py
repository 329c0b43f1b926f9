"""Where the kitchen's physics runs, as the fleet's environment says (``ROCO_WORLD``): in a world
process of its own beside ag_ex (``process``, the default: velma/world/main.py, the robot link
of velma/world/link.py), or inside ag_ex's loop (``loop``: one process, as before the split, to
measure it: docs/bench/loop.md; the kitchen then ends with ag_ex, and a restarted ag_ex starts
it anew, so faults and restarts need ``process``). Imports nothing heavy: the launcher reads
it."""

from __future__ import annotations

from collections.abc import Mapping

from shared.settings import Settings

WORLD_SERVICE = "world"
"""The world process's name among a fleet's processes (its log: ``logs/world.stderr``)."""


def world_in_process(env: Mapping[str, str] | None = None) -> bool:
    """False when ``ROCO_WORLD=loop`` in ``env`` (default ``os.environ``, read now), else True.
    Raises ValueError for a value other than ``loop`` and ``process``."""
    return Settings.from_env(env, only=("world",)).world == "process"
