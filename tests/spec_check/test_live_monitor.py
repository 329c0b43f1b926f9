"""Requirement properties monitored live (services/spec_live, ``absent`` steps of
services/spec/properties.py): a property is flagged violated at the communicate that violates
it, while the run goes on, and a run that keeps it is never flagged.

The record is part of one ``roco scenario urgent_mid_pour`` (tests/spec_check/fixtures/
urgent_mid_pour/README.md): a_co cancels the pour while a_ta holds the jar; a_ta puts the jar
down (its C6 update to a_km: the jar held by nothing), then reports Preempted. Mutations of a
copy of it plant the faults: the put-down removed (Preempted with the jar in hand), the
put-down moved before the cancel (nothing held when the cancel comes), the bowl (held by the
right gripper) kept in hand at the cancel, the jar taken by the right gripper instead."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import msgspec
import pytest

from services.recorder.causal import causal_order, send_order
from services.recorder.flags import FLAGS_JSONL, append_flag, read_flags
from services.report.load import Message
from services.spec.decomposition import load_decomposition
from services.spec.model import DEFAULT_SPEC
from services.spec.properties import EventPattern, Expected, Property, property_problems
from services.spec.requirements import leaves
from services.spec_check.properties import Monitor, Verdict, _content_fits, field_value
from services.spec_live.live import CausalFeed, LiveMonitor
from services.spec_live.sink import open_sink, watched
from shared.fipa_codec.languages.l_sw import SWStatus
from shared.fipa_codec.languages.l_wm import ObjectUpdate, WorldUpdate
from tests.spec_check.recorded import URGENT, Recorded
from tests.support.flags import a_flag

pytestmark = pytest.mark.requirement("R3.3")
LEAVES = {r.id: r for r in leaves(load_decomposition(DEFAULT_SPEC))}
(SAFE,) = LEAVES["R3.3"].properties


@pytest.fixture(scope="module")
def urgent() -> Recorded:
    return Recorded.read(URGENT)


def _put_down(m: Message) -> bool:
    return m.channel == "C6" and m.sender == "a_ta" and field_value(m.content, "objects[jar].held_by") == ""


def _preempted(m: Message) -> bool:
    return isinstance(m.content, SWStatus) and m.content.state == "Preempted" and m.performative == "inform"


def _cancel(m: Message) -> bool:
    return m.channel == "C1" and m.performative == "cancel"


def _causal(r: Recorded) -> list[Message]:
    ordered, _ = causal_order([m for m in r.messages if m.copy_of is None])
    return send_order(ordered)[0]


def _verdicts(prop: Property, messages: list[Message]) -> list[Verdict]:
    """The verdict (run not ended) after each communicate."""
    monitor = Monitor(prop)
    seen = []
    for m in messages:
        monitor.feed(m)
        seen.append(monitor.verdict(final=False))
    return seen


def test_the_real_preemption_is_never_violated_and_is_shown(urgent: Recorded) -> None:
    seen = _verdicts(SAFE, _causal(urgent))
    assert Verdict.VIOLATED not in seen and seen[-1] == Verdict.SHOWN


def test_preempted_without_the_put_down_is_violated_at_the_preempted(urgent: Recorded) -> None:
    messages = _causal(urgent.remove(_put_down))
    seen = _verdicts(SAFE, messages)
    at = seen.index(Verdict.VIOLATED)
    assert _preempted(messages[at])  # flagged live, at the communicate that violates it
    assert set(seen[at:]) == {Verdict.VIOLATED}  # and it stays violated (the pour resumed and ended)
    monitor = Monitor(SAFE)
    for m in messages:
        monitor.feed(m)
    outcome = monitor.outcome(final=False)
    assert outcome.violation is not None and outcome.violation.by is messages[at]
    assert outcome.describe().startswith(f"violated at {messages[at].t:.1f} s: C1 coordinate inform SWStatus")
    assert "came while waiting for C6 fipa-subscribe inform WorldUpdate" in outcome.describe()


def test_a_jar_put_down_before_the_cancel_does_not_make_the_situation(urgent: Recorded) -> None:
    """The jar put down before a_co's cancel: nothing is held when the plan is cancelled, so
    Preempted right after it violates nothing (the absent step before the situation drops
    the partial match)."""
    moved = urgent.move(_put_down, before=_cancel)
    seen = _verdicts(SAFE, _causal(moved))
    assert Verdict.VIOLATED not in seen and seen[-1] == Verdict.NOT_EXERCISED


def _released(name: str) -> Callable[[Message], bool]:
    def pick(m: Message) -> bool:
        return (
            m.channel == "C6"
            and m.sender == "a_ta"
            and field_value(m.content, f"objects[{name}].held_by") == ""
        )

    return pick


def _taken(m: Message) -> bool:
    return m.channel == "C6" and field_value(m.content, "objects[jar].held_by") == "left_gripper"


def _in_right(content: msgspec.Struct) -> msgspec.Struct:
    assert isinstance(content, WorldUpdate)
    objects = tuple(
        msgspec.structs.replace(o, held_by="right_gripper") if o.name == "jar" else o for o in content.objects
    )
    return msgspec.structs.replace(content, objects=objects)


def test_an_object_in_the_right_gripper_at_the_cancel_must_be_put_down_too(urgent: Recorded) -> None:
    """The bowl, held by the right gripper before the cancel, kept in hand (its release
    removed): Preempted comes with the bowl in hand, and the property is violated there."""
    messages = _causal(urgent.remove(_released("bowl")))
    seen = _verdicts(SAFE, messages)
    at = seen.index(Verdict.VIOLATED)
    assert _preempted(messages[at]) and set(seen[at:]) == {Verdict.VIOLATED}


def test_the_jar_taken_by_the_right_gripper_is_followed_as_by_the_left(urgent: Recorded) -> None:
    """The jar's grasp rewritten to the right gripper: put down before Preempted, shown;
    its put-down removed, violated at the Preempted."""
    right = urgent.recontent(_taken, _in_right)
    assert any(field_value(m.content, "objects[jar].held_by") == "right_gripper" for m in right.messages)
    seen = _verdicts(SAFE, _causal(right))
    assert Verdict.VIOLATED not in seen and seen[-1] == Verdict.SHOWN
    messages = _causal(right.remove(_put_down))
    seen = _verdicts(SAFE, messages)
    assert _preempted(messages[seen.index(Verdict.VIOLATED)])


def test_a_variable_binds_one_element_per_match() -> None:
    """``objects[$o]`` fits through each element; a later ``objects[$o]`` is that element."""
    held = WorldUpdate(
        stamp=1.0,
        objects=(
            ObjectUpdate(name="jar", held_by="left_gripper"),
            ObjectUpdate(name="bowl", held_by="right_gripper"),
        ),
    )
    either: dict[str, Expected] = {"objects[$o].held_by": ["left_gripper", "right_gripper"]}
    step = EventPattern(channel="C6", content="WorldUpdate", fields=either)
    assert _content_fits(step, held, ()) == [(("o", "jar"),), (("o", "bowl"),)]
    released = WorldUpdate(stamp=2.0, objects=(ObjectUpdate(name="bowl", held_by=""),))
    down = EventPattern(channel="C6", content="WorldUpdate", fields={"objects[$o].held_by": ""})
    assert _content_fits(down, released, (("o", "bowl"),)) == [(("o", "bowl"),)]
    assert _content_fits(down, released, (("o", "jar"),)) == []
    assert step.describe() == "C6 WorldUpdate objects[$o].held_by=left_gripper|right_gripper"
    cross = EventPattern(channel="C6", refers={"objects[$o].name": "x"}, name="y")
    empty = EventPattern(channel="C6", fields={"a": []})
    problems = property_problems(
        Property(text="x", steps=(EventPattern(channel="C6", name="x"), cross, empty))
    )
    assert problems == [
        "step 2 (C6): field path 'objects[$o].name' of refers/above names a variable",
        "step 3 (C6 a=): field 'a' lists no value",
    ]


def test_absent_steps_are_checked() -> None:
    c1 = EventPattern(channel="C1", protocol="coordinate", performative="inform")
    ends = Property(text="x", steps=(msgspec.structs.replace(c1, absent=True), c1))
    assert property_problems(ends) == [
        "step 1 (no C1 coordinate inform): an absent step cannot be the first or the last"
    ]
    named = Property(
        text="x",
        steps=(c1, msgspec.structs.replace(c1, absent=True, name="a", next=True), c1),
    )
    assert property_problems(named) == [
        "step 2 (no C1 coordinate inform): an absent step binds nothing, so it cannot be named",
        "step 2 (no C1 coordinate inform): an absent step cannot carry at_least, within_s or next",
    ]
    assert property_problems(SAFE) == []


def test_an_answer_is_held_until_what_it_answers_arrives(urgent: Recorded) -> None:
    """Arrival order with an answer before its request: the feed gives the request first; an
    answer to something never seen is let go after ``hold`` arrivals."""
    request, answer = next(
        (m, a)
        for m in urgent.messages
        if m.comm is not None and m.comm.reply_with
        for a in urgent.messages
        if a.comm is not None and a.comm.in_reply_to == m.comm.reply_with
    )
    feed = CausalFeed(hold=3)
    assert feed.push(answer) == []
    assert feed.push(request) == [request, answer]
    orphan = CausalFeed(hold=2)
    others = [
        m for m in urgent.messages if m.comm is not None and not m.comm.in_reply_to and m is not request
    ]
    others = others[:2]
    assert orphan.push(answer) == [] and orphan.push(others[0]) == [others[0]]
    assert orphan.push(others[1]) == [others[1], answer]


def _arrivals(r: Recorded) -> list[tuple[Message, bytes]]:
    return list(zip(r.messages, r.payloads, strict=True))


def test_the_recorders_sink_flags_the_planted_fault_once_and_the_real_run_never(
    urgent: Recorded, tmp_path: Path
) -> None:
    """The sink the recorder loads (services/recorder/recorder.py ``MONITOR``), given the
    records and bytes in arrival order: the mutated run gets one flag for R3.3 at the
    Preempted, raised before the record ended; the real run none."""
    for name, run, flagged in (("real", urgent, 0), ("planted", urgent.remove(_put_down), 1)):
        run_dir = tmp_path / name
        run_dir.mkdir()
        sink = open_sink("recorder", run_dir)
        assert sink is not None
        for m, payload in _arrivals(run):
            sink.communicate(m.rec, payload)
        sink.finish()
        flags = read_flags(run_dir)
        assert len(flags) == flagged, flags
    (flag,) = flags
    preempted = next(m for m in urgent.messages if _preempted(m))
    assert (flag.requirement, flag.prop, flag.seq) == ("R3.3", SAFE.text, preempted.rec.seq)
    assert flag.event.startswith("C1 a_ta → a_co inform SWStatus state=Preempted (conversation ")
    assert flag.recorded < len(urgent.messages) - 1  # live: raised while traffic still came
    assert "came while waiting for C6" in flag.why


def test_only_properties_with_an_absent_step_are_watched() -> None:
    assert watched(DEFAULT_SPEC).channels == {"C1", "C6"}  # R3.3's only
    assert LiveMonitor([]).channels == frozenset()


def test_flags_are_read_back_and_a_cut_line_is_skipped(tmp_path: Path) -> None:
    flag = a_flag(
        t=110.0,
        seq=7,
        recorded=9,
        flagged=111.0,
    )
    append_flag(tmp_path, flag)
    with (tmp_path / FLAGS_JSONL).open("ab") as f:
        f.write(b'{"requirement": "R3')
    assert read_flags(tmp_path) == [flag]
    assert flag.line(100.0) == "R3.3 “p”: C1 a_ta → a_co inform at 10.0 s (w)"
    assert read_flags(tmp_path / "nothing") == []
