"""The executor core (ag_ex's hard-timing part, paper §5.3): a fixed-rate control loop in its
own thread that runs L_EX commands one after another (FIFO) and reports each result once.

No Zenoh and no FIPA messaging here: ``services/executor`` wraps this class.

Timing: physics dt = 1 ms, control at 1 kHz (one control update per physics step).
``realtime=True`` paces the loop to wall time (cycle k ends no earlier than k ms after start;
a cycle whose work ends after its deadline counts as a deadline miss); ``realtime=False``
runs as fast as it can (a cycle whose work exceeds 1 ms counts as a miss).
"""

from __future__ import annotations

import collections
import logging
import threading
import time
from collections.abc import Callable

import msgspec
import numpy as np

from shared.fipa_codec.languages.common import Pose
from shared.fipa_codec.languages.l_ex import CommandResult, ExecutorCommand
from shared.fipa_codec.languages.l_sd import Observation
from velma.control.robot_model import SIDES
from velma.control.trajectory import quat_wxyz
from velma.executor.primitives import Primitive, Result, command_name, make_primitive
from velma.executor.runtime import DT, Runtime

log = logging.getLogger(__name__)

OnDone = Callable[[CommandResult | Observation], None]
TIMING_WINDOW = 200_000  # cycles kept for the percentile statistics


class RobotSnapshot(msgspec.Struct, frozen=True, kw_only=True):
    """The robot's state at ``sim_time`` (s): ``joints`` (rad, by joint name), the world
    pose of each grip frame (``grip`` keyed ``right``/``left``), whether each hand holds an
    object (``held``) and which (``held_object``, body name or None)."""

    sim_time: float
    joints: dict[str, float]
    grip: dict[str, Pose]
    held: dict[str, bool]
    held_object: dict[str, str | None]


class Executor:
    """Runs L_EX commands on the simulated Velma in the kitchen (kitchen.xml).

    ``seed`` selects the jitter of the jar content's start positions (see
    velma/model/scene.py). ``submit`` is thread-safe; ``on_done`` is called from the loop
    thread exactly once per command (exceptions it raises are logged and swallowed).
    Commands still queued at ``stop`` are answered with ``ok=False, reason="stopped"``.
    """

    def __init__(self, *, realtime: bool = False, seed: int = 0) -> None:
        self.realtime = realtime
        self.rt = Runtime(seed=seed)
        self._lock = threading.Lock()
        self._queue: collections.deque[tuple[ExecutorCommand, OnDone]] = collections.deque()
        self._current: tuple[ExecutorCommand, OnDone, Primitive] | None = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._work = np.zeros(TIMING_WINDOW)
        self._cycles = 0
        self._misses = 0

    # ------------------------------------------------------------------ API
    def start(self) -> None:
        """Start the control loop thread (idempotent)."""
        if self._thread is not None and self._thread.is_alive():
            return
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name="velma-loop", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Stop the loop and join its thread; answer queued commands with ``stopped``."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
            self._thread = None
        with self._lock:
            pending = list(self._queue)
            self._queue.clear()
            if self._current is not None:
                pending.insert(0, self._current[:2])
                self._current = None
        for command, on_done in pending:
            self._notify(
                on_done,
                CommandResult(
                    command=command_name(command), ok=False, reason="stopped", sim_time=self.rt.time
                ),
            )

    def submit(self, command: ExecutorCommand, on_done: OnDone) -> None:
        """Queue ``command``; ``on_done(result)`` is called once when it ends (FIFO order)."""
        with self._lock:
            self._queue.append((command, on_done))

    def snapshot(self) -> RobotSnapshot:
        """A consistent copy of the robot's state (thread-safe)."""
        with self._lock:
            rt = self.rt
            q = rt.q()
            joints = {name: float(q[rt.robot.v_index(name)]) for name in rt.robot.joint_names}
            grip = {}
            for side in SIDES:
                site = rt.model.site(f"{side}_HandGripLink").id
                p = rt.data.site_xpos[site]
                rot = rt.data.site_xmat[site].reshape(3, 3)
                grip[side] = Pose(
                    position=(float(p[0]), float(p[1]), float(p[2])), orientation=quat_wxyz(rot)
                )
            held_obj = {s: (rt.model.body(b).name if (b := rt.held[s]) is not None else None) for s in SIDES}
            return RobotSnapshot(
                sim_time=rt.time,
                joints=joints,
                grip=grip,
                held={s: held_obj[s] is not None for s in SIDES},
                held_object=held_obj,
            )

    def timing(self) -> dict[str, float]:
        """Loop statistics: ``cycles``, ``mean_us``/``p99_us``/``max_us`` of the cycle work
        time (primitive + control + physics step, µs), ``deadline_misses``, ``sim_time``."""
        with self._lock:
            n = min(self._cycles, TIMING_WINDOW)
            work = self._work[:n] * 1e6
            return {
                "cycles": float(self._cycles),
                "mean_us": float(work.mean()) if n else 0.0,
                "p99_us": float(np.percentile(work, 99)) if n else 0.0,
                "max_us": float(work.max()) if n else 0.0,
                "deadline_misses": float(self._misses),
                "sim_time": self.rt.time,
            }

    # ------------------------------------------------------------------ loop
    def _run(self) -> None:
        next_deadline = time.perf_counter() + DT
        while not self._stop.is_set():
            t0 = time.perf_counter()
            with self._lock:
                done = self._cycle()
                work = time.perf_counter() - t0
                self._work[self._cycles % TIMING_WINDOW] = work
                self._cycles += 1
                if self.realtime:
                    if time.perf_counter() > next_deadline:
                        self._misses += 1
                elif work > DT:
                    self._misses += 1
            if done is not None:
                self._notify(*done)
            if self.realtime:
                now = time.perf_counter()
                if next_deadline > now:
                    time.sleep(next_deadline - now)
                    next_deadline += DT
                else:  # late: do not try to catch up in a burst
                    next_deadline = now + DT

    def _cycle(self) -> tuple[OnDone, Result] | None:
        """One cycle under the lock: advance the command, control, step. Returns the
        (callback, result) of a command that ended in this cycle."""
        rt = self.rt
        finished: tuple[OnDone, Result] | None = None
        if self._current is None and self._queue:
            command, on_done = self._queue.popleft()
            prim: Primitive | None = None
            try:
                prim = make_primitive(command)
                result = prim.start(rt)
            except Exception as exc:  # a bad command must not kill the loop
                log.exception("command %s failed to start", command_name(command))
                result = CommandResult(
                    command=command_name(command), ok=False, reason=f"error: {exc}", sim_time=rt.time
                )
            if result is not None or prim is None:
                finished = (on_done, result) if result is not None else None
            else:
                self._current = (command, on_done, prim)
        elif self._current is not None:
            command, on_done, running = self._current
            try:
                result = running.step(rt)
            except Exception as exc:
                log.exception("command %s failed", command_name(command))
                result = CommandResult(
                    command=command_name(command), ok=False, reason=f"error: {exc}", sim_time=rt.time
                )
            if result is not None:
                finished = (on_done, result)
                self._current = None
        rt.cycle()
        return finished

    @staticmethod
    def _notify(on_done: OnDone, result: Result) -> None:
        try:
            on_done(result)
        except Exception:
            log.exception("on_done callback raised")
