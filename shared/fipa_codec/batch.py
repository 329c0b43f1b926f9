"""Several encoded communicates to one receiver in one payload: a batch.

When one step of an agent puts more than one communicate on the same key (the same channel,
sender and receiver: a stream of informs, a reply and a request), they travel as one Zenoh
sample: each publication, route and delivery costs once for the batch instead of once per
communicate (one pair streaming informs, 256 a step: 1.4–1.9 × the rate with one put per
communicate on the 2-core VM of docs/benchmarks.md, "One put for what one step sends to one
receiver"). Nothing waits to fill a batch: it holds what the step's output buffer already holds,
or what waited behind a put in progress on its key (:func:`join`; services/runtime/backlog.py).

On the wire a batch is a msgpack array of ``bin`` items, each one encoded communicate exactly
as :func:`shared.fipa_codec.encoding.encode` writes it (a msgpack map), in the order sent. The
first byte tells the two apart: a communicate starts with a map header (``0x80``–``0x8f``,
``0xde``, ``0xdf``), a batch with an array header (``0x90``–``0x9f``, ``0xdc``, ``0xdd``). A
single communicate is never wrapped, so what a step sends once per key is on the wire as before.

Every communicate of a batch is checked as if it had come alone (size, decoding, sender binding,
interface, protocol state, duplicates): :func:`unpack` only splits. A reader that does not know
batches fails to decode one as a communicate (an array where a map must be) and answers
``not-understood``, as for any malformed payload.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence

import msgspec

from shared.fipa_codec.encoding import MAX_COMMUNICATE_BYTES

BATCH_MAX_COMMUNICATES = 256
"""Most communicates :func:`runs` puts into one batch."""
BATCH_MAX_BYTES = 256 * 1024
"""Most bytes of communicates :func:`runs` puts into one batch (a larger communicate goes
alone); far below :data:`MAX_COMMUNICATE_BYTES`, the most :func:`unpack` splits."""

_encode = msgspec.msgpack.Encoder().encode
_decode = msgspec.msgpack.Decoder(list[bytes]).decode
BATCH_HEADS = frozenset(range(0x90, 0xA0)) | {0xDC, 0xDD}
"""The first bytes of a batch (msgpack array headers); a communicate starts with a map's."""


def pack(payloads: Sequence[bytes]) -> bytes:
    """One batch of encoded communicates (``payloads``, in order; at least two)."""
    return _encode(payloads)


def is_batch(payload: bytes | bytearray | memoryview) -> bool:
    """Whether ``payload`` is a batch (its first byte a msgpack array header), not one
    communicate. Looks at one byte only: :func:`unpack` checks the rest."""
    return len(payload) > 0 and payload[0] in BATCH_HEADS


def unpack(payload: bytes) -> list[bytes]:
    """The encoded communicates of ``payload``: its items when it is a well-formed batch of
    at most :data:`MAX_COMMUNICATE_BYTES`, else ``[payload]`` itself (one communicate, or one
    malformed or oversized payload that the receiver's decoding rejects and answers with
    ``not-understood``). Raises nothing."""
    if not is_batch(payload) or len(payload) > MAX_COMMUNICATE_BYTES:
        return [payload]
    try:
        parts = _decode(payload)
    except (msgspec.DecodeError, msgspec.ValidationError):
        return [payload]
    return parts if parts else [payload]


def count(payload: bytes | bytearray | memoryview) -> int:
    """How many communicates ``payload`` carries, read from its msgpack array header: a batch's
    item count, 1 for anything else (one communicate). Looks at ≤ 5 bytes; a malformed batch
    may be miscounted (it only bounds what is joined to it: :func:`join`)."""
    if not is_batch(payload):
        return 1
    head = payload[0]
    if head == 0xDC:
        return int.from_bytes(payload[1:3], "big")
    if head == 0xDD:
        return int.from_bytes(payload[1:5], "big")
    return head & 0x0F


def join(payloads: Sequence[bytes]) -> bytes:
    """One payload carrying the communicates of ``payloads`` (each one communicate or a batch;
    at least one), in order: the only one as it is, else one batch of all their communicates
    (a batch's items taken out of it: batches never nest). A malformed batch
    (:func:`unpack`) travels as one item, which its receiver answers with not-understood as if
    it had come alone."""
    if len(payloads) == 1:
        return payloads[0]
    parts: list[bytes] = []
    for payload in payloads:
        if is_batch(payload):
            parts.extend(unpack(payload))
        else:
            parts.append(payload)
    return pack(parts)


def runs(
    items: Sequence[tuple[str, bytes]], batched: Callable[[str], bool]
) -> Iterator[tuple[str, bytes, int]]:
    """What to put for an output buffer ``items`` of (key, encoded communicate or other
    payload), in order: (key, payload, how many communicates it carries). Consecutive items on
    one key for which ``batched(key)`` is True go as one batch of at most
    :data:`BATCH_MAX_COMMUNICATES` and :data:`BATCH_MAX_BYTES`; everything else goes as it is
    (count 1). The order of all items is kept."""
    n = len(items)
    i = 0
    while i < n:
        key, payload = items[i]
        j, size = i + 1, len(payload)
        if batched(key):
            while j < n and j - i < BATCH_MAX_COMMUNICATES and items[j][0] == key:
                size += len(items[j][1])
                if size > BATCH_MAX_BYTES:
                    break
                j += 1
        if j - i == 1:
            yield key, payload, 1
        else:
            yield key, pack([p for _, p in items[i:j]]), j - i
        i = j
