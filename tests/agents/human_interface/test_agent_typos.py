"""a_hi says back the typos it corrected, in the first report of the request ("I read 'itno' as
'into'. I will pour …"), names a word it cannot settle, and acts on a typo'd stop as a stop. On
a MemoryBus with a stand-in a_co (test_agent.py)."""

from __future__ import annotations

import queue

import pytest

from services.runtime.human import ReportKind
from shared.fipa_codec import Performative
from shared.fipa_codec.languages.l_hc import (
    CommandOutcome,
    HumanCommand,
    Progress,
    Status,
    TaskAtom,
    TaskState,
)
from tests.agents.human_interface.test_agent import ScriptedCo, Stage, _ready


def test_a_corrected_command_says_what_was_read_in_its_first_report_only(stage: Stage) -> None:
    co, _hi, person = _ready(stage)
    person.say("pour the jar itno the bowl", "r1")
    request = co.receive(Performative.REQUEST)
    assert isinstance(request.content, HumanCommand)
    assert request.content.goal == TaskAtom("pour", ("jar", "bowl"))
    cid = request.msg.conversation_id or ""

    def run(co: ScriptedCo) -> None:
        co.engine.reply(request, Performative.AGREE)
        co.progress(Progress(command_id=cid, state=TaskState.PLANNING, detail="plan #1 requested"))
        co.engine.reply(
            request, Performative.INFORM, CommandOutcome(command_id=cid, succeeded=True, detail="done")
        )

    co.do(run)
    reports = person.until_final("r1")
    assert [(r.kind, r.text) for r in reports] == [
        (ReportKind.ACCEPTED, "I read 'itno' as 'into'. I will pour the jar into the bowl."),
        (ReportKind.PROGRESS, "pour the jar into the bowl: planning; plan #1 requested"),
        (ReportKind.SUCCEEDED, "pour the jar into the bowl: succeeded; done"),
    ]


def test_a_corrected_status_question_and_stop_say_it_too(stage: Stage) -> None:
    co, _hi, person = _ready(stage)
    person.say("what are you doimg?", "r1")
    query = co.receive(Performative.QUERY_REF)
    co.do(lambda co: co.engine.reply(query, Performative.INFORM_REF, Status()))
    (report,) = person.until_final("r1")
    assert (report.kind, report.text) == (
        ReportKind.STATUS,
        "I read 'doimg' as 'doing'. I am not doing anything: no command is running or waiting.",
    )
    person.say("stpo!", "r2")
    (report,) = person.until_final("r2")
    assert (report.kind, report.text) == (
        ReportKind.STOPPED,
        "I read 'stpo' as 'stop'. Nothing is running, so there is nothing to stop.",
    )


def test_a_typod_stop_stops_the_running_command(stage: Stage) -> None:
    co, _hi, person = _ready(stage)
    person.say("bring me the cup", "r1")
    request = co.receive(Performative.REQUEST)
    co.do(lambda co: co.engine.reply(request, Performative.AGREE))
    person.say("oh no, sotp", "r2")
    cancel = co.receive(Performative.CANCEL)
    assert cancel.msg.conversation_id == request.msg.conversation_id


def test_a_word_near_two_readings_is_named_and_nothing_is_sent(stage: Stage) -> None:
    co, _hi, person = _ready(stage)
    person.say("pout the jar into the bowl", "r1")
    (report,) = person.until_final("r1")
    assert report.kind is ReportKind.NOT_UNDERSTOOD
    assert report.text.startswith("I do not know 'pout': did you mean 'pour' or 'put'?")
    with pytest.raises(queue.Empty):
        co.inbox.get(timeout=0.3)
