"""Requirement properties (services/spec/properties.py) evaluated over records
(services/spec_check/properties.py, ``roco spec trace``): every verdict can fail.

The recorded run is part of one ``roco scenario urgent_mid_pour`` (tests/spec_check/fixtures/
urgent_mid_pour/README.md): the pour, an urgent command for the cup mid-pour, a_co's cancel,
a_ta's Terminating and Preempted, the cup's plan, then the pour again. Each leaf's defining
communicates are removed, moved or re-linked in a copy of it, and its verdict changes."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import msgspec
import pytest

from services.report.load import Message
from services.spec.decomposition import load_decomposition
from services.spec.model import DEFAULT_SPEC
from services.spec.properties import EventPattern, Property, property_problems
from services.spec.requirements import leaves
from services.spec_check.properties import Monitor, Verdict, evaluate, field_value
from services.spec_check.trace import trace, trace_report
from shared.fipa_codec.languages.l_hc import Sentence, SentenceReport
from shared.fipa_codec.languages.l_sd import Observation
from shared.fipa_codec.languages.l_sw import SWStatus
from tests.report.conftest import RunBuilder
from tests.spec_check.recorded import URGENT, Recorded

LEAVES = {r.id: r for r in leaves(load_decomposition(DEFAULT_SPEC))}
JADE = "da0@host:1099/JADE"


def _c8() -> RunBuilder:
    """A foreign agent's sentence answered on C8 (R1.4), 46 s into the run."""
    b = RunBuilder()
    r = {"protocol": "fipa-request", "conversation": "j1"}
    b.add(46.0, "C8", JADE, "a_hi", "request", Sentence(text="what are you doing?"), reply_with="j1-r", **r)
    b.add(
        46.1,
        "C8",
        "a_hi",
        JADE,
        "inform",
        SentenceReport(kind="status", text="nothing"),
        in_reply_to="j1-r",
        **r,
    )
    return b


@pytest.fixture(scope="module")
def urgent() -> Recorded:
    return Recorded.read(URGENT).plus(_c8())


def _verdicts(run_dir: Path) -> dict[str, Verdict]:
    t = trace(DEFAULT_SPEC, [run_dir], tests=None)
    return {rid: leaf.verdict for rid, leaf in t.leaves.items()}


def _content(name: str) -> Callable[[Message], bool]:
    return lambda m: type(m.content).__name__ == name


def _sw(state: str) -> Callable[[Message], bool]:
    return lambda m: (
        isinstance(m.content, SWStatus) and m.performative == "inform" and m.content.state == state
    )


def _on(channel: str, performative: str, content: str | None = None) -> Callable[[Message], bool]:
    return lambda m: (
        m.channel == channel
        and m.performative == performative
        and (content is None or type(m.content).__name__ == content)
    )


def _cup_request(m: Message) -> bool:
    return m.channel == "C2" and m.performative == "request" and getattr(m.content, "priority", 0) > 0


def test_the_urgent_scenario_shows_every_leaf(urgent: Recorded, tmp_path: Path) -> None:
    """Every leaf of the shipped specification (those with a mutation below); a leaf added since
    is for its own record to show, not for this one, and this one violates none."""
    run_dir = urgent.write(tmp_path / "urgent")
    verdicts = _verdicts(run_dir)
    assert {rid: verdicts[rid] for rid in MUTATIONS} == dict.fromkeys(MUTATIONS, Verdict.SHOWN)
    assert Verdict.VIOLATED not in verdicts.values()
    code, text = trace_report([run_dir], DEFAULT_SPEC, tests=None)
    assert code == 0 and "leaves: 11 shown, " in text and ", 0 violated" in text
    assert "R2.1 [shown]" in text and "Terminating, Preempted, then the waiting command's plan: shown" in text


# each leaf: a mutation of the urgent run that takes away what makes it true, and the verdict then
MUTATIONS: dict[str, tuple[Callable[[Recorded], Recorded], Verdict]] = {
    # the agree no longer answers the command: its in-reply-to names nothing
    "R1.1": (lambda r: r.relink(_on("C2", "agree"), in_reply_to="nothing"), Verdict.NOT_EXERCISED),
    # the urgent command no longer comes while the pour is open: both outcomes arrive before it
    "R1.2": (
        lambda r: r.move(
            lambda m: _on("C2", "inform", "CommandOutcome")(m) and m.conversation == _pour(r), _cup_request
        ),
        Verdict.NOT_EXERCISED,
    ),
    # the cancel is gone (the scenario's record with the cancel removed)
    "R2.1": (lambda r: r.remove(_on("C1", "cancel")), Verdict.NOT_EXERCISED),
    # every plan a_pl sends answers nothing
    "R2.2": (
        lambda r: r.relink(_on("C3", "inform", "HierarchicalPlan"), in_reply_to="nothing"),
        Verdict.NOT_EXERCISED,
    ),
    # the hypothetical query's answer is gone
    "R2.3": (
        lambda r: r.remove(lambda m: m.channel == "C4" and m.conversation in _hypothetical(r)),
        Verdict.NOT_EXERCISED,
    ),
    # every knowledge answer answers nothing
    "R2.4": (
        lambda r: r.relink(_on("C4", "inform-ref", "Answer"), in_reply_to="nothing"),
        Verdict.NOT_EXERCISED,
    ),
    # the names query is not answered
    "R1.3": (lambda r: r.remove(_on("C7", "inform-ref")), Verdict.NOT_EXERCISED),
    # the foreign sentence is not answered
    "R1.4": (lambda r: r.remove(_on("C8", "inform")), Verdict.NOT_EXERCISED),
    # the observation with spheres in the bowl comes before any tilt
    "R3.1": (
        lambda r: r.move(
            lambda m: m.channel == "C5" and m.conversation in _last_look(r), before=_content("Tilt")
        ),
        Verdict.NOT_EXERCISED,
    ),
    # a_ta's world updates travel outside the subscription a_km made
    "R3.2": (lambda r: r.relink(_on("C6", "inform"), conversation_id="elsewhere"), Verdict.VIOLATED),
    # a_ta never tells a_km that the jar is put down: Preempted comes with the jar in hand
    "R3.3": (lambda r: r.remove(_jar_put_down), Verdict.VIOLATED),
}


