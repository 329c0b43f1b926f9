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

What a publisher's cache no longer holds (a_hi died after telling, or told more than the cache
keeps) a tool asks a_hi for with :func:`ask_outcomes` when it has heard nothing of a request
for :data:`ASK_AFTER_S`: a_hi keeps the last final reports of commands across its restarts and
answers a query of ``roco/human/outcomes`` with them
(services/runtime/person.py).
"""

from __future__ import annotations

import datetime
import logging
import queue
import time
from collections import OrderedDict
from collections.abc import Callable, Collection
from typing import Any

import msgspec
import zenoh
import zenoh.ext as zext

from services.runtime import keys
from services.runtime.human import FINAL_REPORTS, HumanReport, ReportKind
from services.runtime.transport import CACHE_SAMPLES

log = logging.getLogger(__name__)

REASK_S = 1.0
"""Period (s) of a follower's queries to each publisher of reports it knows for the reports
after the last one it got."""
MAX_REPORT_BYTES = 64 * 1024
"""The largest report payload read (bytes); a larger one is dropped with a warning (a status
report has one line per command: a few kB)."""
MAX_OUTCOMES_BYTES = 256 * 1024
"""The largest answer of a_hi's outcomes queryable read (bytes); a larger one is dropped with a
warning (a_hi keeps at most 64 outcomes of at most 2,000 characters each)."""
ASK_AFTER_S = 10.0
"""Seconds without a report of a request still open after which a tool asks a_hi for its
outcome (:func:`ask_outcomes`), and again every as many seconds: a pour's progress reports
come every few seconds, so a longer silence means reports may have been missed."""
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


_outcomes_decode = msgspec.json.Decoder(list[HumanReport]).decode


def ask_outcomes(session: Any, request_ids: Collection[str], timeout: float = 2.0) -> list[HumanReport]:
    """Ask a_hi over ``session`` (a :class:`zenoh.Session`) for the outcomes it told; wait up
    to ``timeout`` s. The final reports of ``request_ids`` among them, in the order told; none
    when a_hi did not answer in time, or its answer was larger than
    :data:`MAX_OUTCOMES_BYTES` or malformed (a warning)."""
    wanted = set(request_ids)
    found: list[HumanReport] = []
    for reply in session.get(keys.HUMAN_OUTCOMES, timeout=timeout):
        if reply.ok is None:
            continue
        payload = reply.ok.payload.to_bytes()
        if len(payload) > MAX_OUTCOMES_BYTES:
            log.warning("dropped outcomes of %d bytes (at most %d read)", len(payload), MAX_OUTCOMES_BYTES)
            continue
        try:
            told = _outcomes_decode(payload)
        except (msgspec.DecodeError, msgspec.ValidationError) as exc:
            log.warning("dropped a malformed answer about outcomes: %s", exc)
            continue
        found.extend(r for r in told if r.request_id in wanted and r.kind in FINAL_REPORTS)
    return found


class MissedOutcomes:
    """When a tool asks a_hi for outcomes it may have missed (:func:`ask_outcomes`): after
    :data:`ASK_AFTER_S` without a report of its open requests, then every as many seconds.
    Call :meth:`heard` on each report of one of them; not thread-safe (one thread)."""

    def __init__(self, session: Any, after_s: float = ASK_AFTER_S) -> None:
        self._session = session
        self._after = after_s
        self._last = time.monotonic()

    def heard(self) -> None:
        """A report of an open request came: the silence starts again."""
        self._last = time.monotonic()

    def due_in(self) -> float:
        """Seconds until the next ask (0: due now)."""
        return max(0.0, self._last + self._after - time.monotonic())

    def ask_if_due(self, request_ids: Collection[str]) -> list[HumanReport]:
        """The final reports of ``request_ids`` a_hi still keeps, when an ask is due and some
        request is open (blocks up to 2 s for a_hi's answer); else none."""
        if not request_ids or self.due_in() > 0:
            return []
        self._last = time.monotonic()
        return ask_outcomes(self._session, request_ids)


def next_report(
    reports: queue.SimpleQueue[HumanReport],
    request_id: str,
    shown: ReportFilter,
    missed: MissedOutcomes,
    deadline: float,
    notices: Callable[[HumanReport], None] | None = None,
) -> HumanReport | None:
    """The next report of ``request_id`` to show, from ``reports`` (what :func:`follow_reports`
    hands on), skipping other requests' and those ``shown`` filters out; a ``notice`` (an
    agent tells the person something, of no request) is handed to ``notices`` meanwhile (None:
    skipped). When ``missed`` says the silence has lasted (other requests' reports may still
    flow), a_hi is asked for the outcome meanwhile. None past ``deadline``
    (``time.monotonic()``)."""
    while (left := deadline - time.monotonic()) > 0:
        for told in missed.ask_if_due([request_id]):  # a long silence of this request's reports
            reports.put(told)
        try:
            report = reports.get(timeout=max(0.05, min(left, missed.due_in())))
        except queue.Empty:
            continue
        if report.kind is ReportKind.NOTICE:
            if notices is not None:
                notices(report)
            continue
        if report.request_id == request_id and shown.keep(report):
            missed.heard()
            return report
    return None
