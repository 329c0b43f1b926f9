"""A notice protocol is told by its state machine, not its name (services/spec/notices.py):
one initiator ``inform`` from the initial state to a final state, nothing else."""

from __future__ import annotations

import pytest

from services.spec.model import default_spec
from services.spec.notices import is_notice, notice_protocols
from shared.fipa_codec.acts import Performative
from shared.fipa_codec.protocols import INITIATOR, PARTICIPANT, PROTOCOLS, Protocol, Role, _build

ONE_INFORM = [("start", "initiator", "inform", "told")]


def machine(name: str, transitions: list[tuple[str, str, str, str]], final: set[str]) -> Protocol:
    """A state machine as a ``[protocols.NAME]`` table writes it (shared/fipa_codec/protocols.py
    ``_build`` adds not-understood)."""
    roles: dict[str, Role] = {INITIATOR: INITIATOR, PARTICIPANT: PARTICIPANT}
    edges = [(a, roles[r], Performative(p), b) for a, r, p, b in transitions]
    return _build(name, "", "", edges, final)


def test_roco_notify_is_a_notice_protocol_of_the_shipped_specification_and_fipa_request_is_not() -> None:
    """(A specification grown by an agent of its own may have more: docs/spec.md's walk-through.)"""
    found = notice_protocols(default_spec())
    assert "roco-notify" in found and not found & {"fipa-request", "fipa-query", "fipa-subscribe"}


def test_one_inform_to_a_final_state_is_a_notice_protocol_whatever_its_name() -> None:
    assert is_notice(machine("kitchen-warning", ONE_INFORM, {"told"}))


@pytest.mark.parametrize(
    ("why", "transitions", "final"),
    [
        ("answered", [*ONE_INFORM, ("told", "participant", "inform", "answered")], {"answered"}),
        ("a request", [("start", "initiator", "request", "told")], {"told"}),
        ("two openings", [*ONE_INFORM, ("start", "initiator", "cancel", "told")], {"told"}),
    ],
)
def test_anything_else_is_not(
    why: str, transitions: list[tuple[str, str, str, str]], final: set[str]
) -> None:
    assert not is_notice(machine(why, transitions, final)), why


def test_no_fipa_protocol_of_the_library_is_a_notice_protocol() -> None:
    assert not [name for name, machine in PROTOCOLS.items() if is_notice(machine)]
