"""ag_ex's ledger of the commands its control loop executed: one JSON line per event, appended
to ``<ROCO_RUN_DIR>/ag_ex_ledger.jsonl`` and fsync-ed, so that it outlives ag_ex's restarts
(the run folder is the world process's and the launcher's too; velma/world/files.py) and the
run's judges can tell a command the robot ran twice, or one answered done that never ran
(services/report/ledger.py).

A line is a :class:`LedgerEntry`: ``event`` ``start`` (the loop took the command up and started
its motion primitive), ``end`` (the loop ended it: its own result, not an answer made up when
the loop was gone) or ``replayed`` (a restarted ag_ex answered the request from the ledger
without running it: :func:`recall`), the request's ``conversation`` (FIPA conversation-id), the L_EX
``command`` name, ``sim_time`` (s, the robot's simulated clock, to the µs: the cycle it
started in, or the result's time), ``outcome`` (``end`` only: ``ok``, ``failure: <reason>``, ``captured``
for an Observe's capture, ``observed`` for a ground-truth Observation) and ``life``: which
ag_ex process wrote it (``<pid>-<6 hex digits>``, new at each start of ag_ex). An ``end`` line
keeps the loop's result too, so that a restarted ag_ex answers a request sent again with it
instead of running the command twice: ``result``, an L_EX CommandResult that fits in the line,
or ``stored``, ``(offset, length)`` in bytes of the result in the side store
``<ROCO_RUN_DIR>/ag_ex_answers.bin`` (:data:`ANSWERS_FILE`: an Observe's WorldCapture or
Observation, a longer CommandResult), msgpack, appended and fsync-ed before the line.

Lines are at most :data:`MAX_LINE_BYTES` long (a longer outcome or conversation-id is cut,
marked with "…"); a reader skips lines it cannot decode (a torn last line of a killed
process) and counts them. A stored result is at most :data:`MAX_STORED_BYTES` long and the side
store at most :data:`MAX_ANSWERS_BYTES`; a result that would pass either is not kept (the line
has neither field, and a restarted ag_ex runs the command again).
"""

from __future__ import annotations

import contextlib
import os
import secrets
from dataclasses import dataclass, field
from pathlib import Path
from typing import BinaryIO, Literal

import msgspec

from shared.fipa_codec.languages.l_ex import CommandResult
from shared.fipa_codec.languages.l_sd import Observation
from velma.executor.capture import WorldCapture

LEDGER_FILE = "ag_ex_ledger.jsonl"
MAX_LINE_BYTES = 1024
"""Longest line written or read (B, newline included)."""
MAX_TEXT = 256
"""Longest conversation-id or outcome kept (characters; longer ones are cut, ending "…")."""
MAX_LINES = 1_000_000
"""Most lines a reader takes (a pour writes a few hundred)."""

ANSWERS_FILE = "ag_ex_answers.bin"
MAX_STORED_BYTES = 1 << 20
"""Longest result kept in the side store (B; the kitchen's WorldCapture took 920 B in a chaos run)."""
MAX_ANSWERS_BYTES = 256 << 20
"""Largest side store (B); results past it are not kept."""
MAX_RECALL_BYTES = 8 << 20
"""How much of the ledger's end a starting ag_ex reads (B: the last 8 MiB, at most 8 192 lines
of 1 KiB, about 40 000 of a pour's lines; a pour writes a few hundred)."""

Event = Literal["start", "end", "replayed"]
Answer = CommandResult | Observation | WorldCapture
"""A loop's result as kept for a later answer (an Observe's WorldCapture is rendered then)."""
STOPPED = "stopped"
"""The reason of the commands a stopping loop ends (ag_ex stops: a restart, SIGTERM)."""
INTERRUPTED = f"failure: {STOPPED}"
"""The ``outcome`` of a command cut short because its ag_ex stopped."""


class LedgerEntry(msgspec.Struct, frozen=True, kw_only=True, forbid_unknown_fields=True, omit_defaults=True):
    """One line of the ledger (module docstring)."""

    event: Event
    conversation: str
    command: str
    sim_time: float
    life: str
    outcome: str | None = None
    result: CommandResult | None = None
    stored: tuple[int, int] | None = None


