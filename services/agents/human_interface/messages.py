"""What crosses a_hi's receptor and effector (not FIPA: the person's side of the interface).

``roco/human/in`` carries :class:`HumanInput` (JSON); ``roco/human/out`` carries
:class:`HumanReport` (JSON). ``roco send`` and ``roco run`` speak these.
"""

from __future__ import annotations

import enum

import msgspec


class HumanInput(msgspec.Struct, frozen=True, kw_only=True):
    """A sentence from a person; ``request_id`` lets the sender match the reports.
    ``priority`` > 0 overrides the priority the sentence's urgency words give."""

    text: str
    request_id: str
    priority: int = 0


class ReportKind(enum.StrEnum):
    """What a :class:`HumanReport` says about its request.

    For a command: ``accepted`` (a_co agreed), any number of ``progress`` (a_co's state
    changes), then one final kind: ``succeeded``, ``failed``, ``stopped`` (ended by a stop
    request) — or ``not-understood`` at once. For a stop request ("stop"): ``progress``
    (which commands are being stopped), then ``stopped`` (all stopped, or nothing was
    running) or ``failed`` (some could not be stopped). For a status request ("what are you
    doing?"): ``status``, one line per command.
    """

    ACCEPTED = "accepted"
    PROGRESS = "progress"
    STATUS = "status"
    NOT_UNDERSTOOD = "not-understood"
    SUCCEEDED = "succeeded"
    FAILED = "failed"
    STOPPED = "stopped"


class HumanReport(msgspec.Struct, frozen=True, kw_only=True):
    """What a_hi tells the person about request ``request_id`` (``text``: readable
    sentences; a status report has one line per command)."""

    request_id: str
    kind: ReportKind
    text: str


FINAL_REPORTS = frozenset(
    {
        ReportKind.NOT_UNDERSTOOD,
        ReportKind.SUCCEEDED,
        ReportKind.FAILED,
        ReportKind.STOPPED,
        ReportKind.STATUS,
    }
)
"""Kinds after which no more reports come for a request: for a command, the command has
ended (not understood, succeeded, failed, stopped); ``status`` only ever ends a status
request."""
