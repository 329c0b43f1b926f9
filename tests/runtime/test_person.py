"""What an interface agent keeps of the outcomes it told (services/runtime/person.py): the final
reports of commands, bounded in number and text; not progress, not status."""

from __future__ import annotations

import msgspec

from services.runtime.human import HumanReport, ReportKind
from services.runtime.person import MAX_TOLD, MAX_TOLD_TEXT, Told
from services.runtime.reports import MAX_OUTCOMES_BYTES


def _report(rid: str, kind: ReportKind, text: str = "pour the jar into the bowl: succeeded") -> HumanReport:
    return HumanReport(request_id=rid, kind=kind, text=text)


def test_only_the_final_reports_of_commands_are_kept() -> None:
    told = Told()
    kept = [
        told.keep(_report("a", ReportKind.ACCEPTED)),
        told.keep(_report("a", ReportKind.PROGRESS)),
        told.keep(_report("s", ReportKind.STATUS)),
        told.keep(_report("a", ReportKind.SUCCEEDED)),
        told.keep(_report("b", ReportKind.NOT_UNDERSTOOD)),
    ]
    assert kept == [False, False, False, True, True]
    assert [(r.request_id, r.kind) for r in told.reports] == [
        ("a", ReportKind.SUCCEEDED),
        ("b", ReportKind.NOT_UNDERSTOOD),
    ]


def test_the_oldest_are_forgotten_and_long_texts_cut_so_the_answer_stays_bounded() -> None:
    told = Told()
    for i in range(MAX_TOLD + 5):
        told.keep(_report(f"r{i}", ReportKind.FAILED, "x" * (3 * MAX_TOLD_TEXT)))
    assert len(told.reports) == MAX_TOLD and told.reports[0].request_id == "r5"
    assert all(len(r.text) == MAX_TOLD_TEXT and r.text.endswith("…") for r in told.reports)
    answer = told.answer()
    assert len(answer) <= MAX_OUTCOMES_BYTES  # what roco send reads of it
    assert msgspec.json.decode(answer, type=list[HumanReport]) == told.reports


class _Transport:
    def __init__(self) -> None:
        self.subscribed: dict[str, object] = {}
        self.served: dict[str, object] = {}

    def subscribe(self, key: str, callback: object) -> None:
        self.subscribed[key] = callback

    def serve(self, key: str, answer: object) -> None:
        self.served[key] = answer


class _Engine:
    """What a PersonFace uses of an agent's engine: its transport."""

    def __init__(self) -> None:
        self.transport = _Transport()


class _Agent:
    """What a PersonFace uses of an agent (services/runtime/person.py ``Interface``)."""

    def __init__(self) -> None:
        import logging

        self.engine = _Engine()
        self.log = logging.getLogger("a_desk")
        self.posted: list[object] = []
        self.emitted: list[tuple[str, bytes]] = []

    def post(self, event: object) -> None:
        self.posted.append(event)

    def emit(self, key: str, payload: bytes) -> None:
        self.emitted.append((key, payload))


def test_a_person_face_hears_lines_answers_them_and_keeps_the_outcomes(caplog: object) -> None:
    """Any agent (here not a_hi) hears the person's lines, tells reports and notices, and
    answers roco/human/outcomes with what it kept; what is too large or malformed is dropped
    before it is decoded, with a warning."""
    from services.runtime import keys
    from services.runtime.human import HumanInput
    from services.runtime.person import MAX_INPUT_BYTES, PersonFace

    agent = _Agent()
    face = PersonFace(agent)
    face.open()
    hear = agent.engine.transport.subscribed[keys.HUMAN_IN]
    line = HumanInput(text="sort the bolts", request_id="r1")
    hear(keys.HUMAN_IN, msgspec.json.encode(line))  # type: ignore[operator]
    hear(keys.HUMAN_IN, b"{not json")  # type: ignore[operator]
    hear(keys.HUMAN_IN, b'{"text": "' + b"x" * MAX_INPUT_BYTES + b'", "request_id": "r2"}')  # type: ignore[operator]
    assert agent.posted == [line]
    face.tell("r1", ReportKind.ACCEPTED, "sorting")
    face.tell("r1", ReportKind.SUCCEEDED, "sorted 3 bolts")
    face.notice("a_cv", "the belt jammed", severity="warning")
    said = [msgspec.json.decode(p, type=HumanReport) for k, p in agent.emitted if k == keys.HUMAN_OUT]
    assert [(r.kind, r.sender) for r in said] == [
        (ReportKind.ACCEPTED, ""),
        (ReportKind.SUCCEEDED, ""),
        (ReportKind.NOTICE, "a_cv"),
    ]
    answer = agent.engine.transport.served[keys.HUMAN_OUTCOMES]()  # type: ignore[operator]
    assert [r.text for r in msgspec.json.decode(answer, type=list[HumanReport])] == ["sorted 3 bolts"]
