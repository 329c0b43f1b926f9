"""What tests/agents/human_interface/test_agent_notices.py shares: the shipped specification
with one more agent, a_wt (a kitchen watcher), on a channel of its own to a_hi, C9, that
carries ``roco-notify`` (a_wt initiates) in L_HC; ``ANY_TERM_SPEC`` names no ``contents`` there
(any L_HC term passes the runtime's check). The watcher is in notice_watcher.py (the module
that declares an agent's roles may name only what they send: services/runtime/code_scan.py)."""

from __future__ import annotations

import msgspec

from services.spec.model import AgentSpec, ChannelProtocol, ChannelSpec, SystemSpec, default_spec

WATCHER = "a_wt"
CHANNEL = "C9"
NOTIFY = "roco-notify"


def _spec(contents: dict[str, tuple[str, ...]]) -> SystemSpec:
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
                protocol=NOTIFY, initiator=WATCHER, languages={"inform": "L_HC"}, contents=contents
            ),
        ),
    )
    return msgspec.structs.replace(
        shipped, agents=(*shipped.agents, agent), channels=(*shipped.channels, channel)
    )


SPEC = _spec({"inform": ("Notice",)})
ANY_TERM_SPEC = _spec({})
