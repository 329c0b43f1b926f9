"""Duplicate suppression: no communicate is acted on twice.

A communicate can arrive more than once: its sender retransmits it until answered
(:class:`services.runtime.replies.PendingReplies`, ``retry_s``), or the network
duplicates it (``roco fault msg --duplicate``). Retransmissions are byte-identical, so an
agent recognises a copy by a digest of its bytes. A copy is dropped before it reaches the
agent's input buffer; when the agent has already answered the original, its answers are
published again, because the copy means the sender has not heard them (FIPA SC00061 §2.4:
reply-with identifies what an answer is in reply to).

Memory is bounded: the last ``capacity`` digests and the answers to the last ``capacity``
requests are kept (least recently used dropped first). After a restart an agent remembers
nothing: agents that must not repeat work after a restart persist what they accepted
(a_co's queue, a_hi's open commands), and their participant roles recognise a repeated
request by its reply-with (services/runtime/roles/).
"""

from __future__ import annotations

from collections import OrderedDict

try:  # wire_digest's BLAKE2, built into CPython; ``hashlib`` would also load OpenSSL (≈ 3.4 MiB)
    from _blake2 import blake2b
except ImportError:  # pragma: no cover - an interpreter without the built-in module
    from hashlib import blake2b

DEFAULT_CAPACITY = 4096
ANSWERS_PER_REQUEST = 16
"""Answers kept per request, the first ones: what a copy of the request gets again (its agree
or refuse and the first results). A subscription's stream of informs answers one request for
as long as it lasts; keeping them all grew an agent by every inform it streamed (20,000 informs
of the benchmark: ≈ 10 MiB), and a copy of the subscribe would have had them all sent again."""


def digest(payload: bytes) -> tuple[int, int]:
    """A 128-bit digest of an encoded communicate: CPython's hash of its bytes and of them after
    a zero byte, two 64-bit values of SipHash-1-3 keyed at random per process (PEP 456;
    distinct communicates share both with a chance of ≈ 2⁻¹²⁸, and no peer knows the key to
    make them). ≈ 0.15 µs for 400 bytes, where BLAKE2b took 0.75 µs (timeit, CPython 3.11):
    asked of every communicate received."""
    data = payload if type(payload) is bytes else bytes(payload)  # a bytearray has no hash
    return hash(data), hash(b"\0" + data)


def wire_digest(key: str, payload: bytes) -> bytes:
    """A 16-byte BLAKE2b digest of an encoded communicate and the Zenoh key it crossed on: equal
    for a communicate and its copies (retransmitted, sent again as answers to a copy, or
    duplicated by the network), as an observer of the whole wire tells them apart (the
    traffic record's loader, ``roco sniff``)."""
    return blake2b(key.encode() + b"\0" + payload, digest_size=16).digest()


class Dedup:
    """Digests of received communicates and the answers sent to each request.

    ``capacity``: how many digests and how many answered requests are remembered."""

    def __init__(self, capacity: int = DEFAULT_CAPACITY) -> None:
        if capacity < 1:
            raise ValueError(f"capacity must be at least 1, not {capacity}")
        self.capacity = capacity
        self._seen: OrderedDict[int, int] = OrderedDict()
        self._answers: OrderedDict[tuple[str, str], list[tuple[str, bytes]]] = OrderedDict()

    def seen(self, payload: bytes) -> bool:
        """True when ``payload`` was received before (it is a copy); else remember it."""
        first, second = digest(payload)
        known = self._seen.get(first)
        if known is not None:
            self._seen.move_to_end(first)
            if known == second:
                return True
        # kept as first half → second half: ints, which the garbage collector does not track
        # (a tuple per communicate kept would be); a communicate whose first half is another's
        # (a chance of 2⁻⁶⁴ per pair) takes its place
        self._seen[first] = second
        if len(self._seen) > self.capacity:
            self._seen.popitem(last=False)
        return False

    def answered(self, peer: str, in_reply_to: str, key: str, payload: bytes) -> None:
        """Remember an answer sent to ``peer``'s communicate whose reply-with is ``in_reply_to``
        (the first :data:`ANSWERS_PER_REQUEST` of each)."""
        k = (peer, in_reply_to)
        answers = self._answers.get(k)
        if answers is None:
            answers = self._answers[k] = []
            if len(self._answers) > self.capacity:
                self._answers.popitem(last=False)
        else:
            self._answers.move_to_end(k)
        if len(answers) < ANSWERS_PER_REQUEST:
            answers.append((key, payload))

    def answers(self, peer: str, reply_with: str | None) -> list[tuple[str, bytes]]:
        """The answers already sent to ``peer``'s communicate ``reply_with``, in order."""
        if reply_with is None:
            return []
        return list(self._answers.get((peer, reply_with), ()))
