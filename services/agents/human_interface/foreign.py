"""a_hi's answers to agents of other FIPA platforms (C8; docs/gateway.md).

They reach a_hi through ``roco gateway``; a_hi is the participant of their fipa-request. The
``request`` carries a ``Sentence``, which a_hi reads exactly as a person's line (a
conversation per foreign agent, in the order the sentences came), and the reports the person
would get become the answers, each a ``SentenceReport``: ``accepted`` an ``agree``, a final
report an ``inform`` when the request was done as asked, else a ``failure`` — or a ``refuse``
when the sentence was not understood (before any agree). Progress reports are not sent
(fipa-request has none), nor anything in a request the foreign agent ended with
not-understood. A foreign agent may ``cancel`` its request (FIPA SC00026 §2): what of it is
under way is stopped as by a person's stop, and the cancel is answered once that is settled:
``inform`` when it stopped (or was dropped before it was acted on), ``failure`` when it ended
otherwise or nothing of it was under way. These conversations are not kept across a restart
of a_hi.
"""

from __future__ import annotations

import logging
from collections.abc import Callable

from services.runtime.agent import FINAL_REPORTS, HumanInput, HumanReport, Received, ReportKind, SpecViolation
from services.runtime.roles import Conversation
from shared.fipa_codec import Performative
from shared.fipa_codec.languages.l_hc import Sentence, SentenceReport


class ForeignRequests:
    """The open fipa-requests of foreign agents, by the request id a_hi reads each sentence
    under (module docstring); ``log``: a_hi's; ``new_id``: a_hi's source of identifiers
    (services/runtime/sources.py)."""

    def __init__(self, log: logging.Logger, new_id: Callable[[str], str]) -> None:
        self.log = log
        self.new_id = new_id
        self.open: dict[str, Conversation] = {}
        self.cancels: dict[str, Received] = {}
        """The foreign agents' cancels still to be answered, by request id."""

    def take(self, conv: Conversation) -> HumanInput:
        """A foreign agent's ``request`` (its ``Sentence``: the specification's content,
        checked on arrival) as the line a person of the agent's name says, under a new
        request id whose reports answer it."""
        said = conv.content
        assert isinstance(said, Sentence)
        request_id = self.new_id("fipa-")
        self.open[request_id] = conv
        self.log.info("sentence from %s [%s]: %s", conv.peer, request_id, said.text)
        return HumanInput(text=said.text, request_id=request_id, person=conv.peer)

    def cancelling(self, conv: Conversation) -> str | None:
        """The request id of the request a foreign agent cancels in ``conv`` (while its cancel
        handler runs), its cancel kept to be answered; None when a_hi has no such request open
        (the cancel is then answered ``failure`` at once)."""
        request_id = next((r for r, c in self.open.items() if c is conv), None)
        cancel = conv.to_answer
        if request_id is None or cancel is None:
            conv.answer_cancel(
                False, SentenceReport(kind=ReportKind.FAILED.value, text="no request of yours is open")
            )
            return None
        self.cancels[request_id] = cancel
        self.log.info("%s cancels its request [%s]", conv.peer, request_id)
        return request_id

    def nothing_to_cancel(self, request_id: str) -> None:
        """Nothing of request ``request_id`` is under way: its cancel is answered ``failure``
        and the request goes on to its end as it would have."""
        conv, cancel = self.open.get(request_id), self.cancels.pop(request_id, None)
        if conv is not None and cancel is not None:
            text = "nothing of it is under way to stop"
            conv.answer_cancel(False, SentenceReport(kind=ReportKind.FAILED.value, text=text), to=cancel)

    def answer(self, report: HumanReport) -> None:
        """Answer the foreign request ``report`` is about, if any, with what the person is told
        (module docstring); a progress report is not sent."""
        conv = self.open.get(report.request_id)
        if conv is None:
            return
        if conv.finished:  # the foreign agent ended it (not-understood, FIPA SC00037 §3.12)
            del self.open[report.request_id]
            self.log.info("%s's request [%s] has ended: not answered", conv.peer, report.request_id)
            return
        if report.request_id in self.cancels and self._answer_cancel(conv, report):
            return
        performative: Performative | None = None
        requested = conv.state == "requested"  # fipa-request: not agreed yet
        if report.kind is ReportKind.ACCEPTED and requested:
            performative = Performative.AGREE
        elif report.kind in FINAL_REPORTS:
            del self.open[report.request_id]
            if report.kind is ReportKind.NOT_UNDERSTOOD and requested:
                performative = Performative.REFUSE
            else:
                performative = Performative.INFORM if report.done_as_asked else Performative.FAILURE
        if performative is None:
            return
        try:
            conv.reply(performative, SentenceReport(kind=report.kind.value, text=report.text))
        except SpecViolation as exc:  # e.g. the foreign agent cancelled it meanwhile
            self.log.warning("cannot answer %s's request [%s]: %s", conv.peer, report.request_id, exc)

    def _answer_cancel(self, conv: Conversation, report: HumanReport) -> bool:
        """Answer the cancel still to be answered of the request ``report`` is about, once it
        ends (FIPA SC00026 §2): ``inform`` when it stopped or was dropped unread (the request
        ends with it), else ``failure``, and the request is then answered as usual. Whether the
        request is settled (also: not yet ended, when nothing is sent: no agree after a cancel)."""
        if report.kind not in FINAL_REPORTS:
            return True
        cancel = self.cancels.pop(report.request_id)
        cancelled = report.kind in (ReportKind.STOPPED, ReportKind.NOT_UNDERSTOOD)
        if cancelled:
            del self.open[report.request_id]
        try:
            conv.answer_cancel(cancelled, SentenceReport(kind=report.kind.value, text=report.text), to=cancel)
        except SpecViolation as exc:
            self.log.warning("cannot answer %s's cancel [%s]: %s", conv.peer, report.request_id, exc)
        return cancelled
