"""a_co's command queue in the Rerun recording (a_co's own part, process name ``a_co``).

Entities (timeline ``wall``, POSIX s, shared with the traffic and the robot):

- ``task/queue`` — ``TextDocument`` (Markdown): one table row per command a_co holds and has
  not ended, the one on a_ta first, then in the order of acceptance: request (the C2
  conversation-id), command text, priority, deadline (s left when the row was logged, or
  "—"), state (``running``, ``terminating``, ``waiting``, ``planning``, ``preempted``:
  services/agents/coordinator/agent.py, L_HC ``TaskState``); "*empty*" when nothing is left;
- ``task/queue/length`` — ``Scalars``: the number of rows.

Both are logged only when the queue changes: a command arrives, ends, or changes state (a
new step of the running plan is not a change of the queue; a_ta's steps are ``task/step``).
"""

from __future__ import annotations

import time

import rerun as rr

from services.viewer.recording import Recording
from shared.fipa_codec.languages.l_hc import Status, TaskState, TaskStatus

WALL = "wall"
QUEUE = "task/queue"
LENGTH = "task/queue/length"
ENDED = frozenset({TaskState.SUCCEEDED, TaskState.FAILED, TaskState.STOPPED})

Row = tuple[str, str, int, str]  # request, text, priority, state: what makes a change


def _cell(text: str) -> str:
    """``text`` safe inside a Markdown table cell."""
    return text.replace("|", "\\|").replace("\n", " ")


def queue_rows(status: Status) -> list[TaskStatus]:
    """The commands of ``status`` that have not ended, in its order."""
    return [t for t in status.tasks if t.state not in ENDED]


def markdown(rows: list[TaskStatus]) -> str:
    """The queue as a Markdown table (see module docstring)."""
    if not rows:
        return "*empty*"
    lines = ["| request | command | priority | deadline | state |", "|---|---|---:|---:|---|"]
    for t in rows:
        deadline = f"{t.deadline_in_s:.0f} s" if t.deadline_in_s is not None else "—"
        lines.append(
            f"| {_cell(t.command_id)} | {_cell(t.text)} | {t.priority} | {deadline} | {t.state.value} |"
        )
    return "\n".join(lines)


class QueueLogger:
    """Logs a_co's queue to one recording part when it changed (see module docstring)."""

    def __init__(self, recording: Recording) -> None:
        self.stream = recording.stream
        self._last: tuple[Row, ...] | None = None
        self.logged = 0  # rows logged (for tests)

    def queue(self, status: Status, *, wall: float | None = None) -> bool:
        """Log the queue in ``status`` (a_co's ``Status``) at wall time ``wall`` (POSIX s,
        default now) unless it equals the last one logged; returns whether it was logged."""
        rows = queue_rows(status)
        key = tuple((t.command_id, t.text, t.priority, t.state.value) for t in rows)
        if key == self._last:
            return False
        self._last = key
        s = self.stream
        s.set_time(WALL, timestamp=time.time() if wall is None else wall)
        s.log(QUEUE, rr.TextDocument(markdown(rows), media_type=rr.MediaType.MARKDOWN))
        s.log(LENGTH, rr.Scalars(float(len(rows))))
        self.logged += 1
        return True
