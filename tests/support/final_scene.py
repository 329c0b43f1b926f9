"""A planted final scene of the kitchen (velma/world/files.py ``FINAL_FILE``: the time, then
MuJoCo's ``qpos``, as raw float64), as a world process leaves it in its run folder, for the
judges that read the world's truth (services/scenario/chaos.py ``judged_world``) without
running a fleet: the bowl set down where the test says, with as many of the content spheres in
it as the test says, the rest on the floor."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from velma.model.scene import N_PARTICLES, PARTICLE_PREFIX, load_kitchen
from velma.world.files import FINAL_FILE

BOWL_PLACE = (0.34, -0.46, 0.75)
"""Where a plan puts the bowl on the table (world, m; its frame, the bottom centre): the place
of tests/spec_check/fixtures/urgent_mid_pour's plan."""


def final_scene(
    in_bowl: int,
    *,
    bowl_at: tuple[float, float, float] = BOWL_PLACE,
    jar_at: tuple[float, float, float] | None = None,
) -> bytes:
    """The kitchen of seed 0 (no pose seed) with the bowl upright at ``bowl_at`` (world, m),
    ``in_bowl`` (0..18) content spheres inside it (their centres on a ring 2 cm from its axis,
    1.5 cm above its inner bottom) and the others on the floor, the jar at ``jar_at`` (None: where
    it starts); the simulated time 60 s. Raises ValueError for an ``in_bowl`` out of range."""
    if not 0 <= in_bowl <= N_PARTICLES:
        raise ValueError(f"in_bowl={in_bowl}: the jar holds {N_PARTICLES} spheres")
    model = load_kitchen(N_PARTICLES, 0, None)
    qpos = model.qpos0.copy()

    def free(name: str, at: tuple[float, float, float]) -> None:
        adr = int(model.jnt_qposadr[model.body(name).jntadr[0]])
        qpos[adr : adr + 7] = (*at, 1.0, 0.0, 0.0, 0.0)

    free("bowl", bowl_at)
    if jar_at is not None:
        free("jar", jar_at)
    inner = model.site("bowl_inner")
    floor = float(bowl_at[2] + inner.pos[2] - inner.size[1] + 0.015)
    for i in range(N_PARTICLES):
        body = model.body(f"{PARTICLE_PREFIX}{i}")
        a = 2 * math.pi * i / N_PARTICLES
        inside = (bowl_at[0] + 0.02 * math.cos(a), bowl_at[1] + 0.02 * math.sin(a), floor)
        target = inside if i < in_bowl else (1.5, -1.0 + 0.03 * i, 0.009)
        adr = int(model.jnt_qposadr[body.jntadr[0]])  # slide joints along the world's x, y, z
        qpos[adr : adr + 3] = np.asarray(target) - body.pos
    return np.concatenate(([60.0], qpos)).astype(np.float64).tobytes()


def plant_final_scene(run_dir: Path, in_bowl: int, **where: tuple[float, float, float]) -> Path:
    """Write :func:`final_scene` (``in_bowl``, ``bowl_at``, ``jar_at``) into ``run_dir`` as the
    world process would; its path."""
    path = run_dir / FINAL_FILE
    path.write_bytes(final_scene(in_bowl, **where))
    return path
