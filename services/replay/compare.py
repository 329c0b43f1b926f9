"""A replayed communicate beside the recorded one: equal up to identifiers and clock readings.

Compared, parameter by parameter (FIPA SC00061 §2): performative, sender, receiver, reply-to,
language, encoding, ontology, protocol, user-defined parameters, and the content, decoded in its
language and compared term by term (a reason in UTF-8 text as text).

- Identifiers (conversation-id, reply-with, in-reply-to) are compared through :class:`IdMap`:
  the first time a recorded identifier meets a replayed one they are paired, and from then on
  each stands for the other only (the same pairing both ways), so a reference to the wrong
  conversation or reply is still a difference. A content string that is a paired identifier,
  and a paired identifier inside a UTF-8 reason, are compared the same way.
- reply-by (a time) is compared as the time it leaves after the communicate was sent:
  recorded, after its sender's timestamp; replayed, after the replay's clock when it was sent;
  equal within :data:`TIME_TOLERANCE_S`.
- A content field marked as read from the sender's clock (``Annotated[float, CLOCK]``,
  shared/fipa_codec/languages/common.py: a plan's ``planning_time_s``, a status's
  ``deadline_in_s``) is not compared.
"""

from __future__ import annotations

import enum
import functools
import math
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import msgspec

from services.replay.record import Recorded
from shared.fipa_codec import AgentIdentifier, Communicate
from shared.fipa_codec.languages import ContentError, decode_content

TIME_TOLERANCE_S = 1.0
"""How far (s) the time a reply-by leaves may differ between run and replay: the run's clock
moved on while the agent computed, the replay's stands still."""
_PARAMETERS = (
    "performative",
    "sender",
    "receiver",
    "reply_to",
    "language",
    "encoding",
    "ontology",
    "protocol",
)
_IDS = ("conversation_id", "reply_with", "in_reply_to")


@dataclass(frozen=True)
class Difference:
    """One difference: the recorded communicate it is about (``seq`` in the traffic record,
    ``t`` s since the run began, ``what`` it was: ``a_pl → a_co inform (fipa-request)``; a
    replayed communicate with no recorded one has ``seq`` None), the ``field`` (a parameter in
    FIPA's name, ``content.<path>``, or ``communicate`` when one side has none), and each side's
    value as text."""

    seq: int | None
    t: float
    what: str
    field: str
    recorded: str
    replayed: str

    def line(self) -> str:
        where = f"#{self.seq}" if self.seq is not None else "(none)"
        return (
            f"{where} at {self.t:7.3f} s {self.what}: {self.field}: "
            f"recorded {self.recorded}, replayed {self.replayed}"
        )


class IdMap:
    """The pairing of recorded identifiers with replayed ones (one to one)."""

    def __init__(self) -> None:
        self.replayed_of: dict[str, str] = {}
        self.recorded_of: dict[str, str] = {}

    def pair(self, recorded: str, replayed: str) -> str | None:
        """Pair ``recorded`` with ``replayed``, or check that they are paired; None when they
        are (now), else why not."""
        known, back = self.replayed_of.get(recorded), self.recorded_of.get(replayed)
        if known is None and back is None:
            self.replayed_of[recorded] = replayed
            self.recorded_of[replayed] = recorded
            return None
        if known == replayed:
            return None
        if known is not None:
            return f"{replayed} (where {recorded} was replayed as {known})"
        return f"{replayed} (which stands for {back})"

    def replayed(self, recorded: str) -> str:
        """The replayed identifier ``recorded`` is paired with (itself when none yet)."""
        return self.replayed_of.get(recorded, recorded)

    def renamed(self) -> Iterator[tuple[str, str]]:
        """The pairs of two different identifiers (generated anew in the replay)."""
        return ((a, b) for a, b in self.replayed_of.items() if a != b)


def compare(
    recorded: Recorded, replayed: Communicate, replayed_at: float, ids: IdMap, t0: float
) -> list[Difference]:
    """The differences of ``replayed`` (sent when the replay's clock read ``replayed_at``, POSIX
    s) from ``recorded`` of a run begun at ``t0`` (POSIX s); pairs their identifiers in ``ids``
    as it goes."""
    rec = recorded.comm
    out: list[tuple[str, str, str]] = []
    for name in _PARAMETERS:
        a, b = getattr(rec, name), getattr(replayed, name)
        if a != b:
            out.append((_fipa(name), _text(a), _text(b)))
    for name in _IDS:
        a, b = getattr(rec, name), getattr(replayed, name)
        if a is None or b is None:
            if a != b:
                out.append((_fipa(name), _text(a), _text(b)))
            continue
        why = ids.pair(a, b)
        if why is not None:
            out.append((_fipa(name), a, why))
    out += _reply_by(rec.reply_by, recorded.sent, replayed.reply_by, replayed_at)
    if rec.user_params != replayed.user_params:
        out.append(("user-parameters", _text(rec.user_params), _text(replayed.user_params)))
    out += _content(rec, replayed, ids)
    return [Difference(recorded.seq, recorded.t - t0, recorded.line, f, a, b) for f, a, b in out]