def outcome_of(result: object) -> str:
    """The ledger's ``outcome`` of a loop's result: ``ok`` or ``failure: <reason>`` for an L_EX
    CommandResult, ``captured`` for an Observe's WorldCapture, ``observed`` for an L_SD
    Observation (ground truth), else the type's name."""
    ok, reason = getattr(result, "ok", None), getattr(result, "reason", None)
    if isinstance(ok, bool):
        return "ok" if ok else f"failure: {reason or '?'}"
    name = type(result).__name__
    return {"WorldCapture": "captured", "Observation": "observed"}.get(name, name)


def _cut(text: str) -> str:
    return text if len(text) <= MAX_TEXT else text[: MAX_TEXT - 1] + "…"


def new_life() -> str:
    """A fresh ``life``: this process's id and 6 random hex digits."""
    return f"{os.getpid()}-{secrets.token_hex(3)}"


class Ledger:
    """The append-only ledger at ``path`` (created when missing), written by one ag_ex process
    (``life``, default :func:`new_life`); a torn last line (a writer killed mid-line) is ended
    first, so that it stays the only line lost. Each ``started``/``ended`` appends one line and
    fsyncs it before returning (p50 3.7 ms, p99 11 ms on a 2-core VM, docs/recovery.md: call it
    from the agent's thread, never the loop's).
    An end line with a result kept in the side store costs a second append and fsync.
    Raises OSError when the file cannot be opened or written."""

    def __init__(self, path: Path, life: str | None = None) -> None:
        self.path = path
        self.life = life or new_life()
        self._encode = msgspec.json.Encoder().encode
        self._fd = os.open(path, os.O_RDWR | os.O_APPEND | os.O_CREAT, 0o644)
        self._side = -1  # the side store, opened when first needed
        size = os.fstat(self._fd).st_size
        if size and os.pread(self._fd, 1, size - 1) != b"\n":  # a killed writer's torn last line
            os.write(self._fd, b"\n")

    def started(self, conversation: str, command: str, sim_time: float) -> None:
        """The loop started ``command`` of ``conversation`` at ``sim_time`` (s)."""
        entry = LedgerEntry(
            event="start",
            conversation=_cut(conversation),
            command=command,
            sim_time=round(sim_time, 6),
            life=self.life,
        )
        self._append(entry)

    def ended(
        self, conversation: str, command: str, sim_time: float, outcome: str, result: Answer | None = None
    ) -> None:
        """The loop ended ``command`` of ``conversation`` at ``sim_time`` (s) with ``outcome``
        and ``result`` (None: not kept), kept in the line or the side store (module
        docstring). Raises OSError when the side store or the line cannot be written."""
        entry = LedgerEntry(
            event="end",
            conversation=_cut(conversation),
            command=command,
            sim_time=round(sim_time, 6),
            life=self.life,
            outcome=_cut(outcome),
        )
        if isinstance(result, CommandResult):
            inline = msgspec.structs.replace(entry, result=result)
            if len(self._encode(inline)) < MAX_LINE_BYTES:
                self._append(inline)
                return
        if result is not None:
            entry = msgspec.structs.replace(entry, stored=self._store(result))
        self._append(entry)

    def replayed(self, conversation: str, command: str, sim_time: float) -> None:
        """This ag_ex answered ``conversation``'s ``command`` from the ledger (the result of
        ``sim_time``, s) without running it."""
        self._append(
            LedgerEntry(
                event="replayed",
                conversation=_cut(conversation),
                command=command,
                sim_time=round(sim_time, 6),
                life=self.life,
            )
        )

    def _store(self, result: Answer) -> tuple[int, int] | None:
        """Append ``result`` to the side store, fsync-ed: its ``(offset, length)`` (B), or None
        when it is too long or the store full."""
        data = msgspec.msgpack.encode(result)
        if len(data) > MAX_STORED_BYTES:
            return None
        if self._side < 0:
            side = self.path.with_name(ANSWERS_FILE)
            self._side = os.open(side, os.O_RDWR | os.O_APPEND | os.O_CREAT, 0o644)
        if os.fstat(self._side).st_size + len(data) > MAX_ANSWERS_BYTES:
            return None
        os.write(self._side, data)
        os.fsync(self._side)
        end = os.lseek(self._side, 0, os.SEEK_CUR)  # where this O_APPEND write ended, whoever else appends
        return (end - len(data), len(data))

    def _append(self, entry: LedgerEntry) -> None:
        line = self._encode(entry) + b"\n"
        if len(line) > MAX_LINE_BYTES:  # only an absurd command name gets here
            line = self._encode(msgspec.structs.replace(entry, command=entry.command[:64])) + b"\n"
        os.write(self._fd, line)  # one write of O_APPEND: lines of two processes never interleave
        os.fsync(self._fd)

    def close(self) -> None:
        """Close the files (idempotent)."""
        for fd in (self._fd, self._side):
            if fd >= 0:
                os.close(fd)
        self._fd = self._side = -1


