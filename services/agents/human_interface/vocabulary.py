"""The words a person may use for the kitchen's things, taken from the knowledge base (O_RoCo).

Nothing here is a list of objects: a :class:`Vocabulary` is built from the answer to
:data:`VOCABULARY_QUERY`, a SPARQL SELECT that a_hi sends a_km (``query-ref`` of an L_WM
``SparqlQuery`` on C7, see services/spec/robot_companion.toml) before it interprets a sentence.
So an individual stated in a_km's knowledge a moment ago can be named in the next sentence.

Where the words come from (O_RoCo, services/agents/knowledge/o_roco.ttl and kitchen.ttl):

- ``skos:prefLabel``, ``skos:altLabel`` and ``rdfs:label`` of an individual name it;
- the same labels of its classes and their superclasses name every individual of the class
  ("cup" names each ``roco:Cup``, "container" each ``roco:Container``);
- an individual with no label of its own is also named by its local name (``tea_pot``: "tea pot");
- ``roco:adjective`` values describe it ("small", "glass");
- ``roco:in`` / ``roco:on`` / ``roco:heldBy`` say where it is, so that "the cup on the table"
  can be told from "the cup in the cabinet";
- an individual of ``roco:Content`` ("the beans") stands for the container it is in.

:func:`Vocabulary.from_graph` runs the same query on an rdflib graph (tests, and a_hi's start
before a_km has answered: :func:`Vocabulary.from_files`).
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from rdflib import Graph

ROCO_IRI = "https://w3id.org/roco/O_RoCo#"

VOCABULARY_QUERY = """PREFIX skos: <http://www.w3.org/2004/02/skos/core#>
SELECT DISTINCT ?thing ?kind ?word WHERE {
  ?thing a ?class . ?class rdfs:subClassOf* roco:PhysicalObject .
  FILTER NOT EXISTS { ?class rdfs:subClassOf* roco:RobotPart }
  { ?thing skos:prefLabel|skos:altLabel|rdfs:label ?word . BIND("label" AS ?kind) }
  UNION { ?class rdfs:subClassOf* ?super . ?super skos:prefLabel|skos:altLabel|rdfs:label ?word .
          BIND("label" AS ?kind) }
  UNION { ?thing roco:adjective ?word . BIND("adjective" AS ?kind) }
  UNION { ?thing roco:in ?word . BIND("in" AS ?kind) }
  UNION { ?thing roco:on ?word . BIND("on" AS ?kind) }
  UNION { ?thing roco:heldBy ?word . BIND("heldBy" AS ?kind) }
  UNION { ?class rdfs:subClassOf* roco:Content . BIND("content" AS ?kind) BIND("" AS ?word) }
  UNION { BIND("name" AS ?kind) BIND("" AS ?word) }
}"""
"""a_hi's question to a_km: rows ``(thing IRI, kind, word)``; ``kind`` is ``label``,
``adjective``, ``in``/``on``/``heldBy`` (``word`` the place's IRI), ``content`` (``word``
empty) or ``name`` (``word`` empty: the thing is named by its local name too)."""

VARIABLES = ("thing", "kind", "word")
"""The answer's variables, in order."""


def words_of(text: str) -> tuple[str, ...]:
    """A label as the words a person types: lower case, letters and digits, ``_``/``-`` as
    spaces ("Kitchen_Table" → ("kitchen", "table"))."""
    return tuple(re.sub(r"[^a-z0-9]+", " ", text.lower().replace("'", "")).split())


def local_name(iri: str) -> str:
    """``https://w3id.org/roco/O_RoCo#cup`` → ``cup`` (other IRIs after their last ``#`` or ``/``)."""
    if iri.startswith(ROCO_IRI):
        return iri[len(ROCO_IRI) :]
    return re.split(r"[#/]", iri)[-1]


@dataclass(frozen=True)
class Thing:
    """An individual a person can name: its ``name`` in O_RoCo, the noun phrases naming it
    (``nouns``, tuples of words), the ``adjectives`` describing it, where it is (``relation``
    in/on/heldBy ``place``), and whether it is content (``content``: it stands for its
    container)."""

    name: str
    nouns: frozenset[tuple[str, ...]]
    adjectives: frozenset[str] = frozenset()
    relation: str | None = None
    place: str | None = None
    content: bool = False

    def where(self) -> str:
        """Where it is, in words: "in the cabinet", "on the table", "in your hand"; empty if unknown."""
        if self.place is None:
            return ""
        if self.relation == "heldBy":
            return "in my hand"
        return f"{self.relation or 'in'} the {self.place.replace('_', ' ')}"


