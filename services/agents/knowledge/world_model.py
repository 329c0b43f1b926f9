"""The knowledge base of a_km: an RDF graph over ontology O_RoCo, answering L_WM queries and
applying L_WM updates (paper §5.4, §5.5 Table 5, §5.7).

Storage. The graph is an rdflib :class:`~rdflib.Graph` on the Oxigraph store of oxrdflib
(RocksDB underneath). ``WorldModel(path)`` keeps it on disk, ``WorldModel()`` in memory (an
Oxigraph store without a directory; same engine, so tests exercise the production code path).
On opening, an empty store is filled with ``o_roco.ttl`` and ``kitchen.ttl`` in one
transaction; a store that already holds knowledge is kept as it is ("knowledge kept: N
triples"). All triples live in Oxigraph's default graph, so that a later process (or raw
pyoxigraph, or the ``oxigraph`` CLI) sees them; rdflib's own default identifier for a new
``Graph`` is a fresh blank node per instance, which would hide them after a restart.

Durability. :meth:`WorldModel.apply` writes one update as one Oxigraph transaction (a SPARQL
``DELETE DATA … ; INSERT DATA …`` request: all of it or nothing). When it returns, RocksDB has
written the transaction to its write-ahead log with ``write(2)``: the update survives the end
of the process, ``kill -9`` included. It survives an operating-system crash or a power loss
only after a flush (memtables to fsynced table files): ``flush_each_update=True`` does that
after every update (about 8 ms each on the 2-core VM), :meth:`WorldModel.close` does it once.

Modelling. Poses are individuals ``roco:<object>_pose`` holding position, orientation, frame,
stamp (simulation seconds) and whether the pose is localised; an observation replaces them (a
stale observation, older than the stored stamp, is ignored for the pose and counted: never
duplicated). Vectors are literals of datatype ``roco:Vec3`` ("x y z", stored as plain strings)
and ``roco:Quat`` ("w x y z").

Speed. The structured queries (object, scene, grasps, placement, pour) use direct triple
lookups (one lookup per individual for all its properties), not SPARQL strings; only the
scene's list of physical objects and :class:`SparqlQuery` run SPARQL, on Oxigraph's engine.
``scripts/bench_km.py`` measures them.
"""

from __future__ import annotations

import itertools
import logging
import re
from collections.abc import Iterable, Iterator
from pathlib import Path
from types import TracebackType

import pyoxigraph as ox
from oxrdflib import OxigraphStore
from rdflib import RDF, RDFS, XSD, Graph, Literal, Namespace, URIRef
from rdflib.graph import DATASET_DEFAULT_GRAPH_ID
from rdflib.query import Result
from rdflib.term import Node

from shared.fipa_codec.languages.common import Pose, Quat, Vec3
from shared.fipa_codec.languages.l_wm import (
    Answer,
    AnyQuery,
    GraspAffordance,
    GraspQuery,
    HypotheticalQuery,
    ObjectInfo,
    ObjectQuery,
    ObjectUpdate,
    PlacementInfo,
    PlacementQuery,
    PlanStep,
    PourAffordance,
    PourQuery,
    SceneQuery,
    SparqlQuery,
    WorldUpdate,
)

ROCO = Namespace("https://w3id.org/roco/O_RoCo#")
HERE = Path(__file__).parent
ONTOLOGY_FILE = HERE / "o_roco.ttl"
KITCHEN_FILE = HERE / "kitchen.ttl"
DEFAULT_FILES = (ONTOLOGY_FILE, KITCHEN_FILE)
Query = AnyQuery | HypotheticalQuery
"""Every L_WM query a_km answers."""

_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_-]*\Z")
"""An individual's name: the local part of its IRI in the ``roco:`` namespace."""
_SERVICE = re.compile(r"\bSERVICE\b", re.IGNORECASE)
_PHYSICAL_OBJECTS = """SELECT DISTINCT ?o WHERE { ?o a ?c . ?c rdfs:subClassOf* roco:PhysicalObject .
    FILTER NOT EXISTS { ?c rdfs:subClassOf* roco:RobotPart } }"""
