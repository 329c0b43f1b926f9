"""What crosses a_hi's receptor and effector (not FIPA: the person's side of the interface).

``roco/human/in`` carries :class:`HumanInput` (JSON); ``roco/human/out`` carries
:class:`HumanReport` (JSON). a_hi speaks them, and so do the person's tools (``roco send``,
``roco run``, the scenario runner), which therefore need nothing of a_hi's internals: the
runtime keeps the format, beside the keys (services/runtime/keys.py).
"""

from __future__ import annotations

import enum

import msgspec

MAX_LINE_CHARS = 1000
"""The longest ``HumanInput.text`` a_hi reads, in characters (str length): a longer line is
refused with one ``not-understood`` report, except that a stop in it is still acted on."""


NOTICES_PER_S = 5
"""The most notices of one sender a_hi passes on to the person in a second (the rest it counts,
``notices_dropped``, and drops: services/agents/human_interface/notices.py)."""


class HumanInput(msgspec.Struct, frozen=True, kw_only=True):
    """A sentence from a person; ``request_id`` lets the sender match the reports. ``text``
    is read when at most :data:`MAX_LINE_CHARS` characters long. ``priority`` > 0 overrides the
    priority the sentence's urgency words give. ``person`` names who speaks (a_hi keeps a
    conversation per person: "it", questions and answers); empty: the one anonymous person."""

    text: str
    request_id: str
    priority: int = 0
    person: str = ""


class ReportKind(enum.StrEnum):
    """What a :class:`HumanReport` says about its request.

    For a command: ``accepted`` (a_co agreed), any number of ``progress`` (a_co's state
    changes), then one final kind: ``succeeded``, ``failed``, ``stopped`` (ended by a stop
    request) — or ``not-understood`` at once. For a stop request ("stop"): ``progress``
    (which commands are being stopped), then ``stopped`` (all stopped, or nothing was
    running) or ``failed`` (some could not be stopped). For a status request ("what are you
    doing?"): ``status``, one line per command. For a question ("what is in the bowl?"):
    ``answer``, one sentence. ``notice``: no request of the person's; an agent tells the person
    something unprompted (its ``sender``; a notice protocol such as ``roco-notify``:
    services/spec/notices.py).
    """

    ACCEPTED = "accepted"
    PROGRESS = "progress"
    STATUS = "status"
    ANSWER = "answer"
    NOT_UNDERSTOOD = "not-understood"
    SUCCEEDED = "succeeded"
    FAILED = "failed"
    STOPPED = "stopped"
    NOTICE = "notice"


class RequestKind(enum.StrEnum):
    """What a_hi understood a sentence to be."""

    COMMAND = "command"
    STOP = "stop"
    STATUS = "status"
    QUESTION = "question"


class HumanReport(msgspec.Struct, frozen=True, kw_only=True):
    """What a_hi tells the person about request ``request_id`` (``text``: readable
    sentences; a status report has one line per command). ``request``: what a_hi understood
    the sentence to be (None: not understood, or a command a_hi restored after its restart).
    A ``notice`` answers no request (``request_id`` empty): ``sender`` names the agent that
    said it, ``severity`` is the L_HC ``Notice``'s (``info``, ``warning``, ``alarm``) and
    ``about`` the things it names (both empty for another term: its ``text`` is what the term
    says, shared/fipa_codec/languages/told.py)."""

    request_id: str
    kind: ReportKind
    text: str
    request: RequestKind | None = None
    sender: str = ""
    severity: str = ""
    about: tuple[str, ...] = ()

    @property
    def notice_line(self) -> str:
        """The notice as one line for the person: ``notice from a_wt (warning, about jar):
        the jar tipped over``."""
        what = ", ".join(filter(None, (self.severity, f"about {' '.join(self.about)}" if self.about else "")))
        return f"notice from {self.sender or 'an agent'}{f' ({what})' if what else ''}: {self.text}"

    @property
    def done_as_asked(self) -> bool:
        """A final report that means the request was carried out: ``succeeded`` for a command
        (also when ``request`` is None), ``stopped`` for a stop request, ``status`` for a status
        request, ``answer`` for a question."""
        wanted = {
            RequestKind.STOP: ReportKind.STOPPED,
            RequestKind.STATUS: ReportKind.STATUS,
            RequestKind.QUESTION: ReportKind.ANSWER,
        }
        return self.kind is wanted.get(self.request or RequestKind.COMMAND, ReportKind.SUCCEEDED)


FINAL_REPORTS = frozenset(
    {
        ReportKind.NOT_UNDERSTOOD,
        ReportKind.SUCCEEDED,
        ReportKind.FAILED,
        ReportKind.STOPPED,
        ReportKind.STATUS,
        ReportKind.ANSWER,
    }
)
"""Kinds after which no more reports come for a request: for a command, the command has
ended (not understood, succeeded, failed, stopped); ``status`` only ever ends a status
request, ``answer`` a question."""
