"""The traffic record pairs each record with its own payload across recorder
incarnations, a killed recorder's half-written tail is completed by the next one, and the
integrity check finds mispairing, gaps and duplicates instead of guessing."""

from __future__ import annotations

from pathlib import Path

import msgspec

from services.recorder.integrity import check
from services.recorder.record import (
    TRAFFIC_JSONL,
    TRAFFIC_RAW,
    RawEntry,
    RecordKey,
    encode_entry,
    read_payloads,
    read_records,
)
from services.recorder.recorder import TrafficWriter
from services.report.load import load_run
from services.runtime.transport import Arrival
from shared.fipa_codec import Performative, encode
from tests.support.messages import communicate

KEY = "roco/fipa/C4/a_pl/a_km"


def _payload(i: int, sender: str = "a_pl", receiver: str = "a_km") -> bytes:
    return encode(communicate(Performative.QUERY_REF, sender, receiver, "fipa-query", f"c-{i}"))


def _arrivals(sns: range, source: str = "z1:3") -> list[Arrival]:
    return [Arrival(100.0 + sn, KEY, _payload(sn), source, sn, 99.0 + sn) for sn in sns]


def test_two_incarnations_never_pair_each_others_bytes(tmp_path: Path) -> None:
    first = TrafficWriter(tmp_path, "first")
    first.write_many(_arrivals(range(3)))
    first.close()
    second = TrafficWriter(tmp_path, "second")
    second.write_many(_arrivals(range(3, 6)))
    second.close()
    records = read_records(tmp_path)
    assert [r.seq for r in records] == [0, 1, 2, 3, 4, 5]  # seq counted on, not restarted
    assert [r.incarnation for r in records] == ["first"] * 3 + ["second"] * 3
    integrity, comms = check(records, read_payloads(tmp_path))
    assert integrity.intact and integrity.paired == 6 and integrity.incarnations == ["first", "second"]
    for r in records:  # each record's communicate is its own
        comm = comms[r.ref]
        assert comm is not None and comm.conversation_id == r.conversation_id


def test_a_recorder_killed_between_its_two_writes_is_completed_by_the_next(tmp_path: Path) -> None:
    w = TrafficWriter(tmp_path, "killed")
    w.write_many(_arrivals(range(2)))
    w.close()
    # the payload of sn 2 reached the disk, its record did not; the next entry was cut short
    entry = RawEntry("killed", 2, Arrival(102.0, KEY, _payload(2), "z1:3", 2, 101.0))
    torn = encode_entry(RawEntry("killed", 3, Arrival(103.0, KEY, _payload(3), "z1:3", 3, 102.0)))[:-5]
    with (tmp_path / TRAFFIC_RAW).open("ab") as f:
        f.write(encode_entry(entry) + torn)
    with (tmp_path / TRAFFIC_JSONL).open("ab") as f:
        f.write(b'{"seq": 2, "t"')  # a line cut short
    w2 = TrafficWriter(tmp_path, "next")
    assert not w2.admit("z1:3", 2) and w2.admit("z1:3", 3)  # sn 2 is in the record now; 3 is not
    w2.write_many(_arrivals(range(3, 4)))
    w2.close()
    assert (tmp_path / f"{TRAFFIC_RAW}.next.tail").read_bytes() == torn
    run = load_run(tmp_path)
    assert run.integrity.intact, run.integrity.summary()
    assert [m.rec.sn for m in run.messages] == [0, 1, 2, 3]
    assert any("corrupt line" in n for n in run.notes)  # the cut line is skipped, and said