_PREFIXES = {"roco": str(ROCO), "rdf": str(RDF._NS), "rdfs": str(RDFS._NS)}

log = logging.getLogger(__name__)

Triple = tuple[Node, Node, Node]


class KnowledgeError(ValueError):
    """A query about something the knowledge base does not know, or a query that cannot be
    evaluated (bad SPARQL). a_km answers it with ``failure``."""


class UnsupportedQuery(KnowledgeError):
    """A query a_km does not answer by design (not an L_WM query, CONSTRUCT/DESCRIBE, federated
    SERVICE). a_km answers it with ``refuse``."""


class StoreError(ValueError):
    """The on-disk store cannot be opened: locked by another process (another a_km on the same
    store), not an Oxigraph store, or not accessible. A configuration error (ValueError), so that
    ``services.runtime.main`` ends the process with exit code 2 and the message."""


def _parsed(files: tuple[Path, ...]) -> Iterator[ox.Quad]:
    """The quads of the Turtle ``files``, in order."""
    return itertools.chain.from_iterable(ox.parse(path=f, format=ox.RdfFormat.TURTLE) for f in files)


def _name(node: Node) -> str:
    return str(node).removeprefix(str(ROCO))


def _vec(text: object) -> tuple[float, ...]:
    try:
        return tuple(float(v) for v in str(text).split())
    except ValueError:
        raise KnowledgeError(f"not a vector of numbers: {text!r}") from None


def _vec3(text: object) -> Vec3:
    v = _vec(text)
    if len(v) != 3:
        raise KnowledgeError(f"not a 3-vector: {text!r}")
    return (v[0], v[1], v[2])


def _quat(text: object) -> Quat:
    v = _vec(text)
    if len(v) != 4:
        raise KnowledgeError(f"not a quaternion (w x y z): {text!r}")
    return (v[0], v[1], v[2], v[3])


def _lit(values: Iterable[float]) -> Literal:
    return Literal(" ".join(repr(float(v)) for v in values), datatype=XSD.string)


def _first(props: dict[Node, list[Node]], prop: URIRef) -> Node | None:
    values = props.get(prop)
    return values[0] if values else None


class _Changes:
    """The triples one update removes and adds, applied later in one transaction. Reads go
    through it (the state as it will be), so that several changes to one individual within
    one update see each other."""

    def __init__(self, graph: Graph) -> None:
        self.graph = graph
        self.removed: set[Triple] = set()
        self.added: set[Triple] = set()

    def objects(self, s: Node, p: Node) -> list[Node]:
        out = [o for o in self.graph.objects(s, p) if (s, p, o) not in self.removed]
        out += [t[2] for t in self.added if t[0] == s and t[1] == p and t[2] not in out]
        return out

    def value(self, s: Node, p: Node) -> Node | None:
        values = self.objects(s, p)
        return values[0] if values else None

    def remove(self, s: Node, p: Node) -> None:
        for o in self.objects(s, p):
            t = (s, p, o)
            self.added.discard(t)
            if t in self.graph:
                self.removed.add(t)

    def remove_subject(self, s: Node) -> None:
        predicates = {p for p, _o in self.graph.predicate_objects(s)}
        predicates |= {t[1] for t in self.added if t[0] == s}
        for p in predicates:
            self.remove(s, p)

    def add(self, s: Node, p: Node, o: Node) -> None:
        # the store may hold the triple in another lexical form (Oxigraph keeps numbers by
        # value: "2.0"^^xsd:double comes back as "2"): ask it, and keep what it holds
        stored = list(self.graph.triples((s, p, o)))
        if stored:
            self.removed.difference_update(stored)
        else:
            self.added.add((s, p, o))

    def set(self, s: Node, p: Node, o: Node) -> None:
        self.remove(s, p)
        self.add(s, p, o)

    def sparql_update(self) -> str | None:
        """One SPARQL update request for all the changes; None when there are none."""
        parts = []
        if self.removed:
            parts.append("DELETE DATA {\n" + _ntriples(self.removed) + "}")
        if self.added:
            parts.append("INSERT DATA {\n" + _ntriples(self.added) + "}")
        return " ;\n".join(parts) or None


