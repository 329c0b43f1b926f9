"""Numerical inverse kinematics of one arm's grip frame (damped least squares, Pinocchio).

Used by the executor to decide whether a MoveTool/Tilt target is reachable (``unreachable``)
and to give the Cartesian impedance law a null-space posture that agrees with the target.
Given a ``SelfCollision`` check, a posture in which the robot would touch itself is rejected:
the search first swivels the elbow — steps along the Jacobian's null space, both
ways, each re-converged onto the target — to the nearest posture that is free, and only then
goes on from its random starts.
Only the seven arm joints move; torso, head and hand joints keep their values in ``q``.
Joint limits are enforced by clamping each iterate, with a 0.05 rad margin.

Source: standard DLS IK (Wampler 1986); kinematics from velma.xml via Pinocchio.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Generator
from dataclasses import dataclass
from typing import Protocol

import numpy as np
import pinocchio as pin

from velma.control.joints import SIDES, Array, IntArray, arm_joints
from velma.control.robot_model import RobotModel
from velma.control.self_collision import SelfCollision

LIMIT_MARGIN = 0.05  # rad
SWIVEL_STEP = 0.1
"""Joint motion (rad, norm over the seven joints) per step of the elbow swivel."""
SWIVEL_STEPS = 16
"""Steps of the swivel each way (≈ 1.6 rad of self-motion)."""


class DlsKernel(Protocol):
    """One damped-least-squares iteration of ``_dls`` in compiled code: the compiled law's
    ``Law.dls_step`` (velma/control/_impedance.cpp; velma/control/compiled.py
    ``CompiledController.ik_kernel``), built from the same robot model. ``k``: the arm's index
    in ``SIDES``; ``q`` (nq,) float64, moved in place; ``target`` (12,): rotation (row-major 9)
    and position (3); ``posture`` (nq,) or empty; ``lo``, ``hi`` (7,). Returns (position
    error m, rotation error rad, converged)."""

    def dls_step(
        self,
        k: int,
        q: Array,
        target: Array,
        posture: Array,
        lo: Array,
        hi: Array,
        damping: float,
        pos_tol: float,
        rot_tol: float,
    ) -> tuple[float, float, bool]: ...


@dataclass(frozen=True)
class IkResult:
    """``q``: full Pinocchio configuration (rad, shape (33,)); ``ok``: converged within
    tolerance (and free of self-collision when checked); ``position_error`` (m) and
    ``rotation_error`` (rad) at ``q``; ``self_collision``: the geoms that would touch, when
    every converged posture the search found touched."""

    q: Array
    ok: bool
    position_error: float
    rotation_error: float
    self_collision: tuple[str, str] | None = None


def solve_ik_multi(
    robot: RobotModel,
    side: str,
    target: pin.SE3,
    q0: Array,
    *,
    restarts: int = 12,
    seed: int = 0,
    self_collision: SelfCollision | None = None,
    kernel: DlsKernel | None = None,
) -> IkResult:
    """``solve_ik`` from ``q0``, then (if that fails) from up to ``restarts`` deterministic
    random arm configurations; among converged solutions the one closest to ``q0`` wins.
    With ``self_collision``, converged postures in self-collision do not count. With
    ``kernel``, each iteration runs compiled (``DlsKernel``)."""
    search = IkSearch(
        robot, side, target, q0, restarts=restarts, seed=seed, self_collision=self_collision, kernel=kernel
    )
    while True:
        result = search.advance(1_000_000)
        if result is not None:
            return result


class IkSearch:
    """``solve_ik_multi`` as a resumable computation, for the 1 kHz loop: ``advance(n)`` runs
    at most ``n`` damped-least-squares iterations (≈ 20 µs each) and returns the result when
    the search has ended, else None. The search never blocks the loop for longer than the
    iterations it is given.

    ``data`` is the Pinocchio data the search may overwrite (default: a private one, so that
    the controller's ``robot.data`` is left alone). ``self_collision``: reject postures in
    self-collision (each check is ``CHECK_STEPS`` steps of the search, velma/control/self_collision.py)."""

    def __init__(
        self,
        robot: RobotModel,
        side: str,
        target: pin.SE3,
        q0: Array,
        *,
        restarts: int = 12,
        seed: int = 0,
        data: pin.Data | None = None,
        self_collision: SelfCollision | None = None,
        kernel: DlsKernel | None = None,
    ) -> None:
        self.iterations = 0
        self._gen = _search(
            robot, data or robot.model.createData(), side, target, q0, restarts, seed, self_collision, kernel
        )
        self._result: IkResult | None = None

    def advance(self, iterations: int) -> IkResult | None:
        """Run up to ``iterations`` iterations; the result once the search is over."""
        if self._result is not None:
            return self._result
        for _ in range(iterations):
            try:
                next(self._gen)
                self.iterations += 1
            except StopIteration as stop:
                self._result = stop.value
                return self._result
        return None


def _search(
    robot: RobotModel,
    data: pin.Data,
    side: str,
    target: pin.SE3,
    q0: Array,
    restarts: int,
    seed: int,
    self_collision: SelfCollision | None,
    kernel: DlsKernel | None,
) -> Generator[None, None, IkResult]:
    touching: tuple[str, str] | None = None
    idx = robot.v_indices(arm_joints(side))

    def free(result: IkResult) -> Generator[None, None, bool]:
        """Whether a converged posture is free of self-collision (``CHECK_STEPS`` + 1 search steps)."""
        nonlocal touching
        if self_collision is None:
            return True
        pin.forwardKinematics(robot.model, data, result.q)
        hit = yield from self_collision.colliding_steps(data, side, result.q[idx])
        yield None
        if hit is not None:
            touching = hit
        return hit is None

    first = yield from _dls(robot, data, side, target, q0, posture=q0, kernel=kernel)
    if first.ok and (yield from free(first)):
        return first
    if first.ok and self_collision is not None:  # swivel the elbow off the robot itself
        swivelled = []
        for direction in (1.0, -1.0):
            found = yield from _swivel(robot, data, side, target, first.q, direction, free, kernel)
            if found is not None:
                swivelled.append(found)
        if swivelled:
            return min(swivelled, key=lambda r: float(np.linalg.norm(r.q[idx] - q0[idx])))
    lo = robot.model.lowerPositionLimit[idx]
    hi = robot.model.upperPositionLimit[idx]
    rng = np.random.default_rng(seed)
    best: IkResult | None = None
    for _ in range(restarts):
        q = np.array(q0, dtype=float)
        q[idx] = rng.uniform(0.7 * lo, 0.7 * hi)
        r = yield from _dls(robot, data, side, target, q, kernel=kernel)
        if (
            r.ok
            and (best is None or np.linalg.norm(r.q[idx] - q0[idx]) < np.linalg.norm(best.q[idx] - q0[idx]))
            and (yield from free(r))
        ):
            best = r
            if np.linalg.norm(r.q[idx] - q0[idx]) < 1.0:
                break
    if best is not None:
        return best
    if touching is not None:  # every converged posture touched the robot itself
        return IkResult(first.q, False, first.position_error, first.rotation_error, touching)
    return first


def _arm(robot: RobotModel, side: str) -> tuple[IntArray, Array, Array, int]:
    """The arm's velocity indices, its joint bounds (limits less ``LIMIT_MARGIN``, rad) and the
    grip frame's id."""
    idx = robot.v_indices(arm_joints(side))
    lo = robot.model.lowerPositionLimit[idx] + LIMIT_MARGIN
    hi = robot.model.upperPositionLimit[idx] - LIMIT_MARGIN
    return idx, lo, hi, robot.grip_frame_id[side]


def _swivel(
    robot: RobotModel,
    data: pin.Data,
    side: str,
    target: pin.SE3,
    q_start: Array,
    direction: float,
    free: Callable[[IkResult], Generator[None, None, bool]],
    kernel: DlsKernel | None,
) -> Generator[None, None, IkResult | None]:
    """Self-motion from ``q_start`` (a posture at ``target``): ``SWIVEL_STEPS`` steps of
    ``SWIVEL_STEP`` along the null space of the grip Jacobian (its last right singular vector,
    kept pointing the same way; ``direction`` ±1 picks the way), each re-converged onto
    ``target``. The first posture ``free`` accepts, or None (none did, or the arm left the
    target or met its limits)."""
    model = robot.model
    idx, lo, hi, fid = _arm(robot, side)
    q = np.array(q_start, dtype=float)
    previous: Array | None = None
    for _ in range(SWIVEL_STEPS):
        jac = pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL)[:, idx]
        null = np.linalg.svd(jac)[2][-1]
        if previous is None:
            null = direction * null
        elif float(null @ previous) < 0.0:
            null = -null
        previous = null
        stepped = q[idx] + SWIVEL_STEP * null
        if np.any(stepped < lo) or np.any(stepped > hi):
            return None
        q[idx] = stepped
        result = yield from _dls(robot, data, side, target, q, max_iter=20, posture=q, kernel=kernel)
        if not result.ok:
            return None
        q = result.q
        if (yield from free(result)):
            return result
    return None


