"""What tests/agents/human_interface/test_agent_notices.py shares: the shipped specification
with one more agent, a_wt (a kitchen watcher), on a channel of its own to a_hi, C9, that
carries ``roco-notify`` (a_wt initiates) in L_HC; ``ANY_TERM_SPEC`` names no ``contents`` there
(any L_HC term passes the runtime's check). ``WARNING_SPEC`` carries instead ``kitchen-warning``,
a notice protocol of its own table (one inform, nothing answers), with the watcher's own terms
(:class:`Fallen`, which says itself, and :class:`Plain`, which does not; test_agent_notices.py
adds them to L_HC); ``CHAT_SPEC`` carries ``chat``, two messages (an inform answered by an
inform), which is no notice protocol. The watcher is in notice_watcher.py (the module that
declares an agent's roles may name only what they send: services/runtime/code_scan.py)."""

from __future__ import annotations

import msgspec

from services.spec.model import (
    AgentSpec,
    ChannelProtocol,
    ChannelSpec,
    ProtocolRoles,
    SystemSpec,
    default_spec,
)

WATCHER = "a_wt"
CHANNEL = "C9"
NOTIFY = "roco-notify"
WARNING = "kitchen-warning"
CHAT = "chat"
TABLES = {
    WARNING: ProtocolRoles(
        initiator=("inform",),
        participant=(),
        final=("told",),
        transitions=(("start", "initiator", "inform", "told"),),
        description="the watcher warns the person: one inform, nothing answers",
        spec="inform: FIPA SC00037",
    ),
    CHAT: ProtocolRoles(
        initiator=("inform",),
        participant=("inform",),
        final=("answered",),
        transitions=(("start", "initiator", "inform", "said"), ("said", "participant", "inform", "answered")),
        description="an inform answered by an inform: two messages, no notice",
    ),
}
"""The protocols of :data:`WARNING_SPEC` and :data:`CHAT_SPEC`, as their tables declare them."""


class Fallen(msgspec.Struct, frozen=True, tag="fallen_test", kw_only=True):
    """A thing of the kitchen fell over (the watcher's own term): says itself."""

    object: str
    tilt_deg: float

    def told(self) -> str:
        """The warning the person reads."""
        return f"the {self.object} has tipped over"


class Plain(msgspec.Struct, frozen=True, tag="plain_test", kw_only=True):
    """A term that does not say itself: told by its string form."""

    name: str


class Long(msgspec.Struct, frozen=True, tag="long_test", kw_only=True):
    """A term whose sentence is longer than a Notice's: ``n`` characters."""

    n: int

    def told(self) -> str:
        """``n`` times ``a``."""
        return "a" * self.n


class Broken(msgspec.Struct, frozen=True, tag="broken_test", kw_only=True):
    """A term whose ``told()`` fails."""

    n: int

    def told(self) -> str:
        """Fails: ValueError."""
        raise ValueError(f"no sentence for {self.n}")


TERMS = (Fallen, Plain, Long, Broken)


def _spec(contents: dict[str, tuple[str, ...]], protocol: str = NOTIFY) -> SystemSpec:
    shipped = default_spec()
    agent = AgentSpec(
        name=WATCHER,
        group="wt",
        implementation="tests.support.notice_watcher:Watcher",
        job="watches the kitchen and warns the person",
    )
    channel = ChannelSpec(
        name=CHANNEL,
        ends=(WATCHER, "a_hi"),
        transmits="the watcher's notices to the person",
        protocols=(
            ChannelProtocol(
                protocol=protocol, initiator=WATCHER, languages={"inform": "L_HC"}, contents=contents
            ),
        ),
    )
    protocols = {**shipped.protocols, **({protocol: TABLES[protocol]} if protocol in TABLES else {})}
    return msgspec.structs.replace(
        shipped, agents=(*shipped.agents, agent), channels=(*shipped.channels, channel), protocols=protocols
    )


SPEC = _spec({"inform": ("Notice",)})
ANY_TERM_SPEC = _spec({})
WARNING_SPEC = _spec({"inform": ("Fallen", "Plain", "Long", "Broken")}, WARNING)
CHAT_SPEC = _spec({}, CHAT)