def _jar_put_down(m: Message) -> bool:
    """a_ta's update to a_km that the jar is held by nothing (it was put down)."""
    return m.channel == "C6" and m.sender == "a_ta" and field_value(m.content, "objects[jar].held_by") == ""


def _pour(r: Recorded) -> str | None:
    """The conversation-id of the pour's command (the first)."""
    return next(m for m in r.messages if m.channel == "C2" and m.performative == "request").conversation


def _hypothetical(r: Recorded) -> set[str | None]:
    return {m.conversation for m in r.messages if type(m.content).__name__ == "HypotheticalQuery"}


def _last_look(r: Recorded) -> set[str | None]:
    return {[m for m in r.messages if type(m.content).__name__ == "Observation"][-1].conversation}


def test_every_leaf_the_urgent_record_shows_has_a_mutation(urgent: Recorded, tmp_path: Path) -> None:
    shown = {rid for rid, v in _verdicts(urgent.write(tmp_path / "urgent")).items() if v is Verdict.SHOWN}
    assert shown == set(MUTATIONS) and shown <= set(LEAVES)


@pytest.mark.parametrize("rid", sorted(MUTATIONS))
def test_taking_away_what_makes_a_leaf_true_changes_its_verdict(
    rid: str, urgent: Recorded, tmp_path: Path
) -> None:
    mutate, expected = MUTATIONS[rid]
    verdicts = _verdicts(mutate(urgent).write(tmp_path / "mutated"))
    assert verdicts[rid] == expected, verdicts


def test_a_cancelled_plan_that_is_never_preempted_violates_r2_1(urgent: Recorded, tmp_path: Path) -> None:
    """The situation (two commands open, a plan cancelled) happened; a_ta never said Preempted."""
    verdicts = _verdicts(urgent.remove(_sw("Preempted")).write(tmp_path / "no_preempted"))
    assert verdicts["R2.1"] == Verdict.VIOLATED
    assert verdicts["R1.2"] == Verdict.SHOWN  # the decision stands


def test_preempted_before_terminating_is_out_of_order(urgent: Recorded, tmp_path: Path) -> None:
    late = urgent.move(_sw("Preempted"), before=_sw("Terminating"))
    t = trace(DEFAULT_SPEC, [late.write(tmp_path / "late")], tests=None)
    (outcome,) = t.leaves["R2.1"].runs[0].outcomes
    assert outcome.verdict == Verdict.VIOLATED  # the property itself, whatever conformance says
    assert (
        "steps 1–4 matched, then no C1 coordinate inform SWStatus a_ta→* state=Preempted"
        in outcome.describe()
    )


def test_a_next_plan_for_another_command_does_not_show_the_decision(urgent: Recorded, tmp_path: Path) -> None:
    """R1.2's next plan after the urgent command must name it: re-pointed, the choice is gone."""
    cup = next(m for m in urgent.messages if _cup_request(m)).conversation
    moved = urgent.remove(lambda m: m.channel == "C1" and (m.conversation or "").startswith(f"{cup}-exec"))
    verdicts = _verdicts(moved.write(tmp_path / "no_cup_plan"))
    assert verdicts["R1.2"] != Verdict.SHOWN and verdicts["R2.1"] == Verdict.VIOLATED


# ---- the language and the evaluator ---------------------------------------------------------


def _prop(*steps: EventPattern, exercised: int | None = None) -> Property:
    return Property(text="t", steps=steps, exercised=exercised)


