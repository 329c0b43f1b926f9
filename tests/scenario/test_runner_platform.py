"""The scenario runner's foreign agent (services/scenario/runner.py, a ``say`` step ``from =
"gateway"``): the run gets a gateway, and the answers the foreign agent receives in its
conversation are its command's reports, the final one ending it."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import msgspec

from services.runtime.human import ReportKind
from services.scenario.model import Scenario, Step
from services.scenario.runner import CommandRecord, ScenarioRunner
from shared.fipa_codec import Communicate, Performative
from shared.fipa_codec.aid import AgentIdentifier
from shared.fipa_codec.languages.l_hc import SentenceReport


class _Hosting:
    fleet: Any = None


def _runner(tmp_path: Path, speaker: str) -> ScenarioRunner:
    scenario = Scenario(name="t", steps=(Step(say="pour the jar into the bowl", from_=speaker),))
    return ScenarioRunner(scenario, tmp_path, hosting=_Hosting())  # type: ignore[arg-type]


def _answer(
    performative: Performative, conversation: str, content: bytes, language: str = "L_HC"
) -> Communicate:
    return Communicate(
        performative=performative,
        sender=AgentIdentifier("a_hi"),
        content=content,
        language=language,
        conversation_id=conversation,
    )


def _report(kind: str, text: str) -> bytes:
    """A SentenceReport as the gateway posts it: JSON (services/gateway/bridge.py)."""
    return msgspec.json.encode(SentenceReport(kind=kind, text=text))


def test_a_step_from_the_gateway_gives_the_run_a_gateway(tmp_path: Path) -> None:
    assert _runner(tmp_path, "gateway").gateway is not None
    assert _runner(tmp_path, "person").gateway is None


def test_the_foreign_agents_answers_are_its_commands_reports(tmp_path: Path) -> None:
    runner = _runner(tmp_path, "gateway")
    record = CommandRecord(1, "pour the jar into the bowl", "p-1")
    runner.commands.append(record)
    runner.conversations["roco-scenario-1"] = record
    runner._take("foreign", _answer(Performative.AGREE, "roco-scenario-1", _report("accepted", "on it")))
    runner._take("foreign", _answer(Performative.INFORM, "elsewhere", _report("succeeded", "not this one")))
    assert [r.kind for r in record.reports] == [ReportKind.ACCEPTED] and record.final is None
    runner._take("foreign", _answer(Performative.INFORM, "roco-scenario-1", _report("succeeded", "poured")))
    assert record.final is not None and record.final.kind is ReportKind.SUCCEEDED
    assert record.as_expected


def test_an_answer_without_a_report_fails_the_command_with_its_text(tmp_path: Path) -> None:
    runner = _runner(tmp_path, "gateway")
    record = CommandRecord(1, "pour the jar into the bowl", "p-1")
    runner.commands.append(record)
    runner.conversations["roco-scenario-1"] = record
    runner._take(
        "foreign", _answer(Performative.REFUSE, "roco-scenario-1", b"no such agent", language="text")
    )
    assert record.final is not None and record.final.kind is ReportKind.FAILED
    assert record.final.text == "refuse: no such agent"
