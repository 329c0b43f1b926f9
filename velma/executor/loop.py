"""One cycle of ag_ex's control loop, independent of how the loop is paced or hosted (paper
§5.3): take the next L_EX command when none runs, advance the running motion primitive,
compute the control law and step the physics (``Runtime.cycle``).

``ControlLoop`` owns no thread, lock or clock: ``velma.executor.core.Executor`` runs it in a
thread of the calling process (tests, scripts), ``velma.executor.process`` in a process of its
own (ag_ex). Commands carry an opaque ``token`` that comes back with their result, so each
host can map results to its callers.

Holding (``hold``; ag_ex lost its commander): the running and queued commands end at once
with ``failure`` (reason ``held: <why>``), but the motion that ran is not stopped dead: it is
brought to rest as a cancel brings it (``HaltPrimitive``: setpoints braked along their path, a
tilted jar turned upright, or a pour past its pour point finished first), and only then do the
arms switch to joint impedance at their measured configuration and the torso to its measured
angle; the hands keep their setpoints, so a grasped object stays grasped. Commands that arrive
meanwhile wait for the rest. (Stopped dead half-way through a pour's tilt, at the lean where the
content runs out, the jar poured it short of the bowl and off the table.) ``safe`` switches at
once, with Velma's safe-mode gains. The loop holds until the next command arrives.

Cancelling (``cancel``; a_ta's FIPA cancel of the request, SC00026 §2, paper §3.2 safe
interruption): a command queued behind another is dropped and ends at once with ``halted``
(L_EX ``HALTED``); the running one — or the next one when none runs — is replaced, in the
cycle the cancel arrives, by a ``HaltPrimitive`` (velma/executor/halt.py), which brings
the commanded motion to rest (mid-pour it turns the jar upright; past the point where the
content leaves the jar, after the tilt's end) and ends the command with ``halted``. A cancel
adds no work to the cycle: the host hands it over with the other commands, and the halt is
just the running primitive from then on.
"""

from __future__ import annotations

import collections
import time
from typing import Generic, TypeVar

import msgspec
import numpy as np

from shared.fipa_codec.languages.l_ex import HALTED, CommandResult, ExecutorCommand, command_name
from velma.control.joints import SIDES
from velma.executor.halt import HaltPrimitive
from velma.executor.primitives import Primitive, Result, make_primitive
from velma.executor.runtime import Runtime

T = TypeVar("T")