def test_a_property_that_names_an_unknown_or_later_step_is_refused() -> None:
    p = _prop(EventPattern(channel="C1", same_conversation="x"), EventPattern(channel="C1", name="x"))
    assert property_problems(p) == ["step 1 (C1): names x, which no earlier step is"]
    assert property_problems(_prop()) == ["no steps"]
    twice = _prop(EventPattern(channel="C1", name="a"), EventPattern(channel="C1", name="a"), exercised=3)
    assert property_problems(twice) == ["exercised must be 1 to 2, not 3", "step 2 (C1): name a used twice"]
    assert property_problems(_prop(EventPattern(channel="C1", fields={"a..b": 1}))) == [
        "step 1 (C1 a..b=1): field path 'a..b' is not a, a[key], a.b, …"
    ]


def test_the_shipped_properties_fit_the_channels(tmp_path: Path) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text(
        DEFAULT_SPEC.read_text().replace('{ name = "q", channel = "C7"', '{ name = "q", channel = "C5"', 1)
    )
    from services.spec_check.trace import TraceError

    with pytest.raises(TraceError, match=r"R1.3, property 1 .* step 1 .*C5 does not serve it"):
        trace(bad, [URGENT], tests=None)


def test_field_paths_pick_elements_by_name(urgent: Recorded) -> None:
    last = [m for m in urgent.messages if type(m.content).__name__ == "Observation"][-1]
    assert isinstance(field_value(last.content, "objects[bowl].particles_inside"), int)
    assert field_value(last.content, "objects[teapot].particles_inside") is None
    assert field_value(last.content, "nothing.at.all") is None


def test_the_monitor_is_fed_one_communicate_at_a_time(urgent: Recorded) -> None:
    """Incremental: R2.1 is not exercised until the Preempted's plan follows; shown from then."""
    (prop,) = LEAVES["R2.1"].properties
    monitor = Monitor(prop)
    seen: list[Verdict] = []
    for m in _causal(urgent):
        monitor.feed(m)
        seen.append(monitor.verdict(final=False))
    assert Verdict.VIOLATED not in seen and seen[-1] == Verdict.SHOWN and seen[0] == Verdict.NOT_EXERCISED
    assert evaluate(prop, _causal(urgent)).verdict == Verdict.SHOWN


def _causal(r: Recorded) -> list[Message]:
    from services.recorder.causal import causal_order

    return causal_order(r.messages)[0]


def test_no_spheres_in_the_bowl_does_not_show_that_the_pour_influenced_the_world(urgent: Recorded) -> None:
    (_, _, poured) = LEAVES["R3.1"].properties
    messages = _causal(urgent)
    assert evaluate(poured, messages).verdict == Verdict.SHOWN
    empty = [
        Message(
            m.rec,
            m.t,
            m.comm,
            msgspec.structs.replace(
                m.content,
                objects=tuple(msgspec.structs.replace(o, particles_inside=0) for o in m.content.objects),
            ),
        )
        if isinstance(m.content, Observation)
        else m
        for m in messages
    ]
    assert evaluate(poured, empty).verdict == Verdict.NOT_EXERCISED


def test_updates_outside_the_subscription_do_not_show_r3_2(urgent: Recorded) -> None:
    (prop,) = LEAVES["R3.2"].properties
    elsewhere = urgent.relink(_on("C6", "inform"), conversation_id="elsewhere")
    assert evaluate(prop, _causal(urgent)).verdict == Verdict.SHOWN
    assert evaluate(prop, _causal(elsewhere)).verdict == Verdict.NOT_EXERCISED


def test_a_preempted_in_another_conversation_does_not_follow_the_cancel(urgent: Recorded) -> None:
    (prop,) = LEAVES["R2.1"].properties
    elsewhere = urgent.relink(_sw("Preempted"), conversation_id="elsewhere")
    assert evaluate(prop, _causal(elsewhere)).verdict == Verdict.VIOLATED


def test_the_decision_is_the_next_plan_not_any_later_one(urgent: Recorded) -> None:
    """R1.2's plan step is ``next``: the pour's plan sent first after the urgent command was
    agreed means a_co chose the pour, even though the cup's plan comes later."""
    (prop,) = LEAVES["R1.2"].properties
    cup = next(m for m in urgent.messages if _cup_request(m)).conversation
    pour_again = next(
        m.conversation
        for m in urgent.messages
        if m.channel == "C1" and m.performative == "request" and m.conversation != f"{cup}-exec2" and m.t > 30
    )

    def first_cup_plan(m: Message) -> bool:
        return m.channel == "C1" and m.performative == "request" and m.conversation == f"{cup}-exec2"

    swapped = urgent.move(lambda m: m.channel == "C1" and m.conversation == pour_again, before=first_cup_plan)
    assert evaluate(prop, _causal(urgent)).verdict == Verdict.SHOWN
    assert evaluate(prop, _causal(swapped)).verdict == Verdict.NOT_EXERCISED


def test_a_capped_evaluation_says_so(urgent: Recorded, monkeypatch: pytest.MonkeyPatch) -> None:
    from services.spec_check import properties

    (prop,) = LEAVES["R1.1"].properties
    assert not evaluate(prop, _causal(urgent)).capped
    monkeypatch.setattr(properties, "MAX_PARTIALS", 1)
    outcome = evaluate(prop, _causal(urgent))
    assert outcome.capped and "(partial matches capped at 1)" in outcome.describe()
