"""The answer to a person's question about the kitchen (questions.py): the SPARQL SELECT a_hi
sends a_km on C7 (``query-ref`` of an L_WM ``SparqlQuery``; a_km answers ``inform-ref`` with an
``Answer``), and the one sentence a_hi makes of its rows, saying when the knowledge is from.

Every query answers rows ``(thing IRI, property IRI, value)`` — the values of ``roco:in``,
``roco:on``, ``roco:heldBy``, ``roco:particles``, ``roco:capacity``, ``roco:seenAt`` and
``roco:contentSeenAt`` (services/agents/knowledge/o_roco.ttl) of the thing asked about and of
the things in or on it, or, for "what did you see", of every object a_ta has seen — at most
:data:`ROW_LIMIT` rows. ``roco:seenAt`` is a_ta's wall clock when it received the observation
that saw the thing, ``roco:contentSeenAt`` the one that counted its content (POSIX s); "40 s ago"
is measured from them on a_hi's clock (``Agent.sources``), so the two hosts' clocks must agree.

Pure functions; no state, no I/O.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence

from services.agents.human_interface.intents import WorldQuestion, show
from services.agents.human_interface.vocabulary import ROCO_IRI, local_name

ROW_LIMIT = 200
"""The most rows a question's query asks for (its ``LIMIT``)."""
NO_KNOWLEDGE = "I cannot reach my knowledge now; ask me again in a moment."
"""The answer when a_km is away, refuses, fails or does not answer in time."""

_PROPERTIES = ("in", "on", "heldBy", "particles", "capacity", "seenAt", "contentSeenAt")

Facts = dict[str, dict[str, list[str]]]
"""thing (O_RoCo name) → property (local name) → values (names for IRIs, lexical forms)."""


def question_query(q: WorldQuestion) -> str:
    """The SPARQL SELECT for ``q`` (rows: thing, property, value). Raises ValueError for a
    question about a thing when ``q.thing`` is None, or for ``abilities`` (no query)."""
    props = " ".join(f"roco:{p}" for p in _PROPERTIES)
    if q.kind == "seen":
        return (
            "SELECT ?thing ?property ?value WHERE { ?thing roco:seenAt ?seen . ?thing ?property ?value .\n"
            f"  VALUES ?property {{ {props} }}\n"
            "  FILTER NOT EXISTS { ?thing a ?c . ?c rdfs:subClassOf* roco:RobotPart } }\n"
            f"LIMIT {ROW_LIMIT}"
        )
    if q.kind == "abilities" or q.thing is None:
        raise ValueError(f"a question of kind {q.kind!r} with no thing asks a_km nothing")
    x = f"<{ROCO_IRI}{q.thing}>"
    return (
        "SELECT ?thing ?property ?value WHERE {\n"
        f"  {{ BIND({x} AS ?thing) ?thing ?property ?value . VALUES ?property {{ {props} }} }}\n"
        f"  UNION {{ ?thing roco:in|roco:on {x} . ?thing ?property ?value .\n"
        "    VALUES ?property { roco:in roco:on roco:seenAt }\n"
        "    FILTER NOT EXISTS { ?thing a roco:Content } }\n"
        f"}} LIMIT {ROW_LIMIT}"
    )


def facts_of(rows: Iterable[Sequence[str | None]]) -> Facts:
    """The rows of an answer to :func:`question_query` as :data:`Facts` (rows it does not
    understand skipped)."""
    facts: Facts = {}
    for row in rows:
        if len(row) < 3 or row[0] is None or row[1] is None or row[2] is None:
            continue
        prop = local_name(row[1])
        value = local_name(row[2]) if row[2].startswith(ROCO_IRI) else row[2]
        facts.setdefault(local_name(row[0]), {}).setdefault(prop, []).append(value)
    return facts


def ago(seconds: float) -> str:
    """A time since, in words: "just now", "40 s ago", "3 min ago", "2 h ago"."""
    if seconds < 1.5:
        return "just now"
    if seconds < 90:
        return f"{seconds:.0f} s ago"
    if seconds < 90 * 60:
        return f"{seconds / 60:.0f} min ago"
    return f"{seconds / 3600:.0f} h ago"


def _cap(text: str) -> str:
    return text[:1].upper() + text[1:]


def _and(names: Sequence[str]) -> str:
    shown = [show(n) for n in sorted(names)]
    return shown[0] if len(shown) == 1 else ", ".join(shown[:-1]) + " and " + shown[-1]


def _number(props: dict[str, list[str]], prop: str) -> float | None:
    values = props.get(prop)
    try:
        return float(values[0]) if values else None
    except ValueError:
        return None


def _spheres(n: int) -> str:
    return f"{n} sphere" + ("" if n == 1 else "s")


