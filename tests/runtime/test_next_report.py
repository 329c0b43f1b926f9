"""`next_report` (services/runtime/reports.py) asks a_hi for a request's outcome once that
request's reports have been silent for the ask period, even while other requests' reports keep
coming (a busy fleet): the silence is this request's, not the queue's."""

from __future__ import annotations

import queue
import time
from dataclasses import dataclass, field
from typing import Any

import msgspec

from services.runtime import keys
from services.runtime.human import HumanReport, ReportKind
from services.runtime.reports import MissedOutcomes, ReportFilter, next_report
from tests.support.zenoh_sample import sample

OUTCOME = HumanReport(
    request_id="mine", kind=ReportKind.SUCCEEDED, text="pour the jar into the bowl: succeeded"
)


class _Busy(queue.SimpleQueue[HumanReport]):
    """A queue of reports that always holds another person's progress report first."""

    def get(self, block: bool = True, timeout: float | None = None) -> HumanReport:
        if not self.empty():
            return super().get(block, timeout)
        return HumanReport(request_id="theirs", kind=ReportKind.PROGRESS, text="running")


@dataclass
class _Reply:
    ok: Any


@dataclass
class _Session:
    """a_hi's outcomes queryable: it kept the outcome this session missed."""

    asked: list[str] = field(default_factory=list)

    def get(self, key: str, timeout: float) -> list[_Reply]:
        self.asked.append(key)
        return [_Reply(sample(msgspec.json.encode([OUTCOME])))]


def test_the_outcome_is_asked_for_while_other_requests_reports_keep_coming() -> None:
    session = _Session()
    got = next_report(
        _Busy(), "mine", ReportFilter(), MissedOutcomes(session, after_s=0.2), time.monotonic() + 5
    )
    assert got == OUTCOME and session.asked == [keys.HUMAN_OUTCOMES]


def test_a_notice_is_handed_on_while_the_request_s_reports_are_awaited() -> None:
    """A notice answers no request: it goes to ``notices`` (``roco send`` prints it with its
    sender) and the wait for the request's report goes on."""
    reports: queue.SimpleQueue[HumanReport] = queue.SimpleQueue()
    notice = HumanReport(request_id="", kind=ReportKind.NOTICE, text="the jar tipped over", sender="a_wt")
    reports.put(notice)
    reports.put(OUTCOME)
    told: list[HumanReport] = []
    got = next_report(
        reports, "mine", ReportFilter(), MissedOutcomes(_Session()), time.monotonic() + 5, told.append
    )
    assert got == OUTCOME and told == [notice]
