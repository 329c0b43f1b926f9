"""The world as a run left it: the simulated world's final scene, read for judging the run
(``roco chaos``'s questions, ``roco run``'s last line), never for the agents."""

from __future__ import annotations

import logging
from pathlib import Path

from services.runtime.run_folder import load_launch_env
from shared.fipa_codec.languages.l_sd import Observation
from shared.settings import Settings

__all__ = ["MAX_SCENE_BYTES", "final_world", "judged_world", "world_content"]

log = logging.getLogger(__name__)

MAX_SCENE_BYTES = 1 << 20
"""Largest final scene read (1 MiB; the kitchen's is 1.4 kB)."""


def final_world(run_dir: Path) -> Observation | None:
    """The ground truth of the world as the run left it (``judged_world``), None without one."""
    judged = judged_world(run_dir)
    return None if judged is None else judged[0]


def judged_world(run_dir: Path) -> tuple[Observation, str] | None:
    """The ground truth of the world as the run left it in ``run_dir`` (every known object's
    pose, containers' particle counts): the world process's final scene (velma/world/files.py
    ``FINAL_FILE``) for the scene the launch environment names (ROCO_SEED, ROCO_POSE_SEED): for
    judging a run, never for the agents; with where it comes from. None when there is none
    (``ROCO_WORLD=loop``), or it does not fit (logged)."""
    from velma.executor.checkpoint import observe_scene
    from velma.world.files import FINAL_FILE

    scene = run_dir / FINAL_FILE
    if not scene.is_file():
        return None
    env = load_launch_env(run_dir) or {}
    try:
        read = Settings.from_env(env, only=("seed", "pose_seed"))
        seed, pose_seed = read.seed, read.pose_seed
        if (size := scene.stat().st_size) > MAX_SCENE_BYTES:
            raise ValueError(f"{size} B: not a scene of the kitchen")
        return observe_scene(scene.read_bytes(), seed=seed, pose_seed=pose_seed), "the world's final scene"
    except (OSError, ValueError) as exc:
        log.warning("final world not judged from %s: %s", scene, exc)
        return None


def world_content(run_dir: Path, container: str) -> tuple[int, int] | None:
    """The content spheres the simulated world holds in ``container`` as the run in ``run_dir``
    left it, and the content's total: the simulation's truth (``judged_world``), not the robot's
    count. None without a final scene of the world (``ROCO_WORLD=loop``, a run on no simulated
    world) or when it has no such container."""
    judged = judged_world(run_dir)
    if judged is None:
        return None
    obs = judged[0]
    inside = next((o.particles_inside for o in obs.objects if o.name == container), None)
    return None if inside is None else (inside, obs.total_particles)
