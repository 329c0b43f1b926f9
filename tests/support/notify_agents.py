"""What the two agents of tests/runtime/test_declared_protocol.py share: a specification that
declares two protocols by name in its own table, as ``[protocols.NAME]`` with a state machine
(services/spec/protocol_defs.py) — ``notify`` (one inform, nothing answers) and ``tell`` (an
inform the participant confirms) — spoken on C1 between a_n (initiator) and a_l. The agents
are in notify_sender.py and notify_listener.py (each module may name only what its roles
send: services/runtime/code_scan.py); both answer by a script, as tests/support/role_agents.py
``Scripted``."""

from __future__ import annotations

from services.spec.model import AgentSpec, ChannelProtocol, ChannelSpec, ProtocolRoles, SystemSpec

NOTIFY = "notify"
TELL = "tell"


def _spec() -> SystemSpec:
    protocols = {
        NOTIFY: ProtocolRoles(
            initiator=("inform",),
            participant=(),
            final=("told",),
            transitions=(("start", "initiator", "inform", "told"),),
        ),
        TELL: ProtocolRoles(
            initiator=("inform",),
            participant=("confirm",),
            final=("confirmed",),
            transitions=(
                ("start", "initiator", "inform", "told"),
                ("told", "participant", "confirm", "confirmed"),
            ),
        ),
    }
    channel = ChannelSpec(
        name="C1",
        ends=("a_n", "a_l"),
        transmits="notifications and confirmed statements",
        protocols=(
            ChannelProtocol(protocol=NOTIFY, initiator="a_n", languages={"inform": "L_SW"}),
            ChannelProtocol(protocol=TELL, initiator="a_n", languages={"inform": "L_SW", "confirm": "L_SW"}),
        ),
    )
    agents = tuple(AgentSpec(name=n, group=n, implementation="tests:none") for n in ("a_n", "a_l"))
    return SystemSpec(system="T", agents=agents, protocols=protocols, channels=(channel,))


SPEC = _spec()
