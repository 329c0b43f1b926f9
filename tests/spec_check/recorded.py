"""A recorded run's traffic as (record, payload) pairs that a test can cut, reorder or re-link
and write back as a run folder (the raw stream in the ``[seq, payload]`` form
tests/report/conftest.py writes).

``URGENT`` is part of the record of one ``roco scenario urgent_mid_pour`` (see its README)."""

from __future__ import annotations

import shutil
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import msgspec

from services.recorder.record import TRAFFIC_JSONL, read_payloads
from services.report.load import Message, load_run
from services.runtime.run_folder import RUN_INFO
from shared.fipa_codec import Communicate, decode, encode
from shared.fipa_codec.languages import decode_content, encode_content
from tests.report.conftest import STARTED, RunBuilder, write_raw

URGENT = Path(__file__).parent / "fixtures" / "urgent_mid_pour"
URGENT_LEAVES = ("R1.1", "R1.2", "R1.3", "R2.1", "R2.2", "R2.3", "R2.4", "R3.1", "R3.3", "R3.2")
"""The leaves ``URGENT`` shows (those of the specification it was recorded with, but R1.4: a
sentence from another platform, which tests add on C8). A leaf added to the specification since
is for a record of its own to show."""

Pick = Callable[[Message], bool]
"""Which communicates a mutation applies to."""


@dataclass
class Recorded:
    """The communicates of a run folder in arrival order, each with its payload."""

    source: Path
    messages: list[Message]
    payloads: list[bytes]

    @classmethod
    def read(cls, run_dir: Path = URGENT) -> Recorded:
        run = load_run(run_dir)
        raw = dict(read_payloads(run_dir))
        return cls(run_dir, list(run.messages), [raw[m.rec.ref] for m in run.messages])

    def started(self) -> float:
        run = load_run(self.source)
        return run.t0

    def select(self, pick: Pick) -> list[int]:
        """The indices of the communicates ``pick`` chooses; at least one, or AssertionError."""
        found = [i for i, m in enumerate(self.messages) if pick(m)]
        assert found, "the mutation picks no communicate"
        return found

    def remove(self, pick: Pick) -> Recorded:
        """Without the communicates ``pick`` chooses."""
        gone = set(self.select(pick))
        keep = [i for i in range(len(self.messages)) if i not in gone]
        return Recorded(self.source, [self.messages[i] for i in keep], [self.payloads[i] for i in keep])

    def move(self, pick: Pick, before: Pick) -> Recorded:
        """The communicates ``pick`` chooses sent and recorded just before the first that
        ``before`` chooses (their arrival and send times moved to 1 ms before its, their order
        kept)."""
        at = self.messages[self.select(before)[0]].rec.t
        moved = self.select(pick)
        messages = list(self.messages)
        for k, i in enumerate(moved):
            old = messages[i].rec
            t = at - 1e-3 + k * 1e-6
            sent = None if old.t_sent is None else old.t_sent + (t - old.t)
            rec = msgspec.structs.replace(old, t=t, t_sent=sent)
            messages[i] = Message(rec, messages[i].t, messages[i].comm, messages[i].content)
        order = sorted(range(len(messages)), key=lambda i: messages[i].rec.t)
        return Recorded(self.source, [messages[i] for i in order], [self.payloads[i] for i in order])

    def relink(self, pick: Pick, **fields: str | None) -> Recorded:
        """The communicates ``pick`` chooses with their message parameters ``fields`` changed
        (``conversation_id``, ``in_reply_to``, ``reply_with``), re-encoded."""
        messages, payloads = list(self.messages), list(self.payloads)
        for i in self.select(pick):
            comm: Communicate = msgspec.structs.replace(decode(payloads[i]), **fields)
            payloads[i] = encode(comm)
            rec = msgspec.structs.replace(
                messages[i].rec, conversation_id=comm.conversation_id, size=len(payloads[i])
            )
            messages[i] = Message(rec, messages[i].t, comm, messages[i].content)
        return Recorded(self.source, messages, payloads)

    def recontent(self, pick: Pick, change: Callable[[msgspec.Struct], msgspec.Struct]) -> Recorded:
        """The communicates ``pick`` chooses with their content term replaced by ``change`` of
        it, re-encoded."""
        messages, payloads = list(self.messages), list(self.payloads)
        for i in self.select(pick):
            content = messages[i].content
            assert content is not None, "the mutation picks a communicate without content"
            language, data = encode_content(change(content))
            comm: Communicate = msgspec.structs.replace(decode(payloads[i]), language=language, content=data)
            payloads[i] = encode(comm)
            rec = msgspec.structs.replace(messages[i].rec, size=len(payloads[i]))
            messages[i] = Message(rec, messages[i].t, comm, decode_content(language, data))
        return Recorded(self.source, messages, payloads)

    def plus(self, b: RunBuilder) -> Recorded:
        """With ``b``'s communicates added, their times (s after tests/report/conftest.py's
        ``STARTED``) counted from this run's start."""
        shift = self.started() - STARTED
        added = [Message(msgspec.structs.replace(r, t=r.t + shift), 0.0) for r in b.records]
        pairs = sorted(
            zip([*self.messages, *added], [*self.payloads, *b.payloads], strict=True),
            key=lambda p: p[0].rec.t,
        )
        return Recorded(self.source, [m for m, _ in pairs], [p for _, p in pairs])

    def write(self, run_dir: Path) -> Path:
        """``run_dir`` made a run folder of these communicates (``run.json`` copied)."""
        run_dir.mkdir(parents=True)
        shutil.copy(self.source / RUN_INFO, run_dir / RUN_INFO)
        enc = msgspec.json.Encoder()
        records = [
            msgspec.structs.replace(m.rec, seq=seq, incarnation="") for seq, m in enumerate(self.messages)
        ]
        (run_dir / TRAFFIC_JSONL).write_bytes(b"".join(enc.encode(r) + b"\n" for r in records))
        write_raw(run_dir, list(enumerate(self.payloads)))
        return run_dir