def solve_ik(
    robot: RobotModel,
    side: str,
    target: pin.SE3,
    q0: Array,
    *,
    max_iter: int = 200,
    pos_tol: float = 2e-3,
    rot_tol: float = 1e-2,
    damping: float = 1e-3,
    posture: Array | None = None,
) -> IkResult:
    """Arm joints of ``side`` that put the grip frame at ``target`` (world), from ``q0``.

    ``posture`` (shape (33,)), if given, pulls the redundant (elbow) DOF towards it in the
    Jacobian's null space. Never raises for an unreachable target: returns ``ok=False``.
    Uses (overwrites) ``robot.data``.
    """
    gen = _dls(
        robot,
        robot.data,
        side,
        target,
        q0,
        max_iter=max_iter,
        pos_tol=pos_tol,
        rot_tol=rot_tol,
        damping=damping,
        posture=posture,
    )
    while True:
        try:
            next(gen)
        except StopIteration as stop:
            result: IkResult = stop.value
            return result


def _dls(
    robot: RobotModel,
    data: pin.Data,
    side: str,
    target: pin.SE3,
    q0: Array,
    *,
    max_iter: int = 200,
    pos_tol: float = 2e-3,
    rot_tol: float = 1e-2,
    damping: float = 1e-3,
    posture: Array | None = None,
    kernel: DlsKernel | None = None,
) -> Generator[None, None, IkResult]:
    """The DLS iteration of ``solve_ik``; yields after each iteration. With ``kernel`` each
    iteration runs compiled; this Python loop is its reference (tests/velma/test_ik.py)."""
    model = robot.model
    idx, lo, hi, fid = _arm(robot, side)
    q = np.array(q0, dtype=float)
    q[idx] = np.clip(q[idx], lo, hi)
    if kernel is not None:
        compiled = _dls_compiled(
            kernel, side, target, q, lo, hi, max_iter, pos_tol, rot_tol, damping, posture
        )
        return (yield from compiled)
    target_position = target.translation  # pin.SE3 copies on every read: once
    damped = damping * np.eye(6)
    rhs = np.empty((6, 8))  # [err | J]: one solve per iteration (the cycle's budget)
    perr = rerr = float("inf")
    for _ in range(max_iter):
        pin.framesForwardKinematics(model, data, q)
        cur = data.oMf[fid]
        err = pin.log6(cur.actInv(target)).vector  # in the current grip frame
        perr = math.dist(target_position, cur.translation)
        rerr = math.hypot(*err[3:])
        if perr < pos_tol and rerr < rot_tol:
            return IkResult(q, True, perr, rerr)
        jac = pin.computeFrameJacobian(model, data, q, fid, pin.LOCAL)[:, idx]
        rhs[:, 0] = err
        rhs[:, 1:] = jac
        sol = np.linalg.solve(jac @ jac.T + damped, rhs)
        dq = jac.T @ sol[:, 0]
        if posture is not None:  # (I − Jᵀ(JJᵀ + λI)⁻¹J) times the pull toward the posture
            pull = 0.1 * (posture[idx] - q[idx])
            dq += pull - jac.T @ (sol[:, 1:] @ pull)
        step = float(np.max(np.abs(dq)))
        if step > 0.3:
            dq *= 0.3 / step
        q[idx] = np.clip(q[idx] + dq, lo, hi)
        yield None
    return IkResult(q, perr < pos_tol and rerr < rot_tol, perr, rerr)


def _dls_compiled(
    kernel: DlsKernel,
    side: str,
    target: pin.SE3,
    q: Array,
    lo: Array,
    hi: Array,
    max_iter: int,
    pos_tol: float,
    rot_tol: float,
    damping: float,
    posture: Array | None,
) -> Generator[None, None, IkResult]:
    """``_dls``'s loop with each iteration in ``kernel`` (q already clamped to its bounds)."""
    k = SIDES.index(side)
    goal = np.concatenate([target.rotation.reshape(9), target.translation])
    pull = np.empty(0) if posture is None else np.ascontiguousarray(posture, dtype=float)
    perr = rerr = float("inf")
    for _ in range(max_iter):
        perr, rerr, done = kernel.dls_step(k, q, goal, pull, lo, hi, damping, pos_tol, rot_tol)
        if done:
            return IkResult(q, True, perr, rerr)
        yield None
    return IkResult(q, perr < pos_tol and rerr < rot_tol, perr, rerr)