class ControlLoop(Generic[T]):
    """FIFO of (token, command) run one at a time on ``rt`` (see module docstring).

    ``errors`` collects (command name, exception text) of primitives that raised; they are
    answered with ``failure`` (reason ``error: …``) and the loop goes on. The host drains
    ``errors`` off the loop's path (no logging in the loop)."""

    def __init__(self, rt: Runtime) -> None:
        self.rt = rt
        self.queue: collections.deque[tuple[T, ExecutorCommand]] = collections.deque()
        self.current: tuple[T, ExecutorCommand, Primitive] | None = None
        self.holding: str | None = None
        self.errors: collections.deque[tuple[str, str]] = collections.deque(maxlen=64)
        self.stopping: HaltPrimitive | None = None
        """A hold's halt: the motion that ran when ``hold`` came, being brought to rest before
        the arms switch to joint impedance; None when none runs. Its result goes to nobody
        (its command was answered by ``hold``)."""
        self._self_contacts_at_start: dict[tuple[str, str], int] = {}
        self.started: collections.deque[tuple[T, str, float]] = collections.deque(maxlen=64)
        """(token, command name, sim time s) of each command the loop started, oldest first;
        the host drains it after the cycle (ag_ex's ledger, velma/executor/ledger.py); a host
        that does not keeps the latest 64."""

    def submit(self, token: T, command: ExecutorCommand) -> None:
        """Queue ``command``; its result comes back from ``cycle`` with ``token``."""
        self.queue.append((token, command))

    def cancel(self, token: T) -> list[tuple[T, CommandResult]] | None:
        """Halt the command submitted with ``token`` (module docstring). Returns
        ``[(token, result)]`` when it was queued behind another or behind a hold's halt
        (``stopping``; dropped; ``result`` says ``halted``), ``[]`` when it runs, or was the
        next to run with none running (a ``HaltPrimitive`` runs in its place: the robot is
        halted as it stands, a tilted jar turned upright; its ``halted`` result comes from
        ``cycle`` once the robot is at rest; a second cancel changes nothing), None when the
        loop no longer has it (it has ended). When the halt cannot start (it raised) the loop
        holds position at once instead and the commands that ended are returned."""
        for i, (queued, command) in enumerate(self.queue):
            if queued != token:
                continue
            del self.queue[i]
            if i == 0 and self.current is None and self.stopping is None:
                return self._halt(token, command, None)
            name = command_name(command)
            return [(queued, CommandResult(command=name, ok=False, reason=HALTED, sim_time=self.rt.time))]
        if self.current is None or self.current[0] != token:
            return None
        _, command, running = self.current
        if isinstance(running, HaltPrimitive):
            return []
        return self._halt(token, command, running)

    def _halt(
        self, token: T, command: ExecutorCommand, running: Primitive | None
    ) -> list[tuple[T, CommandResult]]:
        """Make a ``HaltPrimitive`` of ``command`` (``running``: its primitive, None: it never
        started) the running command."""
        halt = HaltPrimitive(command, running)
        self.current = (token, command, halt)
        try:
            halt.start(self.rt)
        except Exception as exc:  # a halt that cannot start must not kill the loop: hold instead
            self.errors.append((command_name(command), f"halt: {type(exc).__name__}: {exc}"))
            why = f"the halt failed: {exc}"
            return self._stop_motion(f"held: {why}", why, safe=False)
        return []

    def pending(self) -> list[tuple[T, ExecutorCommand]]:
        """The running and queued commands, oldest first; removes them (no results)."""
        out = [(c[0], c[1]) for c in ([self.current] if self.current else [])] + list(self.queue)
        self.current = None
        self.queue.clear()
        return out

    def abort(self, reason: str) -> list[tuple[T, CommandResult]]:
        """End the running and queued commands with ``failure`` (``reason``)."""
        t = self.rt.time
        return [
            (token, CommandResult(command=command_name(cmd), ok=False, reason=reason, sim_time=t))
            for token, cmd in self.pending()
        ]

    def hold(self, why: str) -> list[tuple[T, CommandResult]]:
        """Hold position in joint impedance once the running motion is at rest (see module
        docstring); returns the failures of the commands it ended, at once. A hold while a
        hold's halt runs keeps that halt; a halt that cannot start holds at once."""
        running = self.current
        ended = self.abort(f"held: {why}")
        self.holding = why
        if self.stopping is None and running is not None:
            self.stopping = self._brake(running[1], running[2])
        if self.stopping is None:
            self._joint_hold(safe=False)
        return ended

    def _brake(self, command: ExecutorCommand, running: Primitive) -> HaltPrimitive | None:
        """The halt that brings ``running`` (``command``'s primitive) to rest: a cancel's halt
        already under way, else a new one, started; None when it cannot start."""
        if isinstance(running, HaltPrimitive):
            return running
        halt = HaltPrimitive(command, running)
        try:
            halt.start(self.rt)
        except Exception as exc:  # a halt that cannot start must not kill the loop
            self.errors.append((command_name(command), f"halt: {type(exc).__name__}: {exc}"))
            return None
        return halt

    def _step_stopping(self, halt: HaltPrimitive) -> None:
        """Advance a hold's halt; at rest (or should it raise) the arms switch to the hold."""
        try:
            at_rest = halt.step(self.rt) is not None
        except Exception as exc:
            self.errors.append(("halt", f"{type(exc).__name__}: {exc}"))
            at_rest = True
        if at_rest:
            self.stopping = None
            self._joint_hold(safe=False)

    def safe(self, why: str) -> list[tuple[T, CommandResult]]:
        """Safe mode: like ``hold`` but with the arms in Velma's safe joint impedance (K = 5
        N·m/rad, ξ = 1.9, gravity compensated: they can be pushed by hand); commands end with
        ``safe mode: why``."""
        return self._stop_motion(f"safe mode: {why}", f"safe mode: {why}", safe=True)

    def _stop_motion(self, reason: str, holding: str, *, safe: bool) -> list[tuple[T, CommandResult]]:
        """End every command with ``reason`` and hold where the robot is, at once (no halt)."""
        ended = self.abort(reason)
        self.stopping = None
        self._joint_hold(safe=safe)
        self.holding = holding
        return ended

    def _joint_hold(self, *, safe: bool) -> None:
        """Both arms in joint impedance (``safe``: Velma's safe gains) at their measured
        configuration, at rest; the torso at its measured angle."""
        rt = self.rt
        q = rt.q()
        for side in SIDES:
            q_arm = q[rt.ctrl.arm_slice[side]].copy()
            if safe:
                rt.ctrl.safe(side, q_arm)
            else:
                rt.ctrl.hold(side, q_arm)
            rt.ctrl.arm[side].twist = np.zeros(6)
        rt.ctrl.torso_q = float(q[rt.ctrl.torso_idx])
        rt.ctrl.torso_qd = 0.0

    def cycle(self) -> tuple[T, Result] | None:
        """One 1 ms cycle: start or advance the command, control, physics step. Returns the
        (token, result) of a command that ended in this cycle."""
        rt = self.rt
        finished: tuple[T, Result] | None = None
        t0 = time.perf_counter()
        if self.stopping is not None:  # a hold's halt: commands wait until the robot is at rest
            self._step_stopping(self.stopping)
        elif self.current is None and self.queue:
            token, command = self.queue.popleft()
            self.holding = None
            self._self_contacts_at_start = dict(rt.self_contact_pairs)
            self.started.append((token, command_name(command), rt.time))
            try:
                prim = make_primitive(command)
                result = prim.start(rt)
            except Exception as exc:  # a bad command must not kill the loop
                result = self._error(command, exc)
                prim = None
            if result is not None:
                finished = (token, self._with_self_contacts(result))
            elif prim is not None:
                self.current = (token, command, prim)
        elif self.current is not None:
            token, command, running = self.current
            try:
                result = running.step(rt)
            except Exception as exc:
                result = self._error(command, exc)
            if result is not None:
                finished = (token, self._with_self_contacts(result))
                self.current = None
        rt.part_s[0] = time.perf_counter() - t0
        rt.cycle()
        return finished

    def _with_self_contacts(self, result: Result) -> Result:
        """``result`` naming the robot's own geometry pairs that touched since the command
        started (``Runtime.self_contact_pairs`` grew); unchanged when none did."""
        pairs = self.rt.self_contact_pairs
        if not isinstance(result, CommandResult) or pairs == self._self_contacts_at_start:
            return result
        before = self._self_contacts_at_start
        touched = tuple(sorted(f"{a} + {b}" for (a, b), n in pairs.items() if n > before.get((a, b), 0)))
        return msgspec.structs.replace(result, self_contacts=touched)

    def _error(self, command: ExecutorCommand, exc: Exception) -> CommandResult:
        name = command_name(command)
        self.errors.append((name, f"{type(exc).__name__}: {exc}"))
        return CommandResult(command=name, ok=False, reason=f"error: {exc}", sim_time=self.rt.time)
