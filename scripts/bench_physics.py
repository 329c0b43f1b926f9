"""What the physics step alone costs in ag_ex's cycle, and what MuJoCo's options change.

The loop's goal is the whole cycle's work (primitive, control law, physics step, hand-offs) at
p99 within services/bench/targets.py ``LOOP_WORK_P99``. This benchmark measures the floor
under that figure: the physics step
(``mujoco.mj_step``, MuJoCo's own C code) as the loop times it (the *physics* part of
velma/executor/timing.py), over the scripted pour of velma/scenario.py, paced as fast as the
machine goes (``Executor(realtime=False)``; the real-time loop adds scheduling, not work).
Each variant runs the whole pour once and prints the physics part's p50/p99/max, the cycle's
compute p50/p99 and the pour's outcome (all commands ok; spheres in the bowl), so a setting
that is cheaper but drops the jar shows as such.

Variants (the model as ag_ex runs it, with one change each):

- ``baseline``: velma/model/mjcf.py's ``<option>`` (Newton, implicitfast, pyramidal cones,
  impratio 30, 60 iterations, tolerance 1e-8, constraint islands off), self-collision on,
  frictionless content spheres on three slide joints each (velma/model/scene.py);
- solver and option settings: ``CG``, ``PGS``, ``elliptic`` cones, ``iterations=3``,
  ``tolerance=1e-6``, ``Euler``, islands on (MuJoCo's default, which ag_ex disables), sleeping
  on (``mjENBL_SLEEP``, MuJoCo ≥ 3.3; measured with islands on, as MuJoCo defaults);
- ``no self-collision``: the robot's geoms no longer collide with each other (what the robot's
  self-collision costs);
- ``content with wall friction``: the content as it was before (free joints, frictionless
  against each other only, Coulomb friction 0.6 against the jar, bowl, table and hand): the
  model that ag_ex no longer runs, for the before/after comparison.

Usage: ``python scripts/bench_physics.py [--only NAME ...] [--seed N]``; ≈ 20 s a variant.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import benchlib  # noqa: E402  (scripts/benchlib.py, beside this file)
import mujoco  # noqa: E402

Tweak = Callable[[mujoco.MjModel], None]


def _opt(**values: object) -> Tweak:
    def tweak(model: mujoco.MjModel) -> None:
        for key, value in values.items():
            setattr(model.opt, key, value)

    return tweak


def _no_self_collision(model: mujoco.MjModel) -> None:
    from velma.model.mjcf import ROBOT_CONTYPE, SCENE_CONTYPE

    robot = model.geom_contype == ROBOT_CONTYPE
    model.geom_conaffinity[robot] = SCENE_CONTYPE  # robot geoms still touch the scene


OPTION_VARIANTS: dict[str, Tweak] = {
    "baseline": lambda m: None,
    "CG": _opt(solver=mujoco.mjtSolver.mjSOL_CG),
    "PGS": _opt(solver=mujoco.mjtSolver.mjSOL_PGS),
    "elliptic": _opt(cone=mujoco.mjtCone.mjCONE_ELLIPTIC),
    "iterations=3": _opt(iterations=3),
    "tolerance=1e-6": _opt(tolerance=1e-6),
    "Euler": _opt(integrator=mujoco.mjtIntegrator.mjINT_EULER),
    "islands on": _opt(disableflags=0),
    "sleeping on": _opt(disableflags=0, enableflags=int(mujoco.mjtEnableBit.mjENBL_SLEEP)),
    "no self-collision": _no_self_collision,
}
CONTENT_VARIANTS = ("content with wall friction",)


@contextmanager
def _content_with_wall_friction() -> Iterator[None]:
    """Within the block, Runtime builds its kitchen with the content as it was before (see
    module docstring); restores the real loader after."""
    import velma.executor.runtime as runtime
    from velma.model.scene import build_spec, particle_names

    real = runtime.load_kitchen

    def load(n_particles: int, seed: int = 0, pose_seed: int | None = None) -> mujoco.MjModel:
        spec = build_spec(n_particles, seed, pose_seed)
        for name in particle_names(n_particles):
            body = spec.body(name)
            for joint in list(body.joints):
                spec.delete(joint)
            body.add_freejoint()
            for geom in body.geoms:
                geom.priority = 0  # the walls' condim (3) wins again
                geom.friction = [0.6, 0.01, 0.001]
        return spec.compile()

    runtime.load_kitchen = load  # type: ignore[assignment]
    try:
        yield
    finally:
        runtime.load_kitchen = real


def run(name: str, seed: int) -> str:
    """One pour under variant ``name``; a table row."""
    from shared.fipa_codec.languages.l_ex import CommandResult
    from velma.executor import Executor
    from velma.executor.runtime import Runtime
    from velma.scenario import run_pour

    if name in CONTENT_VARIANTS:
        with _content_with_wall_friction():
            rt = Runtime(seed=seed)
    else:
        rt = Runtime(seed=seed)
        OPTION_VARIANTS[name](rt.model)
    ex = Executor(runtime=rt)
    ex.start()
    try:
        commands, results = run_pour(ex.submit)
    finally:
        ex.stop()
    stats = ex.timing()
    physics = next(p for p in stats.parts if p.name == "physics")
    ok = len(results) == len(commands) and all(r.ok for r in results if isinstance(r, CommandResult))
    seen = [o for r in results if not isinstance(r, CommandResult) for o in r.objects if o.name == "bowl"]
    bowl = seen[-1].particles_inside if seen else None
    outcome = f"{'ok' if ok else 'FAILED'}, {bowl} in the bowl"
    return (
        f"| {name} | {stats.cycles} | {physics.p50_us:.0f} | {physics.p99_us:.0f} | {physics.max_us:.0f} "
        f"| {stats.compute_p50_us:.0f} | {stats.compute_p99_us:.0f} | {outcome} |"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    variants = [*OPTION_VARIANTS, *CONTENT_VARIANTS]
    parser.add_argument("--only", nargs="+", choices=variants, help="run only these variants")
    parser.add_argument("--seed", type=int, default=0, help="content jitter seed (default 0)")
    args = parser.parse_args()
    print(f"Measured on: {benchlib.machine(('mujoco', 'pin'))}")
    print("Physics: mj_step as the loop times it; compute: the whole cycle (fast pacing). µs.")
    print()
    print("| variant | cycles | physics p50 | physics p99 | physics max | cycle p50 | cycle p99 | pour |")
    print("|---|---|---|---|---|---|---|---|")
    for name in args.only or variants:
        print(run(name, args.seed), flush=True)


if __name__ == "__main__":
    main()
