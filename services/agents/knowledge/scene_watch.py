"""What a_km tells one subscriber of changes of the scene (L_WM ``SceneSubscription``,
``SceneChange``; FIPA SC00035 fipa-subscribe, a_km the participant).

A :class:`Watch` holds one agreed subscription: the objects and changes of interest, what the
subscriber was last told of each object (its *baseline*: at first what a_km knew when it
agreed), and the changes not yet sent. After each update a_km saved, :meth:`Watch.compare`
sets each changed object of interest against its baseline and queues a ``SceneChange`` for
what crossed the subscription's thresholds; the baseline of what was told moves on, the rest
stays, so that a slow drift is told once it adds up to the threshold. The queue is bounded by
the subscription's ``queue``: past it the oldest change goes, and the next one sent says how
many went before it (``SceneChange.dropped``). a_km sends at most :data:`BURST` queued changes
to each subscriber per step of its ``idle`` behaviour, so a flood of changes does not hold up
its queries.

:func:`problems` says why a subscription is out of range (a_km refuses it with that reason).
"""

from __future__ import annotations

import math
import re
from collections import deque
from collections.abc import Iterable
from dataclasses import dataclass

import msgspec

from services.agents.knowledge.watch_demand import WITHIN_RANGE_S
from shared.fipa_codec.languages.common import Pose, Vec3
from shared.fipa_codec.languages.l_wm import ObjectInfo, SceneChange, SceneSubscription

MAX_SUBSCRIBERS = 8
"""Scene subscriptions a_km serves at once (one per channel; the next one is refused)."""
MAX_QUEUE = 256
"""Largest ``SceneSubscription.queue`` a_km accepts (changes kept per subscriber)."""
MAX_OBJECTS = 64
"""Most objects one subscription may name."""
MOVED_RANGE = (0.001, 10.0)
"""Accepted ``SceneSubscription.moved`` (m): from a millimetre to well past the kitchen's size."""
TILTED_RANGE = (0.01, math.pi - 0.01)
"""Accepted ``SceneSubscription.tilted`` (rad, from upright)."""
BURST = 16
"""Queued changes a_km sends each subscriber per step of its ``idle`` behaviour."""

_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_\-]*$")


def _out_of(value: float | None, bounds: tuple[float, float]) -> bool:
    return value is not None and not (bounds[0] <= value <= bounds[1])


def problems(sub: SceneSubscription) -> list[str]:
    """Why a_km cannot serve ``sub`` (empty: it can): a bound out of its range above, a
    name that is not an individual's, or nothing of interest."""
    bad = [name for name in sub.objects if not _NAME.match(name)]
    checks = (
        (
            _out_of(sub.moved, MOVED_RANGE),
            f"moved must be {MOVED_RANGE[0]}..{MOVED_RANGE[1]} m, not {sub.moved}",
        ),
        (
            _out_of(sub.tilted, TILTED_RANGE),
            f"tilted must be {TILTED_RANGE[0]}..{TILTED_RANGE[1]:.2f} rad, not {sub.tilted}",
        ),
        (_out_of(sub.queue, (1, MAX_QUEUE)), f"queue must be 1..{MAX_QUEUE} changes, not {sub.queue}"),
        (
            sub.within_s is not None and not (WITHIN_RANGE_S[0] <= sub.within_s <= WITHIN_RANGE_S[1]),
            f"within_s must be {WITHIN_RANGE_S[0]}..{WITHIN_RANGE_S[1]} s of robot time, not {sub.within_s}",
        ),
        (len(sub.objects) > MAX_OBJECTS, f"at most {MAX_OBJECTS} objects, not {len(sub.objects)}"),
        (bool(bad), f"not an individual's name: {bad[0]!r}" if bad else ""),
        (
            sub.moved is None and sub.tilted is None and not sub.content and not sub.relation,
            "no change is of interest (moved, tilted, content and relation all off)",
        ),
    )
    return [why for failed, why in checks if failed]


@dataclass
class _Told:
    """What a subscriber was last told of one object (its baseline)."""

    position: Vec3 | None
    tilted: bool
    particles: int | None
    held_by: str
    place: tuple[str | None, str | None]


def _tilt(pose: Pose | None) -> float | None:
    if pose is None:
        return None
    try:
        return pose.tilt()
    except ValueError:  # a zero quaternion: no orientation known
        return None


