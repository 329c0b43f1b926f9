"""The person's side of a_hi's effector: follow a_hi's reports (``roco/human/out``) through
router outages and reconnections, each request's final report taken once.

a_hi puts its reports through a zenoh-ext advanced publisher that keeps the last
``transport.CACHE_SAMPLES`` of them (services/runtime/transport.py). A person's tool (``roco
send``, the scenario runner behind ``roco run``) follows them with :func:`follow_reports`, a
zenoh-ext advanced subscriber that

- asks every publisher of reports for what its cache holds when the subscriber starts and
  whenever a publisher's liveliness token appears to it: after its session reconnects (the
  router restarted), a_hi's token appears again and the reports put meanwhile come then;
- asks each publisher it knows, every :data:`REASK_S`, for the reports after the last one it got
  (zenoh-ext periodic queries): a report missed in any other way comes within that period once
  the session reaches a_hi again.

zenoh-ext delivers each publisher's reports once and in order of sequence number;
:class:`ReportFilter` also drops a request's reports after its final one (a restarted a_hi
telling a command's outcome again), so an outcome is shown once.
"""

from __future__ import annotations

import datetime
import logging
from collections import OrderedDict
from collections.abc import Callable

import msgspec
import zenoh
import zenoh.ext as zext

from services.runtime import keys
from services.runtime.human import FINAL_REPORTS, HumanReport
from services.runtime.transport import CACHE_SAMPLES

log = logging.getLogger(__name__)

REASK_S = 1.0
"""Period (s) of a follower's queries to each publisher of reports it knows for the reports
after the last one it got."""
MAX_REPORT_BYTES = 64 * 1024
"""The largest report payload read (bytes); a larger one is dropped with a warning (a status
report has one line per command: a few kB)."""
MAX_ENDED = 4096
"""Requests whose final report a :class:`ReportFilter` remembers (the oldest forgotten first)."""


class ReportFilter:
    """Which reports to show: all of a request's reports up to and including its first final
    one (services/runtime/human.py ``FINAL_REPORTS``), none after it. Remembers the last
    :data:`MAX_ENDED` ended requests. Not thread-safe: call from one thread."""

    def __init__(self, max_ended: int = MAX_ENDED) -> None:
        if max_ended < 1:
            raise ValueError(f"max_ended must be ≥ 1, not {max_ended}")
        self._ended: OrderedDict[str, None] = OrderedDict()
        self._max = max_ended

    def keep(self, report: HumanReport) -> bool:
        """Whether ``report`` is shown: False once its request has had its final report."""
        if report.request_id in self._ended:
            return False
        if report.kind in FINAL_REPORTS:
            self._ended[report.request_id] = None
            if len(self._ended) > self._max:
                self._ended.popitem(last=False)
        return True


def decode_report(payload: bytes) -> HumanReport | None:
    """The report in ``payload`` (JSON :class:`HumanReport`); None, with a warning, when it is
    larger than :data:`MAX_REPORT_BYTES` or malformed."""
    if len(payload) > MAX_REPORT_BYTES:
        log.warning("dropped a report of %d bytes (at most %d read)", len(payload), MAX_REPORT_BYTES)
        return None
    try:
        return msgspec.json.decode(payload, type=HumanReport)
    except msgspec.DecodeError as exc:
        log.warning("dropped a malformed report: %s", exc)
        return None


def follow_reports(
    session: zenoh.Session, callback: Callable[[HumanReport], None]
) -> zext.AdvancedSubscriber:
    """Call ``callback`` with every report a_hi puts on ``roco/human/out`` (see the module
    docstring), those its cache still holds first, on Zenoh's thread (``callback`` must only
    hand the report on). Reports are not filtered here (:class:`ReportFilter`). The subscriber
    ends with ``session`` or its ``undeclare()``. Raises zenoh.ZError when Zenoh refuses the
    declaration."""

    def on_sample(sample: zenoh.Sample) -> None:
        report = decode_report(sample.payload.to_bytes())
        if report is not None:
            callback(report)

    return zext.declare_advanced_subscriber(
        session,
        keys.HUMAN_OUT,
        on_sample,
        history=zext.HistoryConfig(detect_late_publishers=True, max_samples=CACHE_SAMPLES),
        # zenoh-python 1.x takes a timedelta here (a float raises TypeError); its stub says float
        recovery=zext.RecoveryConfig(
            periodic_queries=datetime.timedelta(seconds=REASK_S),  # type: ignore[arg-type]
            heartbeat=None,
        ),
    )
