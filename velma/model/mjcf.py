"""What the robot's and the kitchen's MJCF writers share (velma/model/robot_mjcf.py,
velma/model/kitchen_mjcf.py): the vector types, the contact bits, the simulation options, the
number format and the inertias of simple shapes, and the XML line writer."""

from __future__ import annotations

Vec = tuple[float, float, float]
Quat = tuple[float, float, float, float]

# Contact bits: robot geoms contype 2, conaffinity 3; scene geoms contype 1, conaffinity 3
# (why: "Self-collision" in velma/model/robot_mjcf.py).
ROBOT_CONTYPE, ROBOT_CONAFFINITY = 2, 3
SCENE_CONTYPE, SCENE_CONAFFINITY = 1, 3

# Simulation options (facts, "MuJoCo notes" and "Control on the real robot": 1 kHz loop,
# impratio ≈ 10). Solver: Newton, which converges in 1–3 iterations where CG used up to 60
# (measured over the scripted pour on this 2-core VM, mujoco 4.0.0: mj_step p50
# 292 → 231 µs, p99 630 → 468 µs, every grasp and 18/18 spheres in the bowl on seeds 1–4 of
# scripts/bench_pour_seeds.py --mode script). The cap of 60 is kept as a bound. Friction
# cones: pyramidal, not the elliptic cones the facts suggest for multi-finger grasps: over the
# same pour they cut mj_step's p99 from ≈ 486 to ≈ 377 µs (p50 ≈ 229 µs either way), with
# every grasp held and 18/18 spheres in the bowl (seeds: scripts/bench_pour_seeds.py, see
# docs/executor.md). Capping the iterations at 3 or 4 instead lets the jar slip from the grasp.
# impratio 30 with the pyramidal cones: at 10 the bowl slid ≈ 15 mm in the hand over the
# tidy-up's carries (≈ 9 mm with elliptic cones at 10, and again at 30; tests/velma/
# test_velma_kitchen.py puts it back within 15 mm); mj_step over the pour: p50 202 → 203 µs,
# p99 391 → 399 µs. Constraint islands off (MuJoCo solves the whole system at once instead of
# finding its independent parts every step; the same physics): over the pour, three runs each
# of scripts/bench_physics.py, the physics step p50 145–148 → 136–137 µs, p99 264–274 →
# 249–253 µs (docs/bench/physics.md).
OPTION = (
    '<option timestep="0.001" integrator="implicitfast" cone="pyramidal" impratio="30" '
    'solver="Newton" iterations="60" tolerance="1e-8"><flag island="disable"/></option>'
)


def add(a: Vec, b: Vec) -> Vec:
    """Sum of two 3-vectors."""
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


def f(*values: float) -> str:
    """Format numbers for MJCF attributes (12 significant digits, no '-0')."""
    return " ".join(f"{v + 0.0:.12g}" for v in values)


def cylinder_inertia(mass: float, radius: float, length: float) -> Vec:
    """Principal inertia (Ixx, Iyy, Izz) of a uniform solid cylinder along z, kg·m²."""
    ixx = mass * (3 * radius**2 + length**2) / 12
    return (ixx, ixx, mass * radius**2 / 2)


def box_inertia(mass: float, half: Vec) -> Vec:
    """Principal inertia of a uniform box with half-sizes ``half`` (m), kg·m²."""
    a, b, c = (2 * h for h in half)
    return (mass * (b * b + c * c) / 12, mass * (a * a + c * c) / 12, mass * (a * a + b * b) / 12)


def inertial(pos: Vec, mass: float, diag: Vec) -> str:
    """An MJCF ``<inertial>`` element (m, kg, kg·m²)."""
    return f'<inertial pos="{f(*pos)}" mass="{f(mass)}" diaginertia="{f(*diag)}"/>'


class Writer:
    """Accumulates indented XML lines."""

    def __init__(self) -> None:
        self.lines: list[str] = []
        self.depth = 0

    def add(self, line: str) -> None:
        self.lines.append("  " * self.depth + line)

    def open(self, line: str) -> None:
        self.add(line)
        self.depth += 1

    def close(self, tag: str) -> None:
        self.depth -= 1
        self.add(f"</{tag}>")
