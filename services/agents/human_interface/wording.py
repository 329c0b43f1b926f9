"""What a_hi tells the person, in words: the text of its reports (services/runtime/human.py
:class:`HumanReport`; docs/agents.md, "a_hi").

Pure functions of L_HC terms and of labels (a command as a_hi names it back, language.py
``describe``: "pour the jar into the bowl"); no state, no I/O.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from services.runtime.agent import MAX_LINE_CHARS
from services.runtime.roles import Conversation
from shared.fipa_codec.languages.l_hc import (
    CommandOutcome,
    HumanCommand,
    Progress,
    Status,
    TaskState,
    TaskStatus,
)

_CONNECTIVES = frozenset(
    {"for", "by", "because", "after", "before", "while", "since", "until", "as", "so", "with", "to"}
)
_AT_STEP = frozenset({TaskState.RUNNING, TaskState.TERMINATING, TaskState.PREEMPTED})
"""States in which the plan's step says where the robot is (elsewhere it is a stale one)."""

NOTHING_TO_STOP = "Nothing is running, so there is nothing to stop."
NOTHING_DONE = "I am not doing anything: no command is running or waiting."


def sentence(label: str, word: str, detail: str = "") -> str:
    """``label: word`` followed by ``detail`` readably: "pour the jar into the bowl:
    stopped; the jar was put down on the table", "…: preempted for 'bring the cup …'"."""
    detail = " ".join(detail.split())
    if not detail:
        return f"{label}: {word}"
    if detail.lower().startswith(word.lower()):
        return f"{label}: {detail}"
    if detail.split()[0].lower() in _CONNECTIVES:
        return f"{label}: {word} {detail}"
    return f"{label}: {word}; {detail}"


def state_words(state: TaskState, step: str | None) -> str:
    """ "running pour(jar,bowl)/fetch_jar/grasp", "planning", …"""
    return f"{state.value} {step}" if step and state in _AT_STEP else state.value


def progress_text(label: str, progress: Progress) -> str:
    """A :class:`Progress` as a sentence ("…: running pour(jar,bowl)/fetch_jar/grasp")."""
    return sentence(label, state_words(progress.state, progress.step), progress.detail)


def status_line(label: str, task: TaskStatus) -> str:
    """One line of a status report: a command, its state and step, priority, deadline."""
    parts = [state_words(task.state, task.step)]
    if task.priority:
        parts.append(f"priority {task.priority}")
    if task.deadline_in_s is not None:
        if task.deadline_in_s >= 0:
            parts.append(f"{task.deadline_in_s:.0f} s left to its deadline")
        else:
            parts.append(f"deadline missed by {-task.deadline_in_s:.0f} s")
    return f"{label}: {', '.join(parts)}"


def status_text(status: Status, labels: Mapping[str, str]) -> str:
    """a_co's :class:`Status` as the person's status report, a line per command (named by
    ``labels``, command id → label, else by its text)."""
    if not status.tasks:
        return NOTHING_DONE
    return "\n".join(status_line(labels.get(t.command_id, repr(t.text)), t) for t in status.tasks)


def no_status(reason: str, known: Sequence[str]) -> str:
    """The status report when a_co gave none (``reason``): what a_hi knows, a line per open
    command (:func:`last_known`)."""
    mine = "\n".join(known) if known else "no command of mine is open."
    return f"a_co did not tell me its status ({reason}); from its last reports:\n{mine}"


def last_known(label: str, last: Progress | None, agreed: bool) -> str:
    """A command as a_co last reported it (``last``), or as sent or accepted."""
    return progress_text(label, last) if last else f"{label}: {'accepted' if agreed else 'sent'}"


def accepted(label: str, command: HumanCommand) -> str:
    """ "I will pour the jar into the bowl (priority 5, within 120 s)." """
    extras = []
    if command.priority:
        extras.append(f"priority {command.priority}")
    if command.deadline_s is not None:
        extras.append(f"within {command.deadline_s:g} s")
    more = f" ({', '.join(extras)})" if extras else ""
    return f"I will {label}{more}."


def stopping(labels: Sequence[str], named: str = "") -> str:
    """What a stop report says it stops (every open command, also when the person's stop
    ``named`` one activity, "pouring")."""
    n = len(labels)
    every = f" (I stop every open command, not only '{named}')" if named else ""
    return f"Stopping {n} command{'s' if n > 1 else ''}: {'; '.join(labels)}{every}."


def dropped(text: str) -> str:
    """A line dropped because the person said stop before it was read."""
    return f"'{text}' was dropped: you said stop before I had read it."


def too_long(chars: int) -> str:
    """A line of ``chars`` characters, over ``MAX_LINE_CHARS``, refused."""
    return (
        f"Your line has {chars:,} characters; I read lines of at most "
        f"{MAX_LINE_CHARS:,}: please say it in fewer words."
    )


def reason_of(conv: Conversation) -> str:
    """Why the peer of ``conv`` (a_co, a_km) answered negatively or not at all, in words: the
    detail of a_co's :class:`CommandOutcome`, else :attr:`Conversation.explanation`."""
    if not conv.timed_out and isinstance(conv.content, CommandOutcome):
        return conv.content.detail or "no reason given"
    return conv.explanation