@dataclass(frozen=True)
class Vocabulary:
    """The things a person can name, and the words for them (see the module docstring)."""

    things: tuple[Thing, ...] = ()
    nouns: frozenset[tuple[str, ...]] = field(init=False)
    adjectives: frozenset[str] = field(init=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "nouns", frozenset(n for t in self.things for n in t.nouns))
        object.__setattr__(self, "adjectives", frozenset(a for t in self.things for a in t.adjectives))

    def named(self, noun: tuple[str, ...]) -> list[Thing]:
        """The things ``noun`` names, in name order."""
        return sorted((t for t in self.things if noun in t.nouns), key=lambda t: t.name)

    def thing(self, name: str) -> Thing | None:
        """The thing called ``name`` in O_RoCo, or None."""
        return next((t for t in self.things if t.name == name), None)

    def examples(self, limit: int = 6) -> str:
        """Some of the things, for a reply: "the bowl, the cabinet, the cup, …" (content, which
        is named through its container, left out)."""
        names = [
            "the " + t.name.replace("_", " ")
            for t in sorted(self.things, key=lambda t: t.name)
            if not t.content
        ]
        more = ", …" if len(names) > limit else ""
        return (", ".join(names[:limit]) + more) if names else "nothing yet"

    @classmethod
    def from_rows(cls, rows: Iterable[Sequence[str | None]]) -> Vocabulary:
        """The vocabulary in an answer to :data:`VOCABULARY_QUERY` (``(thing, kind, word)`` rows,
        values as a_km gives them: IRIs in full, literals by their lexical form). Rows it does
        not understand are skipped."""
        nouns: dict[str, set[tuple[str, ...]]] = {}
        adjectives: dict[str, set[str]] = {}
        where: dict[str, tuple[str, str]] = {}
        content: set[str] = set()
        for row in rows:
            if len(row) < 3 or row[0] is None or row[1] is None or row[2] is None:
                continue
            thing, kind, word = local_name(row[0]), row[1], row[2]
            nouns.setdefault(thing, set())
            if kind == "label" and words_of(word):
                nouns[thing].add(words_of(word))
            elif kind == "name":
                nouns[thing].add(words_of(thing))
            elif kind == "adjective":
                adjectives.setdefault(thing, set()).update(words_of(word))
            elif kind in ("in", "on", "heldBy"):
                where[thing] = (kind, local_name(word))
            elif kind == "content":
                content.add(thing)
        things = []
        for name in sorted(nouns):
            relation, place = where.get(name, (None, None))
            things.append(
                Thing(
                    name=name,
                    nouns=frozenset(n for n in nouns[name] if n),
                    adjectives=frozenset(adjectives.get(name, ())),
                    relation=relation,
                    place=place,
                    content=name in content,
                )
            )
        return cls(tuple(things))

    @classmethod
    def from_graph(cls, graph: Graph) -> Vocabulary:
        """The vocabulary of an rdflib graph holding O_RoCo's terms (:data:`VOCABULARY_QUERY`)."""
        result = graph.query(
            VOCABULARY_QUERY,
            initNs={"roco": ROCO_IRI, "rdfs": "http://www.w3.org/2000/01/rdf-schema#"},
        )
        return cls.from_rows([tuple(None if v is None else str(v) for v in row) for row in result])  # type: ignore[union-attr]

    @classmethod
    def from_files(cls, paths: Iterable[Path]) -> Vocabulary:
        """The vocabulary of Turtle files (O_RoCo and the kitchen as a_km first loads them).
        Raises OSError or rdflib's parser errors for a missing or malformed file. rdflib is
        imported here: a_hi's process loads it only when it needs the files' vocabulary."""
        from rdflib import Graph

        graph = Graph()
        for path in paths:
            graph.parse(path, format="turtle")
        return cls.from_graph(graph)


KNOWLEDGE_FILES = tuple(
    Path(__file__).resolve().parents[1] / "knowledge" / name for name in ("o_roco.ttl", "kitchen.ttl")
)
"""The files a_km first fills its store with (a data path, no import of a_km): what a_hi knows
before a_km has answered its first vocabulary query."""

__all__ = [
    "KNOWLEDGE_FILES",
    "VARIABLES",
    "VOCABULARY_QUERY",
    "Thing",
    "Vocabulary",
    "local_name",
    "words_of",
]
