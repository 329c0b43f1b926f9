"""L_HC: what a_hi and a_co say on C2 (paper §5.2).

- fipa-request (a_hi initiates): a :class:`HumanCommand`; a_co agrees, and ends with a
  :class:`CommandOutcome` in ``inform`` (done) or ``failure``/``refuse``. a_hi stops a
  command with ``cancel`` in its conversation; a_co answers ``inform`` with the outcome
  ("stopped") once the robot is in a safe state.
- fipa-subscribe (a_hi initiates): a :class:`ProgressSubscription`; a_co agrees and informs a
  :class:`Progress` at every change of a command's state.
- fipa-query (a_hi initiates): ``query-ref`` of a :class:`StatusQuery` ("what are you
  doing?"); a_co answers ``inform-ref`` with a :class:`Status`.

On C8, an agent of another FIPA platform asks a_hi as a person would: fipa-request
(the foreign agent initiates) of a :class:`Sentence`; a_hi answers with
:class:`SentenceReport` s: ``agree`` (a command was accepted), then ``inform`` (done as asked:
succeeded, stopped for a stop request, the status for a status request) or ``failure``;
``refuse`` when it does not understand the sentence.

Any agent the specification gives a channel to a_hi with the ``roco-notify`` protocol, or
another notice protocol (one ``inform``, nothing answers; inform: FIPA SC00037;
services/spec/notices.py), tells the person something unprompted with a :class:`Notice` (who
said it is the communicate's sender), or with a term of its own that says itself
(shared/fipa_codec/languages/told.py).
"""

from __future__ import annotations

import enum
from typing import Annotated

import msgspec

from shared.fipa_codec.languages.base import Language, register
from shared.fipa_codec.languages.common import CLOCK

CONTENT_SHARE_REQUIRED = 0.9
"""Share of the content that must end in the target for a pour ("pour X into Y") to count as
done: the planner's goal, the plan's content check a_ta runs, and ``roco chaos``'s judgement
of the world all ask it."""


class TaskAtom(msgspec.Struct, frozen=True, array_like=True):
    """A task in a ground task network: ``name`` and object arguments, e.g. ("pour", ("jar", "bowl"))."""

    name: str
    args: tuple[str, ...] = ()


class HumanCommand(msgspec.Struct, frozen=True, tag="command", kw_only=True):
    """An interpreted human command. ``text`` is what the person said; ``goal`` the task it
    names; ``priority`` larger is more urgent; ``deadline_s`` seconds from acceptance."""

    text: str
    goal: TaskAtom
    priority: int = 0
    deadline_s: float | None = None


class CommandOutcome(msgspec.Struct, frozen=True, tag="outcome", kw_only=True):
    """How a command ended: ``succeeded`` and a one-line ``detail`` for the person."""

    command_id: str
    succeeded: bool
    detail: str = ""


class TaskState(enum.StrEnum):
    """Where a command stands in a_co (paper Table 3)."""

    WAITING = "waiting"
    """accepted, waiting for a plan or for the robot"""
    PLANNING = "planning"
    RUNNING = "running"
    TERMINATING = "terminating"
    """cancelled or preempted; the robot is reaching a safe state"""
    PREEMPTED = "preempted"
    """interrupted for a more urgent command; resumed later"""
    SUCCEEDED = "succeeded"
    FAILED = "failed"
    STOPPED = "stopped"


class ProgressSubscription(msgspec.Struct, frozen=True, tag="progress_subscription"):
    """a_hi's fipa-subscribe to a_co: inform a :class:`Progress` at every change."""


class Progress(msgspec.Struct, frozen=True, tag="progress", kw_only=True):
    """Command ``command_id`` (its C2 conversation-id) is now in ``state``; ``step`` names the
    plan's HFSM state being executed (``pour(jar,bowl)/fetch_jar/grasp``), ``detail`` says
    why in words a person can read."""

    command_id: str
    state: TaskState
    step: str | None = None
    detail: str = ""


class StatusQuery(msgspec.Struct, frozen=True, tag="status_query"):
    """ "What are you doing?": the state of every command a_co holds."""


class TaskStatus(msgspec.Struct, frozen=True, kw_only=True):
    """One command in a :class:`Status`: its ``text``, ``state``, current ``step``,
    ``priority`` and seconds left to its deadline (``deadline_in_s``, negative when missed)."""

    command_id: str
    text: str
    state: TaskState
    step: str | None = None
    priority: int = 0
    deadline_in_s: Annotated[float, CLOCK] | None = None


class Status(msgspec.Struct, frozen=True, tag="status", kw_only=True):
    """a_co's answer to a :class:`StatusQuery`: every command it holds, the running one first."""

    tasks: tuple[TaskStatus, ...] = ()


class Sentence(msgspec.Struct, frozen=True, tag="sentence", kw_only=True):
    """What a person would say to the robot (``text``), sent by an agent of another FIPA
    platform (C8)."""

    text: str


class SentenceReport(msgspec.Struct, frozen=True, tag="sentence_report", kw_only=True):
    """a_hi's report on a :class:`Sentence`: ``kind`` is what a person would be told
    (``accepted``, ``not-understood``, ``succeeded``, ``failed``, ``stopped``, ``status``, ``answer``:
    services/runtime/human.py ``ReportKind``), ``text`` the readable sentences."""

    kind: str
    text: str


MAX_NOTICE_CHARS = 500
"""The longest :attr:`Notice.text`, in characters (str length)."""
MAX_NOTICE_ABOUT = 16
"""The most names :attr:`Notice.about` holds; each at most :data:`MAX_NOTICE_NAME_CHARS`."""
MAX_NOTICE_NAME_CHARS = 100


class Severity(enum.StrEnum):
    """How much a :class:`Notice` asks of the person."""

    INFO = "info"
    """worth knowing"""
    WARNING = "warning"
    """worth looking at (something tipped over)"""
    ALARM = "alarm"
    """worth acting on at once"""


class Notice(msgspec.Struct, frozen=True, tag="notice", kw_only=True):
    """Something an agent tells the person unprompted (protocol ``roco-notify``): ``text`` in words
    a person reads (1 to :data:`MAX_NOTICE_CHARS` characters), its ``severity``, and the
    kitchen's things it is ``about`` (O_RoCo names, e.g. ``("jar",)``; at most
    :data:`MAX_NOTICE_ABOUT`). A term outside these bounds does not decode (ContentError), and
    its receiver answers it ``not-understood``."""

    text: Annotated[str, msgspec.Meta(min_length=1, max_length=MAX_NOTICE_CHARS)]
    severity: Severity = Severity.INFO
    about: Annotated[
        tuple[Annotated[str, msgspec.Meta(min_length=1, max_length=MAX_NOTICE_NAME_CHARS)], ...],
        msgspec.Meta(max_length=MAX_NOTICE_ABOUT),
    ] = ()

    def told(self) -> str:
        """What the notice tells the person: its ``text`` (the hook of
        shared/fipa_codec/languages/told.py)."""
        return self.text


L_HC = register(
    Language(
        "L_HC",
        "O_RoCo",
        (
            HumanCommand,
            CommandOutcome,
            ProgressSubscription,
            Progress,
            StatusQuery,
            Status,
            Sentence,
            SentenceReport,
            Notice,
        ),
    )
)