class _Known:
    """What the facts say of one thing, with the time now (a_hi's clock, POSIX s)."""

    def __init__(self, facts: Facts, name: str, now: float) -> None:
        self.name = name
        self.props = facts.get(name, {})
        self.facts = facts
        self.now = now
        particles = _number(self.props, "particles")
        self.particles = int(particles) if particles is not None else None
        capacity = _number(self.props, "capacity")
        self.capacity = int(capacity) if capacity is not None else None
        self.seen = _number(self.props, "seenAt")
        self.counted = _number(self.props, "contentSeenAt")

    def when(self) -> str:
        """ ", 40 s ago" after "when I last looked" (into it: when its content was counted);
        empty when that time is unknown."""
        return f", {ago(max(0.0, self.now - self.counted))}" if self.counted is not None else ""

    def where(self) -> tuple[str, str] | None:
        for relation in ("heldBy", "in", "on"):
            if self.props.get(relation):
                return relation, self.props[relation][0]
        return None

    def where_words(self) -> str:
        at = self.where()
        if at is None:
            return ""
        relation, place = at
        if relation == "heldBy":
            side = place.removesuffix("_gripper")
            return f"in my {side} hand" if side in ("left", "right") else "in my hand"
        return f"{relation} {show(place)}"

    def inside(self, relation: str = "in") -> list[str]:
        return [t for t, p in self.facts.items() if t != self.name and self.name in p.get(relation, ())]

    def looked(self) -> str:
        """ "The bowl held 18 spheres when I last looked, 40 s ago" (its particles known)."""
        assert self.particles is not None
        empty = ": it was empty" if self.particles == 0 else ""
        return (
            f"{_cap(show(self.name))} held {_spheres(self.particles)} when I last looked{self.when()}{empty}"
        )


def answer_text(q: WorldQuestion, rows: Iterable[Sequence[str | None]], now: float) -> str:
    """The one sentence answering ``q`` from the rows of a_km's answer to
    :func:`question_query`; ``now``: a_hi's wall clock (POSIX s). What the rows do not hold is
    said to be unknown ("I have not looked into the bowl yet"). Raises ValueError for
    ``abilities`` (answered without a_km) or a kind it does not know."""
    facts = facts_of(rows)
    if q.kind == "seen":
        return _seen(facts, now)
    answer = _ANSWERS.get(q.kind)
    if answer is None or q.thing is None:
        raise ValueError(f"no answer from a_km's rows for a question of kind {q.kind!r}")
    return answer(q, _Known(facts, q.thing, now))


def _are(things: Sequence[str]) -> str:
    """ "the cup is", "the cup and the jar are"."""
    return f"{_and(things)} {'is' if len(things) == 1 else 'are'}"


def _where(q: WorldQuestion, k: _Known) -> str:
    it = show(k.name)
    if k.where() is None:
        return f"I do not know where {it} is."
    seen = ", as far as I know" if k.seen is None else f"; I last saw it {ago(max(0.0, k.now - k.seen))}"
    return f"{_cap(it)} is {k.where_words()}{seen}."


def _located(q: WorldQuestion, k: _Known) -> str:
    at = k.where()
    if at is None:
        return f"I do not know where {show(k.name)} is."
    yes = at[1] == q.place and at[0] in ("in", "on")
    return f"{'Yes' if yes else 'No'}, {show(k.name)} is {k.where_words()}, as far as I know."


def _on(q: WorldQuestion, k: _Known) -> str:
    on = k.inside("on")
    if not on:
        return f"Nothing is on {show(k.name)}, as far as I know."
    return f"On {show(k.name)}: {_and(on)}, as far as I know."


def _contents(q: WorldQuestion, k: _Known) -> str:
    it, things = show(k.name), k.inside("in")
    if q.kind == "count" and q.counted == "things":
        n = len(things)
        listed = f": {_and(things)}" if things else ""
        return f"{n} thing{'' if n == 1 else 's'} in {it}, as far as I know{listed}."
    if k.particles is not None:
        return f"{k.looked()}{f'; {_are(things)} in it too' if things else ''}."
    if things:
        return f"{_cap(_are(things))} in {it}, as far as I know."
    if k.capacity is not None:
        return f"I have not looked into {it} yet."
    return f"Nothing is in {it}, as far as I know."


def _empty(q: WorldQuestion, k: _Known) -> str:
    it, things = show(k.name), k.inside("in")
    if things:
        return f"No, {_are(things)} in {it}, as far as I know."
    if k.particles is None:
        return f"I do not know: I have not looked into {it} yet."
    if k.particles == 0:
        return f"Yes, {it} was empty when I last looked{k.when()}."
    return f"No, {it} held {_spheres(k.particles)} when I last looked{k.when()}."


def _full(q: WorldQuestion, k: _Known) -> str:
    it = show(k.name)
    if k.particles is None:
        return f"I do not know: I have not looked into {it} yet."
    if k.capacity is None:
        held = f"it held {_spheres(k.particles)} when I last looked{k.when()}"
        return f"I do not know how much {it} takes; {held}."
    full = "Yes" if k.particles >= k.capacity else "No"
    return (
        f"{full}, {it} held {k.particles} of the {k.capacity} spheres it takes when I last looked{k.when()}."
    )


_ANSWERS: dict[str, Callable[[WorldQuestion, _Known], str]] = {
    "where": _where,
    "located": _located,
    "on": _on,
    "contents": _contents,
    "count": _contents,
    "empty": _empty,
    "full": _full,
}
"""The sentence of each kind of question about one thing."""


def _seen(facts: Facts, now: float) -> str:
    seen = sorted(
        ((t, s) for t in facts if (s := _number(facts[t], "seenAt")) is not None),
        key=lambda ts: (-ts[1], ts[0]),
    )
    if not seen:
        return "I have not looked at anything yet."
    parts = []
    for name, at in seen:
        particles, counted = _number(facts[name], "particles"), _number(facts[name], "contentSeenAt")
        same_look = particles is not None and counted is not None and abs(counted - at) < 0.5
        inside = f", {_spheres(int(particles))} in it" if same_look and particles is not None else ""
        parts.append(f"{show(name)} {ago(max(0.0, now - at))}{inside}")
    return "I have seen " + "; ".join(parts) + "."


__all__ = ["NO_KNOWLEDGE", "ROW_LIMIT", "Facts", "ago", "answer_text", "facts_of", "question_query"]