class Watch:
    """One agreed scene subscription (module docstring): ``conversation_id`` names it,
    ``subscription`` is what it asked for."""

    def __init__(self, conversation_id: str, subscription: SceneSubscription) -> None:
        self.conversation_id = conversation_id
        self.subscription = subscription
        self.objects = frozenset(subscription.objects)
        self.told: dict[str, _Told] = {}
        self.queue: deque[SceneChange] = deque()
        self.dropped = 0
        """Changes dropped since the last one queued was sent (told in the next one sent)."""
        self.dropped_in_all = 0

    def of_interest(self, name: str) -> bool:
        """Whether the subscription is about object ``name``."""
        return not self.objects or name in self.objects

    def _told_now(self, info: ObjectInfo) -> _Told:
        tilt = _tilt(info.pose)
        threshold = self.subscription.tilted
        return _Told(
            position=info.pose.position if info.pose is not None else None,
            tilted=tilt is not None and threshold is not None and tilt > threshold,
            particles=info.particles,
            held_by=info.held_by or "",
            place=(info.location, info.relation),
        )

    def start(self, known: Iterable[ObjectInfo]) -> None:
        """Take what a_km knows now of the objects of interest as what was told."""
        for info in known:
            if self.of_interest(info.name):
                self.told[info.name] = self._told_now(info)

    def compare(self, now: Iterable[ObjectInfo], stamp: float, seen_at: float | None) -> int:
        """Queue a change for each object of interest in ``now`` (as a_km knows it after the
        update of robot time ``stamp`` s, received by a_ta at ``seen_at``) that differs from
        what was told past the subscription's thresholds; returns how many were queued. An
        object never told of before is taken as told (nothing queued for it)."""
        queued = 0
        for info in now:
            if not self.of_interest(info.name):
                continue
            told = self.told.get(info.name)
            if told is None:
                self.told[info.name] = self._told_now(info)
                continue
            change = self._change(info, told, stamp, seen_at)
            if change is not None:
                self._queue(change)
                queued += 1
        return queued

    def _change(
        self, info: ObjectInfo, told: _Told, stamp: float, seen_at: float | None
    ) -> SceneChange | None:
        now = self._told_now(info)
        distance = self._distance(now, told)
        changed = [
            *self._moved(now, told, distance),
            *self._tilted(info, now, told),
            *self._content(now, told),
            *self._relation(now, told),
        ]
        if not changed:
            return None
        return SceneChange(
            object=info.name,
            changed=tuple(changed),
            stamp=stamp,
            seen_at=seen_at,
            pose=info.pose,
            distance=distance if "moved" in changed else None,
            tilt=_tilt(info.pose),
            particles=info.particles,
            held_by=info.held_by or "",
            location=info.location,
            relation=info.relation,
        )

    # each aspect: what changed of it since ``told``, which then takes what is told of it now
    @staticmethod
    def _distance(now: _Told, told: _Told) -> float | None:
        if now.position is None or told.position is None:
            return None
        return math.dist(now.position, told.position)

    def _moved(self, now: _Told, told: _Told, distance: float | None) -> list[str]:
        if told.position is None:  # its first position: taken as told
            told.position = now.position
            return []
        if self.subscription.moved is None or distance is None or distance <= self.subscription.moved:
            return []
        told.position = now.position
        return ["moved"]

    def _tilted(self, info: ObjectInfo, now: _Told, told: _Told) -> list[str]:
        if self.subscription.tilted is None or now.tilted == told.tilted or _tilt(info.pose) is None:
            return []
        told.tilted = now.tilted
        return ["tilted" if now.tilted else "upright"]

    def _content(self, now: _Told, told: _Told) -> list[str]:
        if not self.subscription.content or now.particles is None or now.particles == told.particles:
            return []
        told.particles = now.particles
        return ["content"]

    def _relation(self, now: _Told, told: _Told) -> list[str]:
        if not self.subscription.relation:
            return []
        changed = []
        if now.held_by != told.held_by:
            changed.append("held" if now.held_by else "released")
        if now.place != told.place and now.place[0] is not None:
            changed.append("placed")
        told.held_by, told.place = now.held_by, now.place
        return changed

    def _queue(self, change: SceneChange) -> None:
        if len(self.queue) >= self.subscription.queue:
            self.queue.popleft()
            self.dropped += 1
            self.dropped_in_all += 1
        self.queue.append(change)

    def due(self) -> list[SceneChange]:
        """The next changes to send (at most :data:`BURST`, oldest first), the first saying how
        many were dropped before it."""
        out: list[SceneChange] = []
        while self.queue and len(out) < BURST:
            change = self.queue.popleft()
            if self.dropped and not out:
                change = msgspec.structs.replace(change, dropped=self.dropped)
                self.dropped = 0
            out.append(change)
        return out
