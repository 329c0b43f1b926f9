"""A kinematic test double of ``velma.executor.Executor`` for testing agent logic without
physics: commands succeed at once; objects follow the hand that holds them; a tilt empties
the held container into the nearest other container. ``HaltingExecutor`` keeps chosen
commands running until they are cancelled (halted). Used only by tests of the agents."""

from __future__ import annotations

import math
import queue
import threading
from collections.abc import Callable

from shared.fipa_codec.languages.common import Pose
from shared.fipa_codec.languages.l_ex import (
    HALTED,
    CommandResult,
    ExecutorCommand,
    Grasp,
    MoveTool,
    Observe,
    Release,
    Tilt,
    command_name,
)
from shared.fipa_codec.languages.l_sd import ObjectObservation, Observation

PARTICLES = 20


class FakeExecutor:
    def __init__(self, fail: set[str] | None = None) -> None:
        self.poses = {
            "jar": Pose((0.85, 0.25, 0.9)),
            "bowl": Pose((0.85, -0.25, 0.9)),
            "cup": Pose((0.85, 0.0, 0.9)),
            "table": Pose((0.8, -0.5, 0.0)),
            "cabinet": Pose((1.0, 0.0, 0.0)),
        }
        self.inside = {"jar": PARTICLES, "bowl": 0, "cup": 0}
        self.tool: dict[str, Pose | None] = {"left": None, "right": None}
        self.held: dict[str, str | None] = {"left": None, "right": None}
        self.fail = fail or set()
        self.commands: list[ExecutorCommand] = []
        self.t = 0.0

    def start(self) -> None: ...
    def stop(self) -> None: ...

    def _near(self, arm: str) -> str | None:
        tool = self.tool[arm]
        if tool is None:
            return None
        best = min(("jar", "bowl", "cup"), key=lambda o: math.dist(self.poses[o].position, tool.position))
        return best if math.dist(self.poses[best].position, tool.position) < 0.3 else None

    def submit(
        self, command: ExecutorCommand, on_done: Callable[[CommandResult | Observation], None]
    ) -> object:
        """Run ``command`` at once (``on_done`` called before this returns); returns its token."""
        self.commands.append(command)
        self._answer(command, on_done)
        return object()

    def _answer(
        self, command: ExecutorCommand, on_done: Callable[[CommandResult | Observation], None]
    ) -> None:
        self.t += 1.0
        tag = type(command).__name__
        if tag in self.fail:
            on_done(CommandResult(command=tag, ok=False, reason="injected failure", sim_time=self.t))
            return
        if isinstance(command, Observe):
            names = command.objects or tuple(self.poses)
            objs = tuple(
                ObjectObservation(name=n, pose=self.poses[n], particles_inside=self.inside.get(n))
                for n in names
            )
            on_done(Observation(stamp=self.t, objects=objs, total_particles=PARTICLES))
            return
        if isinstance(command, MoveTool):
            before = self.tool[command.arm.value]
            self.tool[command.arm.value] = command.target
            held = self.held[command.arm.value]
            if held is not None and before is not None:
                d = [a - b for a, b in zip(command.target.position, before.position, strict=True)]
                p = self.poses[held].position
                self.poses[held] = Pose((p[0] + d[0], p[1] + d[1], p[2] + d[2]))
        elif isinstance(command, Grasp):
            self.held[command.arm.value] = self._near(command.arm.value)
            if self.held[command.arm.value] is None:
                on_done(CommandResult(command=tag, ok=False, reason="no contact", sim_time=self.t))
                return
        elif isinstance(command, Release):
            self.held[command.arm.value] = None
        elif isinstance(command, Tilt) and command.angle > 0:
            src = self.held[command.arm.value]
            if src is not None:
                dst = "bowl" if src == "jar" else "jar"
                self.inside[dst] += self.inside[src]
                self.inside[src] = 0
        on_done(CommandResult(command=tag, ok=True, sim_time=self.t))


OnDone = Callable[[CommandResult | Observation], None]


class HaltingExecutor(FakeExecutor):
    """``FakeExecutor`` whose first command of a type named in ``hold`` (e.g. ``Tilt``) keeps
    running — no result — until ``cancel`` halts it: its result then says ``halted``
    (L_EX ``HALTED``) and the world is as before it. ``running`` receives each command held so,
    when it starts (a test sends its stop then); ``cancelled`` lists the commands halted."""

    def __init__(
        self,
        hold: set[str],
        fail: set[str] | None = None,
        when: Callable[[ExecutorCommand], bool] = lambda _command: True,
    ) -> None:
        """``when``: which commands of those types are held (the first one it accepts)."""
        super().__init__(fail)
        self.hold = set(hold)
        self.when = when
        self.running: queue.SimpleQueue[ExecutorCommand] = queue.SimpleQueue()
        self.cancelled: list[ExecutorCommand] = []
        self._held: dict[object, tuple[ExecutorCommand, OnDone]] = {}
        self._lock = threading.Lock()

    def submit(self, command: ExecutorCommand, on_done: OnDone) -> object:
        token = object()
        tag = type(command).__name__
        if tag not in self.hold or not self.when(command):
            self.commands.append(command)
            self._answer(command, on_done)
            return token
        self.hold.discard(tag)  # the first one only
        self.commands.append(command)
        with self._lock:
            self._held[token] = (command, on_done)
        self.running.put(command)
        return token

    def cancel(self, token: object) -> bool:
        """Halt the held command ``token``: its ``on_done`` gets ``halted``; False when it is
        not held (it ran at once, or was halted already)."""
        with self._lock:
            held = self._held.pop(token, None)
        if held is None:
            return False
        command, on_done = held
        self.cancelled.append(command)
        self.t += 1.0
        on_done(CommandResult(command=command_name(command), ok=False, reason=HALTED, sim_time=self.t))
        return True
