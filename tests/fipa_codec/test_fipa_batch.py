"""Several communicates in one payload (shared/fipa_codec/batch.py): a batch splits into exactly
the communicates packed, in order; anything else splits into itself, so that the receiver's
decoding judges it; an output buffer is grouped by key without reordering."""

from __future__ import annotations

import pytest

from shared.fipa_codec import Performative, decode, encode
from shared.fipa_codec.batch import (
    BATCH_MAX_BYTES,
    BATCH_MAX_COMMUNICATES,
    count,
    is_batch,
    join,
    pack,
    runs,
    unpack,
)
from shared.fipa_codec.encoding import MAX_COMMUNICATE_BYTES
from tests.support.messages import communicate

A, B = "roco/fipa/C4/a_km/a_pl", "roco/fipa/C6/a_km/a_ta"


def payloads(n: int) -> list[bytes]:
    return [
        encode(communicate(Performative.INFORM, "a_km", "a_pl", "fipa-subscribe", f"c-{i}")) for i in range(n)
    ]


def test_a_batch_splits_into_its_communicates_in_order() -> None:
    parts = payloads(3)
    batch = pack(parts)
    assert is_batch(batch) and not any(is_batch(p) for p in parts)
    assert unpack(batch) == parts
    assert [decode(p).conversation_id for p in unpack(batch)] == ["c-0", "c-1", "c-2"]


@pytest.mark.parametrize(
    "payload",
    [
        payloads(1)[0],  # one communicate: a map
        b"",  # nothing
        b"\x00garbage",
        b"\x92\x01\x02",  # an array, but of integers
        b"\x92\xc4\x01",  # an array cut short
        b"\x90",  # an empty array
    ],
)
def test_anything_but_a_well_formed_batch_is_left_whole_for_decoding_to_judge(payload: bytes) -> None:
    assert unpack(payload) == [payload]


def test_a_batch_larger_than_one_communicate_may_be_is_not_split() -> None:
    big = pack([b"\x80" * (MAX_COMMUNICATE_BYTES // 2 + 1)] * 2)
    assert is_batch(big) and unpack(big) == [big]


def test_runs_batch_consecutive_communicates_on_one_key_and_keep_every_order() -> None:
    p = payloads(6)
    items = [(A, p[0]), (A, p[1]), (B, p[2]), ("roco/human/out", b"x"), ("roco/human/out", b"y"), (A, p[3])]
    out = list(runs(items, lambda key: key.startswith("roco/fipa/")))
    assert [(key, count) for key, _, count in out] == [
        (A, 2),
        (B, 1),
        ("roco/human/out", 1),  # not a communicate key: never batched
        ("roco/human/out", 1),
        (A, 1),
    ]
    assert unpack(out[0][1]) == [p[0], p[1]] and out[1][1] == p[2] and out[4][1] == p[3]
    assert out[2][1] == b"x" and out[3][1] == b"y"


def test_runs_bound_a_batch_by_count_and_by_bytes() -> None:
    small = payloads(1)[0]
    counts = [c for _, _, c in runs([(A, small)] * (BATCH_MAX_COMMUNICATES + 3), lambda _: True)]
    assert counts == [BATCH_MAX_COMMUNICATES, 3]
    big = b"\x80" * (BATCH_MAX_BYTES // 2)
    out = list(runs([(A, big), (A, big), (A, big)], lambda _: True))
    assert [c for _, _, c in out] == [2, 1]  # the third would pass the byte bound
    assert unpack(out[0][1]) == [big, big] and out[1][1] == big


@pytest.mark.parametrize("n", [2, 15, 16, 300, 70_000])
def test_count_reads_a_batch_header(n: int) -> None:
    """fixarray (≤ 15), array 16 and array 32 headers."""
    parts = [b"\x80"] * n
    assert count(pack(parts)) == n
    assert count(payloads(1)[0]) == 1


def test_join_flattens_batches_in_order_and_leaves_one_payload_as_it_is() -> None:
    a, b, c, d = payloads(4)
    assert join([a]) is a
    assert join([pack([b, c])]) == pack([b, c])
    joined = join([a, pack([b, c]), d])
    assert unpack(joined) == [a, b, c, d]
    assert not any(is_batch(p) for p in unpack(joined))


def test_join_keeps_a_malformed_batch_as_one_item() -> None:
    a, b = payloads(2)
    bad = b"\x92\xc4\x01"  # an array cut short
    assert unpack(join([a, bad, b])) == [a, bad, b]
