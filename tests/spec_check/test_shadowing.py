"""``roco spec verify-code`` refuses an agent whose class replaces a name of the runtime's Agent
that an agent may not define again (services/spec_check/code_check.py ``shadowing``): a helper
named like one of the runtime's attributes broke the runtime far from its cause."""

from __future__ import annotations

from services.runtime.agent import OVERRIDABLE
from services.runtime.main import agent_class
from services.spec.model import default_spec
from services.spec_check.code_check import shadowing


def test_the_kitchen_s_agents_replace_only_what_an_agent_may() -> None:
    spec = default_spec()
    for a in spec.agents:
        assert shadowing(a.name, agent_class(spec, a.name)) == [], a.name


def test_a_helper_named_like_a_runtime_attribute_is_refused_and_a_hook_is_not() -> None:
    spec = default_spec()
    planner = agent_class(spec, "a_pl")

    def helper(self: object) -> bool:
        return True

    shadowed = type("Planner2", (planner,), {"engine": helper, "setup": lambda self: None})
    (problem,) = shadowing("a_pl", shadowed)
    assert problem == "agent a_pl: Planner2.engine replaces the runtime's Agent.engine: name it otherwise"
    assert "setup" in OVERRIDABLE
    public = type("Planner3", (planner,), {"post": helper})
    assert shadowing("a_pl", public) == [
        "agent a_pl: Planner3.post replaces the runtime's Agent.post: name it otherwise"
    ]


def test_the_engine_s_own_names_are_out_of_an_agent_s_way() -> None:
    """A helper named like one of the engine's attributes (``_ended``) or methods (``send``)
    replaces nothing: they are the engine's, not the agent's."""
    planner = agent_class(default_spec(), "a_pl")
    own = type("Planner4", (planner,), {"_ended": lambda self: True, "send": lambda self: None})
    assert shadowing("a_pl", own) == []
