"""A role declared for every channel (services/runtime/roles/ ``EVERY_CHANNEL``): it stands
for one role per channel where the specification gives the agent that role of that protocol in
exactly those languages, so that an agent serves a channel added to the specification without
an edit of its code; the comparison with the specification stays as strict as for roles
declared one by one."""

from __future__ import annotations

from pathlib import Path

import pytest

from services.agents.knowledge.agent import KnowledgeManager
from services.runtime.memory_transport import MemoryBus
from services.runtime.roles import (
    EVERY_CHANNEL,
    RoleMismatch,
    expand_roles,
    handlers_of,
    initiator,
    participant,
    role_problems,
)
from services.spec.model import DEFAULT_SPEC, default_spec, load
from tests.spec_check.walkthrough import NEXT, walkthrough_spec

SPEC = default_spec()
SUBSCRIBE = initiator(
    "C6", "fipa-subscribe", "L_WM", reply_by_s=2.0, resubscribes=True
)  # as a_km declares it
SCENE = participant(EVERY_CHANNEL, "fipa-subscribe", "L_WM")  # a_km's changes of the scene
HANDLERS = list(handlers_of(KnowledgeManager))
KM_QUERIED = [
    c.name
    for c in SPEC.channels
    if "a_km" in c.ends and any(p.protocol == "fipa-query" and p.initiator != "a_km" for p in c.protocols)
]
"""The channels on which a_km answers fipa-query: C4, C6, C7 in the shipped specification, then
any added since."""
KM_SUBSCRIBED = [
    c.name
    for c in SPEC.channels
    if "a_km" in c.ends and any(p.protocol == "fipa-subscribe" and p.initiator != "a_km" for p in c.protocols)
]
"""The channels on which a_km takes subscriptions: C7 in the shipped specification, then any
added since."""


def test_a_role_for_every_channel_stands_for_each_channel_the_spec_gives_it_in_order() -> None:
    declared = [participant(EVERY_CHANNEL, "fipa-query", "L_WM"), SUBSCRIBE, SCENE]
    roles = expand_roles(SPEC, "a_km", declared)
    assert KM_QUERIED[:3] == ["C4", "C6", "C7"]
    assert [(r.channel, r.protocol, r.role, r.languages) for r in roles] == [
        *((c, "fipa-query", "participant", ("L_WM",)) for c in KM_QUERIED),
        ("C6", "fipa-subscribe", "initiator", ("L_WM",)),
        *((c, "fipa-subscribe", "participant", ("L_WM",)) for c in KM_SUBSCRIBED),
    ]
    assert KM_SUBSCRIBED[:1] == ["C7"]
    assert role_problems(SPEC, "a_km", declared, HANDLERS) == []
    # a channel declared by itself is left to that declaration (its own deadline here)
    own = initiator("C6", "fipa-query", "L_WM", reply_by_s=5.0)
    mixed = expand_roles(SPEC, "a_ta", [initiator(EVERY_CHANNEL, "fipa-query", "L_WM", unused=True), own])
    assert mixed == [own]


def test_it_is_as_strict_as_roles_declared_one_by_one() -> None:
    # other languages: it stands for no channel, and each channel's role is missing
    problems = role_problems(
        SPEC, "a_km", [participant(EVERY_CHANNEL, "fipa-query", "L_HC"), SUBSCRIBE, SCENE], HANDLERS
    )
    assert problems[0] == (
        "agent a_km declares itself participant of fipa-query on every channel (L_HC), but no "
        "[[channels]] entry makes it the participant of fipa-query in L_HC"
    )
    assert (
        "agent a_km declares no participant role for fipa-query on C7, which [[channels]] C7 gives it "
        "(in L_WM)" in problems
    )
    # the other role of the protocol
    problems = role_problems(
        SPEC, "a_km", [initiator(EVERY_CHANNEL, "fipa-query", "L_WM"), SUBSCRIBE, SCENE], HANDLERS
    )
    assert any("no [[channels]] entry makes it the initiator of fipa-query in L_WM" in p for p in problems)
    # twice, and a role for every channel whose channels are all declared by themselves
    every = participant(EVERY_CHANNEL, "fipa-query", "L_WM")
    assert "agent a_km declares participant of fipa-query on every channel (L_WM) twice" in role_problems(
        SPEC, "a_km", [every, every, SUBSCRIBE, SCENE], HANDLERS
    )
    each = [participant(c, "fipa-query", "L_WM") for c in KM_QUERIED]
    assert role_problems(SPEC, "a_km", [*each, SUBSCRIBE, SCENE], HANDLERS) == []
    assert role_problems(SPEC, "a_km", [every, *each, SUBSCRIBE, SCENE], HANDLERS) == [
        "agent a_km declares itself participant of fipa-query on every channel (L_WM), but declares each "
        f"such channel ({', '.join(KM_QUERIED)}) by itself: the role on every channel covers none"
    ]


def test_a_channel_with_other_languages_is_not_covered(tmp_path: Path) -> None:
    text = DEFAULT_SPEC.read_text()
    c7 = text[text.index('name = "C7"') :]
    c7 = c7[: c7.index("[[channels.protocols]]", c7.index("protocol = "))]  # its fipa-query
    path = tmp_path / "spec.toml"
    path.write_text(
        text.replace(c7, c7.replace('"L_WM"', '"L_HC"').replace('["SparqlQuery"]', '["StatusQuery"]'))
    )
    spec = load(path)
    problems = role_problems(spec, "a_km", KnowledgeManager.ROLES, HANDLERS)
    assert problems == [
        "agent a_km declares no participant role for fipa-query on C7, which [[channels]] C7 gives it "
        "(in L_HC)"
    ]


@pytest.mark.walkthrough
def test_a_km_serves_a_new_channel_of_the_walkthrough_without_an_edit(tmp_path: Path) -> None:
    """docs/spec.md's walk-through adds a channel (C9 in the shipped specification;
    fipa-subscribe from a_wt): a_km starts on that specification and plays the participant
    there; an a_km that named its channels one by one refuses to start, naming the new one."""
    new = NEXT.channel_name
    spec = load(walkthrough_spec(tmp_path / "spec.toml"))
    subscribed = [
        c.name
        for c in spec.channels
        if "a_km" in c.ends
        and any(p.protocol == "fipa-subscribe" and p.initiator != "a_km" for p in c.protocols)
    ]
    km = KnowledgeManager(MemoryBus().transport(), spec)
    try:
        assert km.roles.role(new, "fipa-subscribe").role == "participant"
        served = [
            d.channel for d in km.roles.declared if d.protocol == "fipa-subscribe" and d.role == "participant"
        ]
        assert served == subscribed and "C7" in subscribed and subscribed[-1] == new
    finally:
        km.close()

    class NamedChannels(KnowledgeManager):
        ROLES = (  # type: ignore[assignment]
            participant(EVERY_CHANNEL, "fipa-query", "L_WM"),
            SUBSCRIBE,
            *(participant(c, "fipa-subscribe", "L_WM") for c in subscribed if c != new),
        )

    with pytest.raises(RoleMismatch, match=f"declares no participant role for fipa-subscribe on {new},"):
        NamedChannels(MemoryBus().transport(), spec)
