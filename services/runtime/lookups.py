"""Per-channel answers an agent looks up for every communicate, computed once.

The specification and an agent's interface are frozen while the agent runs, so what they say
about one peer, channel or kind of communicate is the same for every communicate: the channel
joining the agent to a peer, the peer's agent identifier, the key expression of a channel and
receiver, the parts of a key a communicate arrived on, the interface's sent or received kind of
a (peer, performative, protocol). :class:`Lookups` asks the specification the first time and
keeps the answer; each table holds at most :data:`MAX_ENTRIES` answers (a peer that sends on
ever new keys makes the agent look those up every time, as before, and grows nothing).

Only answers are kept, never a decision about one communicate: every check the runtime makes
(services/runtime/engine.py) still runs on each communicate, on these answers. Among them are
the checks of a received communicate that depend only on its sender, channel, performative,
protocol, language, ontology and encoding (services/runtime/intake.py ``screen``): kept per
such tuple, their answer is the same for every communicate of it; its content is decoded and
checked each time.
"""

from __future__ import annotations

from collections.abc import Callable, Hashable
from typing import TypeVar

from services.runtime import keys
from services.runtime.intake import Screen, screen
from services.spec.model import ChannelSpec, Interface, MessageKind, SpecError, SystemSpec, channel_between
from services.spec.protocol_defs import machine_of
from shared.fipa_codec import AgentIdentifier, Performative
from shared.fipa_codec.protocols import INITIATOR, PARTICIPANT, Protocol, Role

MAX_ENTRIES = 1024
"""Answers kept per table (an agent has a few peers, channels and kinds of communicate)."""

K = TypeVar("K", bound=Hashable)
V = TypeVar("V")

_MISSING = object()

Followed = tuple[Protocol, Role]
"""The state machine of a conversation's protocol and this agent's role in it."""

ScreenKey = tuple[str, str, Performative, str | None, str | None, str | None, str | None, bool]
"""(sender, channel, performative, protocol, language, ontology, encoding, has content)."""


def _memo(table: dict[K, V], key: K, compute: Callable[[], V]) -> V:
    """``table[key]``, computed by ``compute`` and kept (while the table has room) when absent."""
    found = table.get(key, _MISSING)
    if found is not _MISSING:
        return found  # type: ignore[return-value]
    value = compute()
    if len(table) < MAX_ENTRIES:
        table[key] = value
    return value


class Lookups:
    """What agent ``name``'s specification ``spec`` and ``interface`` say, kept per peer,
    channel, key and kind of communicate."""

    def __init__(self, spec: SystemSpec, interface: Interface, name: str) -> None:
        self.spec = spec
        self.interface = interface
        self.name = name
        self._channels: dict[str, ChannelSpec | None] = {}
        self._aids: dict[str, AgentIdentifier] = {}
        self._keys: dict[tuple[str, str], str] = {}
        self._parsed: dict[str, keys.FipaKey] = {}
        self._accepts: dict[tuple[str, str, str | None], MessageKind | None] = {}
        self._sends: dict[tuple[str, str, str], MessageKind | None] = {}
        self._screens: dict[ScreenKey, Screen] = {}
        self._roles = roles(spec, name)
        self._followed: dict[tuple[str, str], Followed | None] = {}

    def channel(self, to: str) -> ChannelSpec | None:
        """The channel joining this agent and ``to`` (``channel_between``; a foreign agent as
        the external role it plays, ``SystemSpec.role_of``), or None."""
        return _memo(self._channels, to, lambda: channel_between(self.spec, self.name, self.spec.role_of(to)))

    def aid(self, name: str) -> AgentIdentifier:
        """The agent identifier of ``name`` (checked once: raises ValueError for a bad name)."""
        return _memo(self._aids, name, lambda: AgentIdentifier(name))

    def key(self, channel: str, to: str) -> str:
        """The key expression of a communicate from this agent to ``to`` on ``channel``."""
        return _memo(self._keys, (channel, to), lambda: keys.fipa_key(channel, self.name, to))

    def parse(self, key: str) -> keys.FipaKey:
        """``keys.parse_fipa_key(key)``; raises ValueError (nothing kept) for a key that is no
        communicate key."""
        found = self._parsed.get(key)
        if found is None:
            found = keys.parse_fipa_key(key)
            if len(self._parsed) < MAX_ENTRIES:
                self._parsed[key] = found
        return found

    def accepts(self, sender: str, performative: str, protocol: str | None) -> MessageKind | None:
        """The interface's received kind matching a communicate (``Interface.accepts``; a
        foreign sender as the external role it plays), or None."""
        return _memo(
            self._accepts,
            (sender, performative, protocol),
            lambda: self.interface.accepts(self.spec.role_of(sender), performative, protocol),
        )

    def sends(self, to: str, performative: str, protocol: str) -> MessageKind | None:
        """The interface's first sent kind to ``to`` (a foreign agent as its external role) of
        ``performative`` in ``protocol``, or None."""
        role = self.spec.role_of(to)

        def first() -> MessageKind | None:
            for kind in self.interface.sends:
                if kind.receiver == role and kind.performative == performative and kind.protocol == protocol:
                    return kind
            return None

        return _memo(self._sends, (to, performative, protocol), first)

    def screen(
        self,
        sender: str,
        channel: str,
        performative: Performative,
        protocol: str | None,
        language: str | None,
        ontology: str | None,
        encoding: str | None,
        has_content: bool,
    ) -> Screen:
        """The checks of a communicate from ``sender`` on ``channel`` with these parameters
        that depend on nothing else (services/runtime/intake.py ``screen``, on the
        interface's kind of :meth:`accepts`)."""
        # the member itself is the key (equal to its value, whose lookup is a Python call)
        key = (sender, channel, performative, protocol, language, ontology, encoding, has_content)
        found = self._screens.get(key)
        if found is None:
            kind = self.accepts(sender, performative.value, protocol)
            found = screen(channel, performative, protocol, language, ontology, encoding, has_content, kind)
            if len(self._screens) < MAX_ENTRIES:
                self._screens[key] = found
        return found

    def followed(self, peer: str, protocol: str) -> Followed | None:
        """The state machine of ``protocol`` and this agent's role in it with ``peer``; None
        when conversations of it with ``peer`` are not followed (a protocol the specification
        does not name or gives no state machine, or none this agent plays with ``peer``)."""
        found = self._followed.get((peer, protocol), _MISSING)
        if found is _MISSING:
            found = self._machine_and_role(peer, protocol)
            if len(self._followed) < MAX_ENTRIES:
                self._followed[(peer, protocol)] = found
        return found  # type: ignore[return-value]

    def _machine_and_role(self, peer: str, protocol: str) -> Followed | None:
        if protocol not in self.spec.protocols:
            return None
        mine = self._roles.get((self.spec.role_of(peer), protocol))
        if mine is None:
            return None
        try:
            return machine_of(self.spec, protocol), mine
        except SpecError:  # a protocol with no state machine is not followed
            return None


def roles(spec: SystemSpec, agent: str) -> dict[tuple[str, str], Role]:
    """``agent``'s role per (peer, protocol), from the channels' protocols' initiators."""
    out: dict[tuple[str, str], Role] = {}
    for ch in spec.channels:
        if agent not in ch.ends:
            continue
        peer = ch.ends[1] if ch.ends[0] == agent else ch.ends[0]
        for cp in ch.protocols:
            out[(peer, cp.protocol)] = INITIATOR if cp.initiator == agent else PARTICIPANT
    return out
