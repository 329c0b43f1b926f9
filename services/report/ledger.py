"""ag_ex's ledger of executed commands (velma/executor/ledger.py) held against the traffic
record: did the robot run a command twice, or was a command answered done that never ran?
Read by `roco chaos`'s "nothing executed twice" question (services/scenario/chaos.py) and the
run report's header.

- **Executed twice**: a conversation-id whose command the loop started more than once, unless
  each start but the last was *interrupted*: its ag_ex stopped under it (no ``end`` line in
  that ag_ex's life, or the ``end`` of a stopping loop, ``failure: stopped``) and a later ag_ex
  started it again. A request a_ta sends again to a restarted ag_ex is such a case
  (services/agents/task_executor/agent.py: only absolute motions are sent again); a command
  that ran to its end and ran again, or started twice by one ag_ex, is not. A restarted ag_ex
  answers a request whose command a loop ended before from the ledger instead
  (services/agents/executor/agent.py): a ``replayed`` line, no ``start``; those are listed,
  *answered from the ledger after a restart*, and are not a fault (an Observe's capture is
  rendered again then: sensing moves nothing in the world).
- **Answered done, never ran**: an ``inform`` from ag_ex in a fipa-request with a CommandResult
  that is ``ok`` or an L_SD Observation (the answer to a cancel is never such: it says
  ``halted``), whose conversation-id has no ``start`` and ``end`` in the ledger.
"""

from __future__ import annotations

import itertools
from collections import defaultdict
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from services.report.load import Message
from shared.fipa_codec.languages.l_ex import CommandResult
from shared.fipa_codec.languages.l_sd import Observation
from velma.executor.ledger import INTERRUPTED, LEDGER_FILE, LedgerEntry, LedgerRead, read_ledger

EXECUTOR = "ag_ex"
REQUEST_PROTOCOL = "fipa-request"


@dataclass
class LedgerVerdict:
    """What ag_ex's ledger says beside the record. ``found``: the run folder has a ledger;
    ``runs``: commands the loop started; ``lives``: ag_ex processes that wrote it; ``skipped``:
    lines that did not decode; ``twice``: conversations executed twice, as "command
    (conversation): started at t1, t2 s"; ``never_ran``: conversations answered done without a
    run in the ledger, as "command (conversation)"; ``resumed``: conversations started again
    by a restarted ag_ex after their first run was interrupted (not a fault); ``replayed``:
    conversations a restarted ag_ex answered from the ledger without running them (not a
    fault), as "command (conversation)"."""

    found: bool = False
    runs: int = 0
    lives: int = 0
    skipped: int = 0
    twice: list[str] = field(default_factory=list)
    never_ran: list[str] = field(default_factory=list)
    resumed: list[str] = field(default_factory=list)
    replayed: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not self.twice and not self.never_ran

    def problems(self) -> list[str]:
        """Each fault found, in words."""
        return [f"executed twice: {t}" for t in self.twice] + [
            f"answered done, never ran: {n}" for n in self.never_ran
        ]

    def summary(self) -> str:
        """One line: what the ledger holds and its verdict."""
        if not self.found:
            head = f"no ledger ({LEDGER_FILE})"
        else:
            head = f"{self.runs} command(s) started by {self.lives} ag_ex process(es)"
            if self.skipped:
                head += f", {self.skipped} unreadable line(s)"
        verdict = "; ".join(self.problems()) or "nothing executed twice, every done answer ran"
        resumed = f" (resumed after a restart: {', '.join(self.resumed)})" if self.resumed else ""
        if self.replayed:
            resumed += f" (answered from the ledger after a restart: {', '.join(self.replayed)})"
        return f"{head}: {verdict}{resumed}"


def _started_twice(entries: Sequence[LedgerEntry]) -> tuple[list[str], list[str]]:
    """(executed twice, resumed after a restart) of the ledger's ``entries`` (module docstring)."""
    starts: dict[str, list[LedgerEntry]] = defaultdict(list)
    ends: dict[tuple[str, str], list[LedgerEntry]] = defaultdict(list)
    for e in entries:
        if e.event == "start":
            starts[e.conversation].append(e)
        elif e.event == "end":
            ends[(e.conversation, e.life)].append(e)
    twice: list[str] = []
    resumed: list[str] = []
    for conversation, runs in starts.items():
        if len(runs) < 2:
            continue
        times = ", ".join(f"{r.sim_time:.3f}" for r in runs)
        what = f"{runs[-1].command} ({conversation}): started at {times} s"
        interrupted = all(
            _interrupted(ends[(conversation, run.life)]) and later.life != run.life
            for run, later in itertools.pairwise(runs)
        )
        (resumed if interrupted else twice).append(what)
    return sorted(twice), sorted(resumed)


def _interrupted(ends: Sequence[LedgerEntry]) -> bool:
    """True when a run whose life wrote ``ends`` was cut short by its ag_ex stopping."""
    return all(e.outcome == INTERRUPTED for e in ends)


def _replayed(entries: Sequence[LedgerEntry]) -> list[str]:
    """ "command (conversation)" of each request a restarted ag_ex answered from the ledger."""
    return sorted({f"{e.command} ({e.conversation})" for e in entries if e.event == "replayed"})


def _answered_done(messages: Sequence[Message]) -> dict[str, str]:
    """Conversation-id → command of each request ag_ex answered done (module docstring)."""
    done: dict[str, str] = {}
    for m in messages:
        if m.comm is None or m.sender != EXECUTOR or m.performative != "inform":
            continue
        if m.rec.protocol != REQUEST_PROTOCOL or m.conversation is None:
            continue
        if isinstance(m.content, Observation):
            done[m.conversation] = "observe"
        elif isinstance(m.content, CommandResult) and m.content.ok:
            done[m.conversation] = m.content.command
    return done


def judge_ledger(run_dir: Path, messages: Sequence[Message]) -> LedgerVerdict:
    """The verdict of ``run_dir``'s ledger beside its recorded ``messages`` (module
    docstring). A missing ledger reads as empty: then every done answer never ran. Raises
    OSError when the ledger exists but cannot be read."""
    read: LedgerRead = read_ledger(run_dir)
    twice, resumed = _started_twice(read.entries)
    ran = {e.conversation for e in read.entries if e.event == "start"}
    ended = {e.conversation for e in read.entries if e.event == "end"}
    never = sorted(
        f"{command} ({conversation})"
        for conversation, command in _answered_done(messages).items()
        if conversation not in ran or conversation not in ended
    )
    return LedgerVerdict(
        found=read.found,
        runs=sum(e.event == "start" for e in read.entries),
        lives=len({e.life for e in read.entries}),
        skipped=read.skipped,
        twice=twice,
        never_ran=never,
        resumed=resumed,
        replayed=_replayed(read.entries),
    )
