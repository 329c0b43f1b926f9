"""The record of an agent's FSM (paper §3.2, Tables 3–6): the FSM it built, each state it
entered and each reply-by time-out it met, one JSON line each (``roco spec coverage``).

A behaviour's transition function runs many times a state; this record is written once per
FSM transition, never per step. An agent writes it to ``<folder>/fsm/<agent>.<pid>.jsonl`` of
its run folder (``ROCO_RUN_DIR``) and of the tap folder (``ROCO_TAP_DIR``,
services/runtime/tap.py), each when set; with neither, :func:`for_agent` gives None and the
agent writes nothing. Records (a msgspec tagged union, tag ``kind``):

- :class:`FsmDeclared` (``fsm``): the agent started; its states and arcs (source, target,
  label) as :meth:`~services.runtime.behaviour.FSM.describe` gives them;
- :class:`FsmEntered` (``enter``): the agent entered ``state`` at start (``how`` ``start``),
  along an arc (``arc``: ``source`` and ``label`` name it), or back in the initial state after a
  transition function raised (``error``);
- :class:`TimedOut` (``timeout``): a reply-by deadline of the agent's passed before ``peer``
  answered in a conversation of ``protocol`` that stood in ``state`` (FIPA SC00061 §2.4: the
  runtime ends it with a local failure, services/runtime/replies.py). A time-out is never on
  the wire; this is its only record.
"""

from __future__ import annotations

import itertools
import os
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Literal

import msgspec

from services.runtime.behaviour import FSM
from services.runtime.tap import Appender, appender
from shared.settings import Settings

FSM_DIR = "fsm"
"""The folder of the records, in a run folder and in the tap folder."""
MAX_RECORD_BYTES = 64 * 1024 * 1024
"""Most bytes of one record file a reader reads."""

Entry = Literal["start", "arc", "error"]


class FsmDeclared(msgspec.Struct, frozen=True, kw_only=True, tag="fsm", tag_field="kind"):
    """An agent started: ``agent`` its name, ``implementation`` its class (``module:Class``),
    ``instance`` this start's id (``<pid>-<n>``), ``t`` POSIX s, its FSM's ``initial`` state,
    ``states`` and ``arcs`` ([source, target, label], in order of evaluation)."""

    agent: str
    implementation: str
    instance: str
    t: float
    initial: str
    states: list[str]
    arcs: list[tuple[str, str, str]]


class FsmEntered(msgspec.Struct, frozen=True, kw_only=True, tag="enter", tag_field="kind"):
    """The agent ``instance`` entered ``state`` at ``t`` (POSIX s): ``how`` ``start``, along
    the arc from ``source`` labelled ``label`` (``arc``), or after an error (``error``)."""

    agent: str
    instance: str
    t: float
    state: str
    how: Entry
    source: str | None = None
    label: str = ""


class TimedOut(msgspec.Struct, frozen=True, kw_only=True, tag="timeout", tag_field="kind"):
    """A reply-by deadline of ``agent`` passed before ``peer`` answered (module docstring):
    the conversation's ``protocol`` and ``conversation_id``, and the protocol ``state`` it
    stood in (None: the agent followed no state of it)."""

    agent: str
    instance: str
    t: float
    peer: str
    protocol: str | None
    conversation_id: str | None
    state: str | None


Record = FsmDeclared | FsmEntered | TimedOut
_encoder = msgspec.json.Encoder()
_decoder = msgspec.json.Decoder(Record)
_instances = itertools.count()


class FsmRecord:
    """Where one agent writes its records (module docstring)."""

    def __init__(self, agent: str, files: list[Appender]) -> None:
        self.agent = agent
        self.instance = f"{os.getpid()}-{next(_instances)}"
        self._files = files

    def _write(self, record: Record) -> None:
        line = _encoder.encode(record) + b"\n"
        for f in self._files:
            f.write(line)

    def declared(self, fsm: FSM, implementation: str) -> None:
        """The agent starts with ``fsm``."""
        self._write(
            FsmDeclared(
                agent=self.agent,
                implementation=implementation,
                instance=self.instance,
                t=time.time(),
                initial=fsm.initial,
                states=list(fsm.states),
                arcs=[(a.source, a.target, a.label) for a in fsm.arcs],
            )
        )

    def entered(self, state: str, how: Entry, source: str | None = None, label: str = "") -> None:
        """The agent entered ``state`` (see :class:`FsmEntered`)."""
        self._write(
            FsmEntered(
                agent=self.agent,
                instance=self.instance,
                t=time.time(),
                state=state,
                how=how,
                source=source,
                label=label,
            )
        )

    def timed_out(
        self, peer: str, protocol: str | None, conversation_id: str | None, state: str | None
    ) -> None:
        """A reply-by deadline passed (see :class:`TimedOut`)."""
        self._write(
            TimedOut(
                agent=self.agent,
                instance=self.instance,
                t=time.time(),
                peer=peer,
                protocol=protocol,
                conversation_id=conversation_id,
                state=state,
            )
        )


def for_agent(agent: str) -> FsmRecord | None:
    """The record of ``agent`` in the run folder and the tap folder set in the environment
    (read now); None when neither is set."""
    read = Settings.from_env(only=("run_dir", "tap_dir"))
    folders = [f for f in (read.run_dir, read.tap_dir) if f is not None]
    if not folders:
        return None
    name = f"{agent}.{os.getpid()}.jsonl"
    return FsmRecord(agent, [appender(folder / FSM_DIR / name) for folder in folders])


def record_files(folder: Path) -> list[Path]:
    """The record files of a run or tap ``folder``, by name (none when it has no ``fsm/``)."""
    return sorted((folder / FSM_DIR).glob("*.jsonl"))


def read_records(path: Path) -> Iterator[Record]:
    """The records of one file, in the order written; lines that do not decode (a process
    killed while writing) are skipped. Raises ValueError when the file is larger than
    :data:`MAX_RECORD_BYTES`, OSError when it cannot be read."""
    size = path.stat().st_size
    if size > MAX_RECORD_BYTES:
        raise ValueError(f"{path}: {size} bytes, more than the {MAX_RECORD_BYTES} read")
    for line in path.read_bytes().splitlines():
        try:
            yield _decoder.decode(line)
        except (msgspec.DecodeError, msgspec.ValidationError):
            continue
