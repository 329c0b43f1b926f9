"""The executor in a thread of the calling process: ``ControlLoop`` (velma.executor.loop)
paced by a thread, for tests, scripts and benchmarks. ag_ex runs the same loop in a process
of its own (velma.executor.process), where no other Python thread competes for the
interpreter.

No Zenoh and no FIPA messaging here: ``services/agents/executor`` wraps the executors.

Observe: the loop hands off a ``WorldCapture``; ``ResultDelivery``
(velma/executor/delivery.py), a worker thread of this process, renders and localises it and
delivers every result in the loop's order. In this in-process host that thread shares the
interpreter with the loop thread, so an Observe (≈ 0.2 s of rendering and fitting, much of it
in C with the GIL released, not all) can stretch some loop cycles; ag_ex's
``ExecutorProcess`` does not have that problem.

Timing: physics dt = 1 ms, control at 1 kHz (one control update per physics step).
``realtime=True`` releases cycle k at t₀ + k·1 ms of wall time; ``realtime=False`` runs as fast
as it can. ``DeadlineMonitor`` (velma.executor.timing) counts compute time, lateness and
overruns either way.

Idle steps: while no command runs the loop steps on (the robot holds its pose as time
passes), so how much robot time passes between two commands of a caller that submits one
after the other's result depends on the caller's thread timing, and so does what the
kitchen's contact-rich physics does next. ``idle_steps=False`` (as fast as possible only) waits
instead: the next command starts in the cycle after the last one ended, and a run of
commands ends in the same state whatever the machine's load (the scripted kitchen tasks).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable

import msgspec

from shared.fipa_codec.languages.l_ex import CommandResult, ExecutorCommand, command_name
from shared.fipa_codec.languages.l_sd import Observation
from shared.settings import Settings
from velma.control.compiled import law_name
from velma.executor.camera import InThreadCamera
from velma.executor.capture import WorldCapture, perception_mode
from velma.executor.delivery import RecordSink, ResultDelivery
from velma.executor.gather import robot_snapshot
from velma.executor.loop import ControlLoop
from velma.executor.runtime import DT, Runtime
from velma.executor.state import RobotSnapshot
from velma.executor.timing import DeadlineMonitor, Pacer, TimingStats

log = logging.getLogger(__name__)

OnDone = Callable[[CommandResult | Observation], None]


class Executor:
    """Runs L_EX commands on the simulated Velma in the kitchen (kitchen.xml), in a thread.

    ``seed`` selects the jitter of the jar content's start positions, ``pose_seed`` a
    randomisation of the jar and bowl poses (±2 cm, ±10°; see velma/model/scene.py).
    ``submit``, ``cancel`` and ``hold`` are thread-safe; ``on_done`` is called from the loop thread
    exactly once per command (exceptions it raises are logged and swallowed).
    Commands still queued at ``stop`` are answered with ``ok=False, reason="stopped"``.
    ``idle_steps=False``: no physics step while no command runs (module docstring); raises
    ``ValueError`` with ``realtime``.

    ``perception``: ``camera`` or ``truth`` (None: ``ROCO_PERCEPTION``, else the default of
    velma/executor/capture.py ``perception_mode``); ``perception_log`` receives each camera
    Observation's records beside the truth (velma/executor/perception_log.py). ``on_done`` runs
    on the delivery thread (module docstring), in the order the commands ended.
    """

    def __init__(
        self,
        *,
        realtime: bool = False,
        seed: int = 0,
        pose_seed: int | None = None,
        runtime: Runtime | None = None,
        perception: str | None = None,
        perception_log: RecordSink | None = None,
        idle_steps: bool = True,
    ) -> None:
        if realtime and not idle_steps:
            raise ValueError("idle_steps=False is for an executor as fast as possible, not real time")
        self.realtime = realtime
        self.idle_steps = idle_steps
        self.rt = runtime if runtime is not None else Runtime(seed=seed, pose_seed=pose_seed)
        self.perception = perception_mode(
            {Settings.env_name("perception"): perception} if perception is not None else None
        )
        self.rt.observe_by_camera = self.perception == "camera"
        self.perception_log = perception_log
        self.delivery: ResultDelivery[OnDone] | None = None
        self.loop: ControlLoop[OnDone] = ControlLoop(self.rt)
        self.monitor = DeadlineMonitor(DT, realtime=realtime)
        self.monitor.control_law = law_name(self.rt.ctrl)
        self.monitor.plant = self.rt.plant_name
        self._lock = threading.Lock()
        self._work = threading.Condition(self._lock)
        """Notified when the loop may have work (a command, a hold, a cancel) or must stop."""
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    # ------------------------------------------------------------------ API
    def start(self) -> None:
        """Start the control loop thread (idempotent)."""
        if self._thread is not None and self._thread.is_alive():
            return
        if self.delivery is None:
            model = self.rt.model
            camera = (
                InThreadCamera(lambda: model, None, self.rt.pose_seed or 0, self.perception_log is not None)
                if self.rt.observe_by_camera
                else None
            )
            self.delivery = ResultDelivery(self._notify, camera, record=self.perception_log)
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name="velma-loop", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Stop the loop and join its thread; answer queued commands with ``stopped`` (after
        the results already ended, in order); end the delivery thread."""
        with self._lock:
            self._stop.set()
            self._work.notify_all()
        if self._thread is not None:
            self._thread.join()
            self._thread = None
        with self._lock:
            ended = self.loop.abort("stopped")
        for on_done, result in ended:
            self._put(on_done, result)
        if self.delivery is not None:
            self.delivery.close()
            self.delivery = None

    def submit(self, command: ExecutorCommand, on_done: OnDone) -> OnDone:
        """Queue ``command``; ``on_done(result)`` is called once when it ends (FIFO order).
        Returns the command's token for ``cancel`` (``on_done`` itself: give each command a
        callable of its own to cancel it)."""
        with self._lock:
            self.loop.submit(on_done, command)
            self._work.notify_all()
        return on_done

    def cancel(self, token: OnDone) -> bool:
        """Halt the command ``token`` (velma.executor.loop ``ControlLoop.cancel``): its
        ``on_done`` gets a result that says ``halted``, or its own when it had ended. False
        when the loop no longer has it. The halt begins under the loop's lock, between two
        cycles; it is logged with the wall time."""
        with self._lock:
            ended = self.loop.cancel(token)
            running = self.loop.current
            self._work.notify_all()
            at = (time.time(), self.rt.time)
        if ended is None:
            return False
        if not ended and running is not None:
            log.info(
                "halt: %s halted by a cancel at wall time %.6f, sim time %.3f s",
                command_name(running[1]),
                *at,
            )
        for on_done, result in ended:
            self._put(on_done, result)
        return True

    def hold(self, why: str) -> None:
        """Hold position in joint impedance, ending every command with ``held: why``
        (velma.executor.loop)."""
        with self._lock:
            ended = self.loop.hold(why)
            self._work.notify_all()
        for on_done, result in ended:
            self._put(on_done, result)

    def displace(self, body: str, delta: tuple[float, float, float], tilt: float = 0.0) -> bool:
        """Move free body ``body`` by ``delta`` (world, m) and tilt it by ``tilt`` (rad, about
        world x): a disturbance of the simulated world. Raises KeyError/ValueError as
        Runtime.displace."""
        with self._lock:
            self.rt.displace(body, delta, tilt)
        return True

    def safe(self, why: str) -> None:
        """Enter safe mode, ending every command with ``safe mode: why`` (velma.executor.loop)."""
        with self._lock:
            ended = self.loop.safe(why)
            self._work.notify_all()
        for on_done, result in ended:
            self._put(on_done, result)

    def snapshot(self) -> RobotSnapshot:
        """A consistent copy of the robot's state, with the loop's timing (thread-safe)."""
        with self._lock:
            snap = robot_snapshot(self.rt, self.loop.holding)
        return msgspec.structs.replace(snap, timing=self.monitor.stats(snap.sim_time))

    def timing(self) -> TimingStats:
        """The deadline monitor's statistics (velma.executor.timing.TimingStats)."""
        return self.monitor.stats(self.rt.time)

    # ------------------------------------------------------------------ loop
    def _run(self) -> None:
        pacer = Pacer(DT, realtime=self.realtime)
        while not self._stop.is_set():
            if not self.idle_steps and not self._await_work():
                break
            start = pacer.begin()
            with self._lock:
                done = self.loop.cycle()
            self.monitor.record(pacer.release, start, time.perf_counter(), self.rt.part_s)
            if done is not None:
                self._put(*done)
            while self.loop.errors:
                name, text = self.loop.errors.popleft()
                log.error("command %s raised %s", name, text)
            pacer.wait()

    def _await_work(self) -> bool:
        """Wait until a command runs or is queued or a hold's halt runs (True), or ``stop`` was
        called (False)."""
        loop = self.loop
        with self._lock:
            while loop.current is None and not loop.queue and loop.stopping is None:
                if self._stop.is_set():
                    return False
                self._work.wait()
        return True

    def _put(self, on_done: OnDone, result: CommandResult | Observation | WorldCapture) -> None:
        """Hand ``result`` to the delivery thread (or deliver it here when there is none)."""
        if self.delivery is not None:
            self.delivery.put(on_done, result)
        elif not isinstance(result, WorldCapture):
            self._notify(on_done, result)
        else:
            self._notify(
                on_done, CommandResult(command="observe", ok=False, reason="stopped", sim_time=result.stamp)
            )

    @staticmethod
    def _notify(on_done: OnDone, result: CommandResult | Observation) -> None:
        try:
            on_done(result)
        except Exception:
            log.exception("on_done callback raised")