def _ntriples(triples: Iterable[Triple]) -> str:
    return "".join(f"{s.n3()} {p.n3()} {o.n3()} .\n" for s, p, o in triples)


class WorldModel:
    """O_RoCo and the kitchen in an rdflib graph on Oxigraph: :meth:`answer` L_WM queries,
    :meth:`apply` L_WM updates.

    ``store``: directory of the on-disk Oxigraph store (created if missing; filled with
    ``files`` when empty, kept otherwise); None keeps everything in memory. ``files``: Turtle
    files loaded into an empty store (default O_RoCo and the kitchen). ``flush_each_update``:
    flush to disk after every update (survives power loss, not only the end of the process).
    Raises :class:`StoreError` when the store cannot be opened. Not thread-safe: one thread
    (a_km's) queries and updates it. Close it with :meth:`close` (or use it as a context
    manager); the on-disk store stays locked until then.
    """

    def __init__(
        self,
        store: Path | None = None,
        *,
        files: tuple[Path, ...] = DEFAULT_FILES,
        flush_each_update: bool = False,
    ) -> None:
        self.path = store
        self.files = files
        """The initial knowledge (Turtle files) an empty store is filled with (:meth:`renew`)."""
        self.flush_each_update = flush_each_update
        self.stale_poses = 0
        """Poses ignored because the stored pose was observed later (paper §5.5, item 3 of a_km)."""
        self.unstamped_poses = 0
        """Poses ignored because their update had no observation time (stamp < 0)."""
        self.rejected_changes = 0
        """Object updates ignored: invalid name or relation."""
        try:
            self._ox: ox.Store | None = ox.Store(str(store)) if store is not None else ox.Store()
        except OSError as exc:
            raise StoreError(f"cannot open the knowledge store {store}: {exc}") from None
        self.graph = Graph(store=OxigraphStore(store=self._ox), identifier=DATASET_DEFAULT_GRAPH_ID)
        self.graph.bind("roco", ROCO)
        self.kept = len(self._ox) > 0
        """True when the store already held knowledge when it was opened (nothing was loaded)."""
        if self.kept:
            log.info("knowledge kept: %d triples in %s", len(self._ox), store)
        elif files:
            self._ox.extend(_parsed(files))
            log.info("knowledge loaded: %d triples from %s", len(self._ox), ", ".join(f.name for f in files))

    # ---- life cycle ----
    @property
    def closed(self) -> bool:
        return self._ox is None

    def close(self) -> None:
        """Flush an on-disk store and release it (its lock too). Idempotent; a closed model
        answers nothing (RuntimeError)."""
        if self._ox is None:
            return
        if self.path is not None:
            self._ox.flush()
        self.graph.close()
        self._ox = None

    def __enter__(self) -> WorldModel:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    def __len__(self) -> int:
        """The number of triples."""
        return len(self._store)

    def _check_open(self) -> None:
        if self._ox is None:
            raise RuntimeError("the world model is closed")

    @property
    def _store(self) -> ox.Store:
        if self._ox is None:
            raise RuntimeError("the world model is closed")
        return self._ox

    def fork(self) -> WorldModel:
        """An in-memory copy of the whole knowledge base (a few hundred to a few thousand
        triples: about a millisecond), for hypothetical states."""
        copy = WorldModel(None, files=())
        assert copy._ox is not None
        copy._ox.extend(self._store.quads_for_pattern(None, None, None, ox.DefaultGraph()))
        return copy

    # ---- queries ----
    def answer(self, query: Query) -> Answer:
        """Answer an L_WM query. Raises :class:`UnsupportedQuery` for queries a_km does not
        answer, :class:`KnowledgeError` for unknown individuals or bad SPARQL."""
        if isinstance(query, ObjectQuery):
            return Answer(objects=(self.object_info(query.name),))
        if isinstance(query, SceneQuery):
            return Answer(objects=tuple(self.object_info(n) for n in self.physical_objects()))
        if isinstance(query, GraspQuery):
            return Answer(grasps=self.grasps(query.object, query.arm))
        if isinstance(query, PlacementQuery):
            return Answer(placement=self.placement(query.object, query.surface))
        if isinstance(query, PourQuery):
            return Answer(pour=self.pour(query.source, query.target))
        if isinstance(query, SparqlQuery):
            return self.sparql(query.query)
        if isinstance(query, HypotheticalQuery):
            return self.hypothetical(query.changes, query.query, query.steps)
        raise UnsupportedQuery(f"unsupported query {type(query).__name__}")

    def hypothetical(
        self, changes: Iterable[ObjectUpdate], query: Query, steps: Iterable[PlanStep] = ()
    ) -> Answer:
        """Answer ``query`` in the state after ``steps``, then ``changes`` (paper §5.7), applied
        in order to an in-memory copy; the real state is not touched. Each step's preconditions
        are checked (services/agents/knowledge/plan_check.py) in the state the steps before it
        left, then its effects, by a_km's reading of its operator (not the ``changes`` the step
        declares), are applied; the first that fails raises ``StepRefused`` (a
        KnowledgeError) naming the step and the reason. A hypothetical pose is taken as known
        (localised) but unobserved: no stamp, so ``pose_stamp`` is None."""
        # imported here: plan_check reads the world model through this module's names
        from services.agents.knowledge.plan_check import StepRefused, effects, refusal

        if isinstance(query, HypotheticalQuery):
            raise UnsupportedQuery("a hypothetical query inside a hypothetical query")
        with self.fork() as scratch:
            for step in steps:
                why = refusal(scratch, step)
                if why is not None:
                    raise StepRefused(f"step {step.index} {step.operator}: {why}")
                scratch._apply(effects(scratch, step), stamp=None)
            scratch._apply(tuple(changes), stamp=None)
            return scratch.answer(query)

    def _props(self, name: str) -> tuple[URIRef, dict[Node, list[Node]]]:
        """The individual ``name`` and all its properties (one lookup). Raises KnowledgeError
        when nothing is known about it."""
        if not _NAME.match(name):
            raise KnowledgeError(f"not an individual's name: {name!r}")
        node = ROCO[name]
        props = self._node_props(node)
        if RDF.type not in props:
            raise KnowledgeError(f"nothing is known about {name!r}")
        return node, props

    def _node_props(self, node: Node) -> dict[Node, list[Node]]:
        """All properties of ``node``: predicate → objects (one lookup)."""
        self._check_open()
        props: dict[Node, list[Node]] = {}
        for p, o in self.graph.predicate_objects(node):
            props.setdefault(p, []).append(o)
        return props

    def _node(self, name: str) -> URIRef:
        return self._props(name)[0]

    def physical_objects(self) -> list[str]:
        """Names of every individual whose class is a subclass of roco:PhysicalObject and not of
        roco:RobotPart, sorted."""
        rows = self._select(_PHYSICAL_OBJECTS)
        return sorted(_name(r[0]) for r in rows)  # type: ignore[index]

    def _select(self, text: str) -> Result:
        self._check_open()
        return self.graph.query(text, initNs=_PREFIXES)

    def object_info(self, name: str) -> ObjectInfo:
        """Everything known about the individual ``name`` (lengths m, angles rad, stamps s of
        simulation time). Raises KnowledgeError when nothing is known about it."""
        _node, props = self._props(name)
        cls = _first(props, RDF.type)
        pose_node = _first(props, ROCO.hasPose)
        pose = stamp = sigma = None
        localised = False
        if pose_node is not None:
            pp = self._node_props(pose_node)
            position = _first(pp, ROCO.position)
            if position is not None:
                orientation = _first(pp, ROCO.orientation)
                pose = Pose(
                    position=_vec3(position),
                    orientation=_quat(orientation) if orientation is not None else (1.0, 0.0, 0.0, 0.0),
                    frame=str(_first(pp, ROCO.frame) or "world"),
                )
                stamp_lit = _first(pp, ROCO.stamp)
                stamp = float(str(stamp_lit)) if stamp_lit is not None else None
                sigma_lit = _first(pp, ROCO.positionSigma)
                sigma = float(str(sigma_lit)) if sigma_lit is not None else None
                localised = bool(getattr(_first(pp, ROCO.localised), "value", False))
        location = relation = None
        for rel in ("in", "on"):
            where = _first(props, ROCO[rel])
            if where is not None:
                location, relation = _name(where), rel
        held = _first(props, ROCO.heldBy)
        size = _first(props, ROCO.size)
        mass = _first(props, ROCO.mass)
        particles = _first(props, ROCO.particles)
        facing = _first(props, ROCO.facing)
        picked = _first(props, ROCO.pickedFrom)
        view = _first(props, ROCO.viewPoint)
        return ObjectInfo(
            name=name,
            type=_name(cls) if cls is not None else "Thing",
            pose=pose,
            pose_stamp=stamp,
            position_sigma=sigma,
            size=_vec3(size) if size is not None else None,
            mass=float(str(mass)) if mass is not None else None,
            location=location,
            relation=relation,
            held_by=_name(held) if held is not None else None,
            localised=localised,
            particles=int(str(particles)) if particles is not None else None,
            facing=float(str(facing)) if facing is not None else None,
            view_point=_vec3(view) if view is not None else None,
            picked_from=_name(picked) if held is not None and picked is not None else None,
        )

    @staticmethod
    def _float(node: str, props: dict[Node, list[Node]], prop: URIRef, default: float | None = None) -> float:
        value = _first(props, prop)
        if value is None:
            if default is None:
                raise KnowledgeError(f"{node} has no {_name(prop)}")
            return default
        try:
            return float(str(value))
        except ValueError:
            raise KnowledgeError(f"{node}: {_name(prop)} is not a number: {value!r}") from None

    @staticmethod
    def _req_vec3(node: str, props: dict[Node, list[Node]], prop: URIRef) -> Vec3:
        value = _first(props, prop)
        if value is None:
            raise KnowledgeError(f"{node} has no {_name(prop)}")
        return _vec3(value)

    @staticmethod
    def _vec3_or(props: dict[Node, list[Node]], prop: URIRef, default: Vec3) -> Vec3:
        value = _first(props, prop)
        return default if value is None else _vec3(value)

    def grasps(self, obj: str, arm: str) -> tuple[GraspAffordance, ...]:
        """The grasp affordances of ``obj`` for the hand of ``arm`` ("left"/"right"), sorted by
        name; () when there are none. Raises KnowledgeError for an unknown object or an
        affordance missing a required value."""
        node = self._node(obj)
        out = []
        for aff in sorted(self.graph.subjects(ROCO.affordanceOf, node), key=str):
            name = _name(aff)
            p = self._node_props(aff)
            if ROCO.GraspAffordance not in p.get(RDF.type, ()) or str(_first(p, ROCO.forArm)) != arm:
                continue
            entry = _first(p, ROCO.entry)
            orientation = _first(p, ROCO.gripOrientation)
            out.append(
                GraspAffordance(
                    name=name,
                    grip_in_object=Pose(
                        position=self._req_vec3(name, p, ROCO.gripPosition),
                        orientation=_quat(orientation) if orientation is not None else (1.0, 0.0, 0.0, 0.0),
                        frame=obj,
                    ),
                    approach=self._req_vec3(name, p, ROCO.approach),
                    distance=self._float(name, p, ROCO.approachDistance),
                    spread=self._float(name, p, ROCO.spread, 0.0),
                    preshape=self._float(name, p, ROCO.preshape, 0.5),
                    entry=_vec3(entry) if entry is not None else None,
                    entry_distance=self._float(name, p, ROCO.entryDistance, 0.0),
                    posture=_vec(_first(p, ROCO.posture) or ""),
                    on=tuple(sorted(_name(f) for f in p.get(ROCO.graspOn, ()))),
                    lift=self._float(name, p, ROCO.lift, 0.04),
                    retreat=self._req_vec3(name, p, ROCO.retreat),
                    retreat_distance=self._float(name, p, ROCO.retreatDistance, 0.25),
                )
            )
        return tuple(out)

    def placement(self, obj: str, surface: str) -> PlacementInfo:
        """Where on ``surface`` the ``obj`` can be put down, in order of preference: the
        surface's ``roco:Place`` individuals meant for ``obj`` (``roco:forObject``) or for
        anything (none given), by ``roco:rank``; then its plain ``roco:placementPosition``
        values. World positions in m; each place's torso angle (``roco:facing``, rad) or None
        for the surface's own. Raises KnowledgeError for unknown individuals or a surface
        with no place for ``obj``."""
        obj_node = self._node(obj)
        surface_node, p = self._props(surface)
        places: list[tuple[float, Vec3, float | None, float | None, Vec3 | None]] = []
        for place in self.graph.subjects(ROCO.placeOn, surface_node):
            pp = self._node_props(place)
            meant = pp.get(ROCO.forObject, [])
            if meant and obj_node not in meant:
                continue
            name = _name(place)
            rank = self._float(name, pp, ROCO.rank, 50.0)
            facing = self._float(name, pp, ROCO.facing) if ROCO.facing in pp else None
            approach = self._float(name, pp, ROCO.placeApproach) if ROCO.placeApproach in pp else None
            park = self._req_vec3(name, pp, ROCO.parkOffset) if ROCO.parkOffset in pp else None
            places.append((rank, self._req_vec3(name, pp, ROCO.placePosition), facing, approach, park))
        places.sort(key=lambda t: (t[0], t[1]))
        plain = sorted(_vec3(v) for v in p.get(ROCO.placementPosition, ()))
        positions = tuple([t[1] for t in places] + plain)
        if not positions:
            raise KnowledgeError(f"nothing can be put on {surface}")
        n = len(plain)
        facings: list[float | None] = [t[2] for t in places] + [None] * n
        approaches: list[float | None] = [t[3] for t in places] + [None] * n
        parks: list[Vec3 | None] = [t[4] for t in places] + [None] * n
        return PlacementInfo(
            surface=surface,
            positions=positions,
            facings=tuple(facings),
            approaches=tuple(approaches),
            parks=tuple(parks),
            clearance=self._float(surface, p, ROCO.placeClearance, 0.005),
            approach=self._float(surface, p, ROCO.placeApproach, 0.08),
            park=self._req_vec3(surface, p, ROCO.parkOffset) if ROCO.parkOffset in p else (0.0, 0.0, 0.1),
        )

    def pour(self, source: str, target: str) -> PourAffordance | None:
        """How to pour from ``source`` into ``target`` (m, rad, s); None when no pour affordance
        joins them. Raises KnowledgeError for unknown individuals or missing values."""
        src, dst = self._node(source), self._node(target)
        for aff in sorted(self.graph.subjects(ROCO.source, src), key=str):
            if (aff, ROCO.target, dst) not in self.graph:
                continue
            name = _name(aff)
            p = self._node_props(aff)
            return PourAffordance(
                facing=self._float(name, p, ROCO.facing),
                source_in_target=self._req_vec3(name, p, ROCO.sourceInTarget),
                approach_height=self._float(name, p, ROCO.approachHeight, 0.08),
                pivot_in_target=self._req_vec3(name, p, ROCO.pivotInTarget),
                axis=self._req_vec3(name, p, ROCO.axis),
                angle=self._float(name, p, ROCO.angle),
                duration=self._float(name, p, ROCO.duration),
                wait=self._float(name, p, ROCO.wait, 2.0),
                untilt_duration=self._float(name, p, ROCO.untiltDuration, 3.0),
                clear_view=self._vec3_or(p, ROCO.clearView, (0.0, 0.0, 0.0)),
            )
        return None

    def sparql(self, text: str) -> Answer:
        """Evaluate a SPARQL 1.1 SELECT or ASK (prefixes ``roco:``, ``rdf:``, ``rdfs:``
        predefined) on Oxigraph's engine. Values come back as strings (IRIs in full, literals
        by their lexical form), unbound as None. Raises KnowledgeError for bad SPARQL,
        UnsupportedQuery for CONSTRUCT/DESCRIBE and federated queries (SERVICE: a_km makes no
        HTTP requests on a querier's behalf). Updates are not queries: they are bad SPARQL."""
        if _SERVICE.search(text):
            raise UnsupportedQuery("federated queries (SERVICE) are not answered")
        try:
            result = self._select(text)
        except (SyntaxError, ValueError, OSError) as exc:
            raise KnowledgeError(f"bad SPARQL: {str(exc).splitlines()[0] if str(exc) else exc!r}") from None
        if result.type == "ASK":
            return Answer(boolean=bool(result.askAnswer))
        if result.type != "SELECT":
            raise UnsupportedQuery("only SELECT and ASK are answered")
        variables = tuple(str(v) for v in (result.vars or ()))
        rows = tuple(
            tuple(None if v is None else str(v) for v in row)  # type: ignore[union-attr]
            for row in result
        )
        return Answer(variables=variables, rows=rows)

    # ---- updates ----
    @property
    def total_particles(self) -> int | None:
        """Spheres in the whole scene, as last observed (on the roco:Content individual)."""
        content = next(iter(self.graph.subjects(RDF.type, ROCO.Content)), None)
        value = self.graph.value(content, ROCO.totalParticles) if content is not None else None
        return int(str(value)) if value is not None else None

    def apply(self, update: WorldUpdate) -> int:
        """Apply an observation or asserted change in one transaction; returns the number of
        object updates it carried. Unknown objects are added as roco:PhysicalObject (something
        new was seen). A pose older than the stored one (``update.stamp`` < its stamp) is
        ignored and counted in :attr:`stale_poses`; a pose in an update with no observation
        time (stamp < 0, a_ta's asserted changes) is ignored and counted in
        :attr:`unstamped_poses`. An observation's ``seen_at`` (a_ta's wall clock, POSIX s) becomes
        ``roco:seenAt`` of each object whose pose it takes, and ``roco:contentSeenAt`` of each
        whose content count it gives. Durable when it returns (see the
        module docstring)."""
        self._apply(
            update.objects, stamp=update.stamp, total_particles=update.total_particles, seen_at=update.seen_at
        )
        return len(update.objects)

    def renew(self, update: WorldUpdate) -> int:
        """Drop everything known of the world and take it anew: the store is emptied, filled
        with the initial knowledge (the ``files`` it was opened with: the kitchen as it starts),
        then ``update`` is applied (:meth:`apply`; the stale check finds no stamp to compare
        with). For a robot that was power-cycled: its kitchen started again, its time from 0
        (L_WM ``WorldUpdate.renews``). Three steps, each durable: a process that ends between
        them leaves an empty store (filled with the initial knowledge when it is opened again)
        or the initial knowledge. Returns the number of object updates ``update`` carried."""
        store = self._store
        store.clear()
        if self.files:
            store.extend(
                itertools.chain.from_iterable(
                    ox.parse(path=f, format=ox.RdfFormat.TURTLE) for f in self.files
                )
            )
        log.info("knowledge renewed: %d triples of the initial kitchen", len(store))
        return self.apply(update)

    def _apply(
        self,
        objects: tuple[ObjectUpdate, ...],
        *,
        stamp: float | None,
        total_particles: int | None = None,
        seen_at: float | None = None,
    ) -> None:
        """``stamp`` None: hypothetical changes (poses taken without a stamp and no stale check)."""
        self._check_open()
        ch = _Changes(self.graph)
        if total_particles is not None:
            content = next(iter(self.graph.subjects(RDF.type, ROCO.Content)), None)
            if content is not None:
                ch.set(content, ROCO.totalParticles, Literal(total_particles))
        for change in objects:
            self._change(ch, change, stamp, seen_at)
        text = ch.sparql_update()
        if text is not None:
            self.graph.update(text)
            if self.flush_each_update and self.path is not None:
                self._store.flush()

    def _change(self, ch: _Changes, change: ObjectUpdate, stamp: float | None, seen_at: float | None) -> None:
        if not _NAME.match(change.name):
            self.rejected_changes += 1
            log.warning("update of %r ignored: not an individual's name", change.name)
            return
        node = ROCO[change.name]
        if ch.value(node, RDF.type) is None:
            ch.add(node, RDF.type, ROCO.PhysicalObject)
        if change.pose is not None:
            self._set_pose(ch, node, change, stamp, seen_at)
        if change.held_by is not None:
            ch.remove(node, ROCO.heldBy)
            if change.held_by:
                if not _NAME.match(change.held_by):
                    self.rejected_changes += 1
                    log.warning(
                        "%s held by %r ignored: not an individual's name", change.name, change.held_by
                    )
                else:
                    ch.add(node, ROCO.heldBy, ROCO[change.held_by])
                    where = ch.value(node, ROCO["in"]) or ch.value(node, ROCO.on)
                    if where is not None:
                        ch.set(node, ROCO.pickedFrom, where)
                    # held objects leave where they were; their pose is no longer localised
                    ch.remove(node, ROCO["in"])
                    ch.remove(node, ROCO.on)
                    self._unlocalise(ch, node)
        if change.location is not None:
            if change.relation not in ("in", "on") or (change.location and not _NAME.match(change.location)):
                self.rejected_changes += 1
                log.warning(
                    "%s %s %r ignored: relation must be in/on and location a name",
                    change.name,
                    change.relation,
                    change.location,
                )
            else:
                ch.remove(node, ROCO["in"])
                ch.remove(node, ROCO.on)
                if change.location:
                    ch.add(node, ROCO[change.relation], ROCO[change.location])
                    self._unlocalise(ch, node)
        if change.particles is not None:
            ch.set(node, ROCO.particles, Literal(change.particles))
            if stamp is not None and stamp >= 0 and seen_at is not None:
                ch.set(node, ROCO.contentSeenAt, Literal(float(seen_at)))

    def _set_pose(
        self, ch: _Changes, node: URIRef, change: ObjectUpdate, stamp: float | None, seen_at: float | None
    ) -> None:
        assert change.pose is not None
        pose_node = ROCO[f"{change.name}_pose"]
        if stamp is not None:
            if stamp < 0:
                self.unstamped_poses += 1
                log.warning(
                    "pose of %s ignored: an update with no observation time carries no pose", change.name
                )
                return
            stored = ch.value(pose_node, ROCO.stamp)
            if stored is not None and stamp < float(str(stored)):
                self.stale_poses += 1
                log.info(
                    "stale pose of %s ignored: observed at %.3f s, known since %.3f s",
                    change.name,
                    stamp,
                    float(str(stored)),
                )
                return
        ch.remove_subject(pose_node)
        ch.set(node, ROCO.hasPose, pose_node)
        ch.add(pose_node, RDF.type, ROCO.Pose)
        ch.add(pose_node, ROCO.position, _lit(change.pose.position))
        ch.add(pose_node, ROCO.orientation, _lit(change.pose.orientation))
        ch.add(pose_node, ROCO.frame, Literal(change.pose.frame, datatype=XSD.string))
        if stamp is not None:
            ch.add(pose_node, ROCO.stamp, Literal(float(stamp)))
        if change.position_sigma is not None:
            ch.add(pose_node, ROCO.positionSigma, Literal(float(change.position_sigma)))
        ch.add(pose_node, ROCO.localised, Literal(True))
        if stamp is not None and seen_at is not None:
            ch.set(node, ROCO.seenAt, Literal(float(seen_at)))

    @staticmethod
    def _unlocalise(ch: _Changes, node: URIRef) -> None:
        pose_node = ch.value(node, ROCO.hasPose)
        if pose_node is not None:
            ch.set(pose_node, ROCO.localised, Literal(False))

    def triples(self) -> Iterator[Triple]:
        """Every triple (for copies, exports and tests)."""
        return iter(self.graph.triples((None, None, None)))
