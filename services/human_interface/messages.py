"""What crosses a_hi's receptor and effector (not FIPA: the person's side of the interface).

``roco/human/in`` carries :class:`HumanInput` (JSON); ``roco/human/out`` carries
:class:`HumanReport` (JSON). ``roco send`` and ``roco run`` speak these.
"""

from __future__ import annotations

import enum

import msgspec


class HumanInput(msgspec.Struct, frozen=True, kw_only=True):
    """A sentence from a person; ``request_id`` lets the sender match the reports."""

    text: str
    request_id: str
    priority: int = 0


class ReportKind(enum.StrEnum):
    ACCEPTED = "accepted"
    NOT_UNDERSTOOD = "not-understood"
    SUCCEEDED = "succeeded"
    FAILED = "failed"


class HumanReport(msgspec.Struct, frozen=True, kw_only=True):
    """What a_hi tells the person about request ``request_id``."""

    request_id: str
    kind: ReportKind
    text: str


FINAL_REPORTS = frozenset({ReportKind.NOT_UNDERSTOOD, ReportKind.SUCCEEDED, ReportKind.FAILED})
