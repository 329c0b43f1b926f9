"""Every agent's communication follows from the specification: each declares its
protocol roles, sends only through them, and no agent module compares performatives (the
roles route what arrives by the protocols' state machines)."""

from __future__ import annotations

import pytest

from services.runtime.code_scan import scan
from services.runtime.main import agent_class
from services.runtime.roles import agent_problems
from services.spec.model import default_spec
from services.spec_check.code_check import package_files
from shared.fipa_codec import Performative

AGENTS = default_spec().agent_names


@pytest.mark.parametrize("agent", AGENTS)
def test_no_agent_module_compares_performatives_or_sends_outside_its_roles(agent: str) -> None:
    implementation = next(a.implementation for a in default_spec().agents if a.name == agent)
    files = package_files(implementation)
    assert files, implementation
    # every performative allowed and every opening known: what is left is a comparison, a
    # raw send or a handler not written
    found = scan(files, frozenset(Performative), frozenset({("*", "*")}))
    opens = [f for f in found if f.text.startswith("opens ")]  # checked against the roles below
    assert [str(f) for f in found if f not in opens] == []


@pytest.mark.parametrize("agent", AGENTS)
def test_every_agent_plays_exactly_the_roles_the_specification_gives_it(agent: str) -> None:
    spec = default_spec()
    cls = agent_class(spec, agent)
    implementation = next(a.implementation for a in spec.agents if a.name == agent)
    assert cls.ROLES is not None
    assert agent_problems(spec, agent, cls, package_files(implementation)) == []