def test_keys_written_twice_by_an_old_recorder_are_left_unpaired_not_guessed(tmp_path: Path) -> None:
    """A restarted recorder does not begin again at seq 0 in both files."""
    w = TrafficWriter(tmp_path, "")
    w.write_many(_arrivals(range(2), source="z1:1"))
    w.close()
    (tmp_path / TRAFFIC_RAW).write_bytes(
        b"".join(msgspec.msgpack.encode((i % 2, _payload(i))) for i in range(3))  # seq 0, 1, 0
    )
    records = read_records(tmp_path)
    integrity, comms = check(records, read_payloads(tmp_path))
    assert integrity.ambiguous == [RecordKey("", 0)]
    assert RecordKey("", 0) not in comms and not integrity.intact
    assert "written twice" in integrity.summary()


def test_a_payload_that_is_not_the_communicate_its_record_describes_is_refused(tmp_path: Path) -> None:
    w = TrafficWriter(tmp_path, "a")
    w.write_many(_arrivals(range(2)))
    w.close()
    data = b"".join(encode_entry(RawEntry("a", i, Arrival(0.0, KEY, _payload(9 - i)))) for i in range(2))
    (tmp_path / TRAFFIC_RAW).write_bytes(data)  # same keys and sizes, other conversations
    integrity, comms = check(read_records(tmp_path), read_payloads(tmp_path))
    assert integrity.mismatched == [RecordKey("a", 0), RecordKey("a", 1)] and not comms


def test_gaps_and_duplicates_by_publisher_sequence_numbers(tmp_path: Path) -> None:
    w = TrafficWriter(tmp_path, "a")
    w.write_many([*_arrivals(range(0, 3)), *_arrivals(range(6, 8)), *_arrivals(range(7, 8))])
    w.write_many(_arrivals(range(0, 2), source="z2:9"))
    w.close()
    integrity, _ = check(read_records(tmp_path), read_payloads(tmp_path))
    assert [(g.source, g.first, g.last) for g in integrity.gaps] == [("z1:3", 3, 5)]
    assert integrity.lost == 3 and integrity.duplicates == [f"{KEY} sn 7"]
    assert not integrity.intact and "3 communicate(s) lost" in integrity.summary()


def test_the_writer_drops_what_a_publisher_cache_sends_again(tmp_path: Path) -> None:
    w = TrafficWriter(tmp_path, "a")
    fresh = [a for a in _arrivals(range(4)) if w.admit(a.source, a.sn)]
    w.write_many(fresh)
    again = [a for a in _arrivals(range(6)) if w.admit(a.source, a.sn)]
    assert [a.sn for a in again] == [4, 5] and w.duplicates == 4
    assert w.admit(None, None)  # a plain put carries no sequence number: always new
    w.close()


def test_the_communicates_of_a_batch_share_its_sequence_number(tmp_path: Path) -> None:
    """A batch (shared/fipa_codec/batch.py) is one sample: its communicates arrive as parts 0, 1,
    … of one sn; a cache's resend of the batch is refused whole, and only a part recorded twice
    is a duplicate."""
    w = TrafficWriter(tmp_path, "a")

    def batch(sn: int, parts: int) -> list[Arrival]:
        return [
            Arrival(100.0 + sn, KEY, _payload(10 * sn + k), "z1:3", sn, 99.0, part=k) for k in range(parts)
        ]

    first = [a for a in [*batch(0, 3), *batch(1, 1)] if w.admit(a.source, a.sn, a.part)]
    assert [(a.sn, a.part) for a in first] == [(0, 0), (0, 1), (0, 2), (1, 0)]
    w.write_many(first)
    again = [a for a in [*batch(0, 3), *batch(1, 1), *batch(2, 2)] if w.admit(a.source, a.sn, a.part)]
    assert [(a.sn, a.part) for a in again] == [(2, 0), (2, 1)] and w.duplicates == 4
    w.write_many([*again, batch(2, 2)[1]])  # part 1 of sn 2 written twice
    w.close()
    integrity, _ = check(read_records(tmp_path), read_payloads(tmp_path))
    assert not integrity.gaps and integrity.duplicates == [f"{KEY} sn 2 part 1"]
    assert [(r.sn, r.part) for r in read_records(tmp_path)][:3] == [(0, 0), (0, 1), (0, 2)]