@dataclass
class LedgerRead:
    """A ledger as read: its ``entries`` in file order, ``skipped`` lines that did not decode
    (or were longer than :data:`MAX_LINE_BYTES`), and whether the file was there (``found``)."""

    entries: list[LedgerEntry] = field(default_factory=list)
    skipped: int = 0
    found: bool = False


def read_ledger(run_dir: Path) -> LedgerRead:
    """The ledger of the run folder ``run_dir`` (``found`` False when it has none), at most
    :data:`MAX_LINES` lines from its start. Raises OSError when the file exists but cannot be
    read."""
    path = Path(run_dir) / LEDGER_FILE
    if not path.is_file():
        return LedgerRead()
    with path.open("rb") as f:
        return _read_lines(f, MAX_LINES)


def _read_lines(f: BinaryIO, most: int) -> LedgerRead:
    out = LedgerRead(found=True)
    decode = msgspec.json.Decoder(LedgerEntry).decode
    for _ in range(most):
        line = f.readline(MAX_LINE_BYTES + 1)
        if not line:
            break
        if len(line) > MAX_LINE_BYTES:  # too long: skip to its end
            while line and not line.endswith(b"\n"):
                line = f.readline(MAX_LINE_BYTES + 1)
            out.skipped += 1
            continue
        if not line.strip():
            continue
        try:
            out.entries.append(decode(line))
        except msgspec.DecodeError:
            out.skipped += 1
    return out


@dataclass(frozen=True)
class Recalled:
    """A command an earlier ag_ex's loop ended: its ``command`` name, the result's
    ``sim_time`` (s) and the loop's ``answer``."""

    command: str
    sim_time: float
    answer: Answer


def recall(path: Path, max_bytes: int = MAX_RECALL_BYTES) -> dict[str, Recalled]:
    """Conversation-id → the command the ledger at ``path`` says a loop ended, with its kept
    result, from the last ``max_bytes`` of the file (:data:`MAX_RECALL_BYTES`): the last end
    of each conversation that was not cut short by its ag_ex stopping (``failure: stopped``)
    and whose result was kept and reads back. Conversations under "?" or cut to
    :data:`MAX_TEXT` are left out (two could share a cut id). Empty when the file is missing.
    Raises OSError when it exists but cannot be read."""
    if not path.is_file():
        return {}
    ends = [e for e in _tail(path, max_bytes).entries if e.event == "end" and _recallable(e)]
    side = path.with_name(ANSWERS_FILE)
    out: dict[str, Recalled] = {}
    with contextlib.ExitStack() as stack:
        store = stack.enter_context(side.open("rb")) if side.is_file() else None
        for e in ends:
            answer = e.result if e.result is not None else _stored(store, e.stored)
            if answer is not None:
                out[e.conversation] = Recalled(e.command, e.sim_time, answer)
    return out


def _tail(path: Path, max_bytes: int) -> LedgerRead:
    """The lines of the ledger at ``path`` that lie whole in its last ``max_bytes``."""
    with path.open("rb") as f:
        size = os.fstat(f.fileno()).st_size
        if size > max_bytes:
            f.seek(size - max_bytes - 1)
            f.readline(max_bytes + 1)  # the rest of a line cut by the start of the window
        return _read_lines(f, max_bytes)


def _recallable(e: LedgerEntry) -> bool:
    """An end whose command ran to its end, under a conversation-id kept whole."""
    return e.outcome != INTERRUPTED and e.conversation != "?" and not e.conversation.endswith("…")


def _stored(store: BinaryIO | None, where: tuple[int, int] | None) -> Answer | None:
    """The result at ``where`` in the side store, None when missing or unreadable."""
    if store is None or where is None or not 0 < where[1] <= MAX_STORED_BYTES or where[0] < 0:
        return None
    store.seek(where[0])
    data = store.read(where[1])
    try:
        return msgspec.msgpack.decode(data, type=Answer) if len(data) == where[1] else None
    except (msgspec.DecodeError, msgspec.ValidationError):
        return None
