"""ag_ex's side of the watch: a_ta's fipa-subscribe on C5 with an L_EX ``Watch`` (FIPA
SC00035), served by the executor's watch (velma/executor/watch.py, ``ExecutorProcess.watch``).

At most one watch: a new subscription replaces the one before (that one is told ``failure``,
which ends it). Agreed, the executor makes a camera frame every ``period_s`` of robot time,
each informed to the subscriber as an L_SD ``Observation`` (naming the robot's power-on, as
command results do); ``cancel`` ends it (the role answers the cancel), as does the subscriber's
liveliness token disappearing (:meth:`WatchService.drop`). An executor that cannot watch (no
head camera: ``ROCO_PERCEPTION=truth``) refuses, with its reason. After a power cycle of the
robot the new loop is asked to watch again (:meth:`WatchService.rearm`).
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import msgspec

from services.runtime.roles import Conversation
from shared.fipa_codec import Performative
from shared.fipa_codec.languages.l_ex import Watch
from shared.fipa_codec.languages.l_sd import Observation


@dataclass(frozen=True)
class Frame:
    """A watch frame the executor observed for the subscription ``conversation_id``."""

    conversation_id: str
    observation: Observation


class WatchService:
    """The one watch ag_ex serves (module docstring). ``post`` puts a :class:`Frame` on the
    agent's receptor buffer (frames come on the executor's delivery thread)."""

    def __init__(self, post: Callable[[Frame], None], log: logging.Logger) -> None:
        self.post = post
        self.log = log
        self.conversation: Conversation | None = None
        self.frames = 0

    def subscribe(self, conv: Conversation, watch: Watch, executor: Any) -> None:
        """Serve ``watch`` of ``conv`` on ``executor``: agree and start it, or refuse saying why."""
        try:
            self._start(executor, conv.conversation_id, watch)
        except (AttributeError, RuntimeError, ValueError) as exc:
            conv.refuse_with(Performative.REFUSE, f"cannot watch: {exc}")
            return
        before, self.conversation = self.conversation, conv
        if before is not None and before is not conv and not before.finished:
            before.refuse_with(Performative.FAILURE, "replaced by a later watch")
        conv.reply(Performative.AGREE)
        self.log.info(
            "%s asked the robot to watch %s every %.2f s of robot time (%s)",
            conv.peer,
            ", ".join(watch.objects) or "the scene",
            watch.period_s,
            conv.conversation_id,
        )

    def _start(self, executor: Any, conversation_id: str, watch: Watch) -> None:
        post = self.post

        def on_frame(obs: Observation, cid: str = conversation_id) -> None:  # delivery thread
            post(Frame(cid, obs))

        executor.watch(tuple(watch.objects), watch.period_s, on_frame)

    def cancelled(self, conv: Conversation, executor: Any) -> None:
        """``conv`` was cancelled: end the watch when it is the one served."""
        if conv is self.conversation:
            self.stop(executor, "cancelled")

    def drop(self, peer: str, executor: Any) -> None:
        """``peer`` disappeared: end its watch (nobody is told)."""
        if self.conversation is not None and self.conversation.peer == peer:
            self.stop(executor, f"{peer} lost")

    def stop(self, executor: Any, why: str) -> None:
        """End the watch served (nothing when none), because ``why``."""
        conv, self.conversation = self.conversation, None
        if conv is None:
            return
        unwatch = getattr(executor, "unwatch", None)
        if unwatch is not None:
            unwatch()
        self.log.info("the watch %s ended (%s) after %d frames", conv.conversation_id, why, self.frames)

    def inform(self, frame: Frame, world: str) -> None:
        """Inform the subscriber of ``frame`` (``world``: the power-on it was seen in)."""
        conv = self.conversation
        if conv is None or conv.conversation_id != frame.conversation_id or conv.finished:
            return  # a frame of a watch that has ended
        obs = frame.observation
        conv.reply(Performative.INFORM, msgspec.structs.replace(obs, world=world) if world else obs)
        self.frames += 1

    def rearm(self, executor: Any) -> None:
        """Ask a new executor (the robot power-cycled) for the watch served; one that cannot
        watch ends it with ``failure``."""
        conv = self.conversation
        watch = conv.opening.content if conv is not None and conv.opening is not None else None
        if conv is None or not isinstance(watch, Watch):
            return
        try:
            self._start(executor, conv.conversation_id, watch)
        except (AttributeError, RuntimeError, ValueError) as exc:
            self.conversation = None
            conv.refuse_with(Performative.FAILURE, f"cannot watch any more: {exc}")
