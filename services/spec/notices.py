"""Notice protocols: which interaction protocols of a specification tell the person
something (docs/agents.md, a_hi "Notices"; docs/spec.md, "A role on every channel").

A protocol is a *notice protocol* when its state machine is one message: from the initial
state the initiator's ``inform`` (FIPA SC00037) leads to a final state, and nothing else —
no other transition, no terminal one, no cancel meta-protocol — so nothing answers it. The
shipped ``roco-notify`` is one; a table a new agent declares with the same machine
(``[protocols.kitchen-warning]`` of the walk-through) is one too. The rule reads the machine,
never the name. a_hi is the participant of every notice protocol on every channel that makes
it so (services/runtime/roles/declare.py ``EVERY_NOTICE``)."""

from __future__ import annotations

from services.spec.model import SystemSpec
from services.spec.protocol_defs import machine_of
from shared.fipa_codec.acts import Performative
from shared.fipa_codec.protocols import INITIATOR, Protocol


def is_notice(machine: Protocol) -> bool:
    """Whether ``machine`` is one initiator ``inform`` from its initial state to a final state
    and nothing else (module docstring)."""
    if machine.terminal_transitions or len(machine.transitions) != 1:
        return False
    ((state, role, performative), target), *_ = machine.transitions.items()
    return (
        state == machine.initial
        and role == INITIATOR
        and performative is Performative.INFORM
        and target in machine.final
    )


def notice_protocols(spec: SystemSpec) -> frozenset[str]:
    """The names of ``spec``'s protocols that are notice protocols (:func:`is_notice` of each
    protocol's state machine, services/spec/protocol_defs.py ``machine_of``). Raises SpecError
    as ``machine_of`` does."""
    return frozenset(name for name in spec.protocols if is_notice(machine_of(spec, name)))
