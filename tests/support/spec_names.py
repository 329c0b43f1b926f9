"""The names module of another specification, for a test (services/spec/render_names.py).

An agent module imports its channels, protocols and languages from its system's names module
(services/spec/names.py for the shipped specification). An agent written for another specification
(a test's, with protocols or channels the shipped one lacks) imports names that module does not
have: :func:`use_names` puts the module rendered from that specification in its place for one
test, as ``roco spec new-agent`` renders it into the checkout it writes the agent in."""

from __future__ import annotations

import sys
from types import ModuleType

import pytest

from services.spec.model import SystemSpec
from services.spec.render_names import render


def use_names(spec: SystemSpec, monkeypatch: pytest.MonkeyPatch) -> ModuleType:
    """Make ``import`` of ``spec``'s names module (``SystemSpec.names_module``: the one an agent
    ``roco spec new-agent`` writes imports) give the module rendered from ``spec`` until the test
    ends (``monkeypatch`` undoes it); the module. Raises NamesError as ``render``."""
    module = ModuleType(spec.names_module)
    exec(compile(render(spec), f"<names of {spec.system}>", "exec"), module.__dict__)
    monkeypatch.setitem(sys.modules, spec.names_module, module)
    return module