def _reply_by(a: float | None, a_sent: float, b: float | None, b_sent: float) -> list[tuple[str, str, str]]:
    if a is None or b is None:
        return [] if a == b else [("reply-by", _text(a), _text(b))]
    left_a, left_b = a - a_sent, b - b_sent
    if abs(left_a - left_b) <= TIME_TOLERANCE_S:
        return []
    return [("reply-by", f"{left_a:.3f} s after sending", f"{left_b:.3f} s after sending")]


def _content(a: Communicate, b: Communicate, ids: IdMap) -> list[tuple[str, str, str]]:
    if a.content == b.content:
        return []
    term_a, term_b = _read(a), _read(b)
    if isinstance(term_a, str) and isinstance(term_b, str):  # two reasons in words
        for old, new in ids.renamed():
            term_a = term_a.replace(old, new)
        return [] if term_a == term_b else [("content", repr(term_a), repr(term_b))]
    if isinstance(term_a, msgspec.Struct) and a.language == b.language:
        return list(_terms("content", term_a, term_b, ids))
    return [("content", _text(term_a), _text(term_b))]


def _read(comm: Communicate) -> msgspec.Struct | str:
    """The content of ``comm``: a term of its language, or a reason in words (UTF-8 text, or
    what does not decode, said so)."""
    if comm.language is None or comm.encoding == "utf-8":
        return comm.content.decode("utf-8", "replace")
    try:
        return decode_content(comm.language, comm.content)
    except ContentError as exc:
        return f"(does not decode in {comm.language}: {exc})"


def _terms(path: str, a: object, b: object, ids: IdMap) -> Iterator[tuple[str, str, str]]:
    """The differences of term ``b`` from term ``a`` at ``path`` and below it."""
    if isinstance(a, msgspec.Struct) and type(a) is type(b):
        return _fields(path, a, b, ids)
    if isinstance(a, list | tuple) and isinstance(b, list | tuple):
        return _items(path, a, b, ids)
    if isinstance(a, dict) and isinstance(b, dict):
        return _entries(path, a, b, ids)
    return _leaf(path, a, b, ids)


def _fields(path: str, a: msgspec.Struct, b: object, ids: IdMap) -> Iterator[tuple[str, str, str]]:
    skip = clock_fields(type(a))
    for name in a.__struct_fields__:
        if name not in skip:
            yield from _terms(f"{path}.{name}", getattr(a, name), getattr(b, name), ids)


def _items(path: str, a: Sequence[object], b: Sequence[object], ids: IdMap) -> Iterator[tuple[str, str, str]]:
    for i, (x, y) in enumerate(zip(a, b, strict=False)):
        yield from _terms(f"{path}[{i}]", x, y, ids)
    if len(a) != len(b):
        yield (f"{path} length", str(len(a)), str(len(b)))


def _entries(
    path: str, a: dict[object, object], b: dict[object, object], ids: IdMap
) -> Iterator[tuple[str, str, str]]:
    for k in [*a, *(k for k in b if k not in a)]:
        if k in a and k in b:
            yield from _terms(f"{path}[{k!r}]", a[k], b[k], ids)
        else:
            yield (f"{path}[{k!r}]", _text(a.get(k)), _text(b.get(k)))


def _leaf(path: str, a: object, b: object, ids: IdMap) -> Iterator[tuple[str, str, str]]:
    if isinstance(a, str) and isinstance(b, str) and a in ids.replayed_of:  # an identifier
        why = ids.pair(a, b)
        if why is not None:
            yield (path, a, why)
    elif not _same(a, b):
        yield (path, _text(a), _text(b))


def _same(a: object, b: object) -> bool:
    if type(a) is not type(b):
        return False
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return a == b


@functools.cache
def clock_fields(kind: type) -> frozenset[str]:
    """The fields of Struct type ``kind`` marked as read from the sender's clock (``CLOCK``)."""
    info = msgspec.inspect.type_info(kind)
    if not isinstance(info, msgspec.inspect.StructType):
        return frozenset()
    return frozenset(f.name for f in info.fields if _clocked(f.type))


def _clocked(t: msgspec.inspect.Type) -> bool:
    if isinstance(t, msgspec.inspect.Metadata):
        return bool((t.extra or {}).get("clock"))
    if isinstance(t, msgspec.inspect.UnionType):
        return any(_clocked(u) for u in t.types)
    return False


def _fipa(name: str) -> str:
    """A parameter's name as FIPA writes it (``conversation_id`` → ``conversation-id``)."""
    return name.replace("_", "-")


def _text(value: object) -> str:
    """``value`` as a person reads it in a difference's line."""
    if isinstance(value, tuple) and value and all(isinstance(v, AgentIdentifier) for v in value):
        return ",".join(v.name for v in value)
    for kind, shown in _SHOWN:
        if isinstance(value, kind):
            return shown(value)
    return str(value)


_SHOWN: tuple[tuple[type, Callable[[Any], str]], ...] = (
    (type(None), lambda _: "(none)"),
    (enum.Enum, lambda v: str(v.value)),
    (AgentIdentifier, lambda v: v.name),
    (msgspec.Struct, lambda v: type(v).__name__),
    (str, repr),
)
"""How a value of each kind is written in a difference's line (else ``str``)."""
