"""The requirement properties that can be violated as they happen, followed over traffic in
arrival order.

A property is violated *live* when a communicate one of its ``absent`` steps forbids comes in
a partial match that bound its situation (services/spec/properties.py;
services/spec_check/properties.py ``Monitor.violation``); the rest of the language says only
at the run's end that a property did not follow, so :class:`LiveMonitor` follows only the
properties with an absent step.

Traffic arrives in arrival order, not causal order (services/recorder/causal.py: an answer can
arrive before what it answers). :class:`CausalFeed` holds a communicate whose ``in-reply-to``
names a ``reply-with`` not yet fed, until that one comes, or until :data:`HOLD` further
communicates arrived (what it answers may never be recorded): then it is fed as it is. A copy
(the same bytes again on the same key: services/runtime/dedup.py) is fed once.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

from services.recorder.causal import Token, answered, offered
from services.recorder.flags import LiveFlag
from services.report.load import Message
from services.spec.properties import Property
from services.spec_check.properties import Monitor, Outcome

HOLD = 64
"""How many communicates an answer waits at most for what it answers (arrival order)."""
SEEN = 4096
"""How many reply-with tokens fed are remembered (the oldest forgotten first): an answer to a
communicate older than that is held :data:`HOLD` communicates, then fed as it is."""


@dataclass
class CausalFeed:
    """Arrival order in, causal order out as far as known (module docstring)."""

    hold: int = HOLD
    _arrived: int = 0
    _seen: OrderedDict[Token, None] = field(default_factory=OrderedDict)
    _waiting: dict[Token, list[tuple[int, Message]]] = field(default_factory=dict)

    def push(self, m: Message) -> list[Message]:
        """Take the next communicate to arrive; return those to evaluate now, in order."""
        self._arrived += 1
        out: list[Message] = []
        token = answered(m)
        if token is not None and token not in self._seen:
            self._waiting.setdefault(token, []).append((self._arrived, m))
        else:
            self._emit(m, out)
        overdue = [t for t, held in self._waiting.items() if held[0][0] + self.hold <= self._arrived]
        for t in overdue:
            for _, late in self._waiting.pop(t, []):
                self._emit(late, out)
        return out

    def flush(self) -> list[Message]:
        """Everything still held, in arrival order (the traffic ended)."""
        held = sorted((x for xs in self._waiting.values() for x in xs), key=lambda x: x[0])
        self._waiting.clear()
        out: list[Message] = []
        for _, m in held:
            self._emit(m, out)
        return out

    def _emit(self, m: Message, out: list[Message]) -> None:
        out.append(m)
        token = offered(m)
        if token is None:
            return
        self._seen[token] = None
        if len(self._seen) > SEEN:
            self._seen.popitem(last=False)
        for _, later in self._waiting.pop(token, []):
            self._emit(later, out)


def live_properties(requirements: Iterable[tuple[str, Sequence[Property]]]) -> list[tuple[str, Property]]:
    """(requirement id, property) of every property that has an ``absent`` step, from
    (requirement id, its properties) pairs."""
    return [(rid, p) for rid, props in requirements for p in props if any(s.absent for s in p.steps)]


class LiveMonitor:
    """The properties ``watched`` ((requirement id, property) pairs) over one run's traffic:
    :meth:`arrive` takes each communicate as it arrives and returns the flags it raised."""

    def __init__(self, watched: Sequence[tuple[str, Property]], hold: int = HOLD) -> None:
        self._monitors = [(rid, Monitor(p)) for rid, p in watched]
        self.channels = frozenset(s.channel for _, p in watched for s in p.steps)
        """The channels the watched properties are about (others need not be fed)."""
        self._feed = CausalFeed(hold)

    def arrive(self, m: Message) -> list[tuple[str, Outcome, Message]]:
        """Take the next communicate to arrive; the properties it (or what it released)
        violated, each once: (requirement id, outcome, the violating communicate)."""
        return self._evaluate(self._feed.push(m))

    def end(self) -> list[tuple[str, Outcome, Message]]:
        """The traffic ended: evaluate what was still held."""
        return self._evaluate(self._feed.flush())

    def _evaluate(self, ordered: list[Message]) -> list[tuple[str, Outcome, Message]]:
        raised: list[tuple[str, Outcome, Message]] = []
        for m in ordered:
            for rid, monitor in self._monitors:
                if monitor.violation is not None:
                    continue
                monitor.feed(m)
                if monitor.violation is not None:
                    raised.append((rid, monitor.outcome(final=False), m))
        return raised


def describe(m: Message) -> str:
    """A communicate in words: ``C1 a_ta → a_co inform SWStatus state=Preempted (conversation
    cmd-…-exec2)``."""
    content = type(m.content).__name__ if m.content is not None else ""
    state = getattr(m.content, "state", None)
    said = f" state={getattr(state, 'value', state)}" if state is not None else ""
    to = ", ".join(m.rec.receivers)
    words = " ".join(w for w in (m.channel, f"{m.sender} → {to}", m.performative, content) if w)
    return f"{words}{said} (conversation {m.conversation})"


def flag_of(rid: str, outcome: Outcome, m: Message, recorded: int, flagged: float) -> LiveFlag:
    """The flag of ``outcome`` (violated by ``m`` when ``recorded`` communicates had arrived,
    raised at POSIX time ``flagged``) of a property of requirement ``rid``."""
    return LiveFlag(
        requirement=rid,
        prop=outcome.prop.text,
        event=describe(m),
        why=outcome.forbidden(),
        t=m.rec.t,
        seq=m.rec.seq,
        recorded=recorded,
        flagged=flagged,
    )
