"""The knowledge base of a_km: an RDF graph over ontology O_RoCo (rdflib), answering L_WM
queries and applying L_WM updates (paper §5.4, §5.5 Table 5).

Poses are individuals ``roco:<object>_pose`` holding position, orientation, frame and stamp;
an update replaces them (a stale observation is superseded, never duplicated). Vectors are
literals of datatype ``roco:Vec3`` ("x y z") and ``roco:Quat`` ("w x y z").
"""

from __future__ import annotations

from pathlib import Path

from rdflib import RDF, RDFS, Graph, Literal, Namespace, URIRef
from rdflib.query import Result

from shared.fipa_codec.languages.common import Pose, Vec3
from shared.fipa_codec.languages.l_wm import (
    Answer,
    GraspAffordance,
    GraspQuery,
    ObjectInfo,
    ObjectQuery,
    PlacementInfo,
    PlacementQuery,
    PourAffordance,
    PourQuery,
    SceneQuery,
    SparqlQuery,
    WorldUpdate,
)

ROCO = Namespace("https://w3id.org/roco/O_RoCo#")
HERE = Path(__file__).parent
DEFAULT_FILES = (HERE / "o_roco.ttl", HERE / "kitchen.ttl")
Query = SparqlQuery | ObjectQuery | SceneQuery | GraspQuery | PlacementQuery | PourQuery


class KnowledgeError(ValueError):
    """A query about something the knowledge base does not know, or a malformed query."""


def _vec(text: object) -> tuple[float, ...]:
    return tuple(float(v) for v in str(text).split())


def _vec3(text: object) -> Vec3:
    v = _vec(text)
    if len(v) != 3:
        raise KnowledgeError(f"not a 3-vector: {text!r}")
    return (v[0], v[1], v[2])


def g_has(graph: Graph, node: URIRef, prop: URIRef) -> bool:
    return graph.value(node, prop) is not None


def _lit(values: tuple[float, ...] | list[float]) -> Literal:
    return Literal(" ".join(repr(float(v)) for v in values))


class WorldModel:
    """An rdflib graph with O_RoCo and the kitchen; :meth:`answer` and :meth:`apply`."""

    def __init__(self, files: tuple[Path, ...] = DEFAULT_FILES) -> None:
        self.graph = Graph()
        self.graph.bind("roco", ROCO)
        for f in files:
            self.graph.parse(f, format="turtle")
        self.total_particles: int | None = None

    # ---- queries ----
    def answer(self, query: Query) -> Answer:
        """Answer an L_WM query. Raises KnowledgeError for unknown individuals or bad SPARQL."""
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
        raise KnowledgeError(f"unsupported query {type(query).__name__}")

    def _node(self, name: str) -> URIRef:
        node = ROCO[name]
        if (node, RDF.type, None) not in self.graph:
            raise KnowledgeError(f"nothing is known about {name!r}")
        return node

    def physical_objects(self) -> list[str]:
        """Names of every individual whose class is a subclass of roco:PhysicalObject."""
        q = """SELECT DISTINCT ?o WHERE { ?o a ?c . ?c rdfs:subClassOf* roco:PhysicalObject .
               FILTER NOT EXISTS { ?c rdfs:subClassOf* roco:RobotPart } }"""
        rows = self.graph.query(q, initNs={"roco": ROCO, "rdfs": RDFS})
        return sorted(str(r[0]).removeprefix(str(ROCO)) for r in rows)  # type: ignore[index]

    def object_info(self, name: str) -> ObjectInfo:
        node = self._node(name)
        g = self.graph
        cls = g.value(node, RDF.type)
        pose_node = g.value(node, ROCO.hasPose)
        pose = stamp = None
        localised = False
        if pose_node is not None:
            pose = Pose(
                position=_vec3(g.value(pose_node, ROCO.position)),
                orientation=tuple(_vec(g.value(pose_node, ROCO.orientation))),  # type: ignore[arg-type]
                frame=str(g.value(pose_node, ROCO.frame) or "world"),
            )
            stamp_lit = g.value(pose_node, ROCO.stamp)
            stamp = float(str(stamp_lit)) if stamp_lit is not None else None
            localised = bool(g.value(pose_node, ROCO.localised))
        location = relation = None
        for rel in ("in", "on"):
            where = g.value(node, ROCO[rel])
            if where is not None:
                location, relation = str(where).removeprefix(str(ROCO)), rel
        held = g.value(node, ROCO.heldBy)
        size = g.value(node, ROCO.size)
        particles = g.value(node, ROCO.particles)
        facing = g.value(node, ROCO.facing)
        picked = g.value(node, ROCO.pickedFrom)
        view = g.value(node, ROCO.viewPoint)
        return ObjectInfo(
            name=name,
            type=str(cls).removeprefix(str(ROCO)) if cls is not None else "Thing",
            pose=pose,
            pose_stamp=stamp,
            size=_vec3(size) if size is not None else None,
            location=location,
            relation=relation,
            held_by=str(held).removeprefix(str(ROCO)) if held is not None else None,
            localised=localised,
            particles=int(str(particles)) if particles is not None else None,
            facing=float(facing) if facing is not None else None,  # type: ignore[arg-type]
            view_point=_vec3(view) if view is not None else None,
            picked_from=str(picked).removeprefix(str(ROCO))
            if held is not None and picked is not None
            else None,
        )

    def _float(self, node: URIRef, prop: URIRef, default: float | None = None) -> float:
        value = self.graph.value(node, prop)
        if value is None:
            if default is None:
                raise KnowledgeError(f"{node.removeprefix(str(ROCO))} has no {prop.removeprefix(str(ROCO))}")
            return default
        return float(value)  # type: ignore[arg-type]

    def _vec3(self, node: URIRef, prop: URIRef) -> Vec3:
        value = self.graph.value(node, prop)
        if value is None:
            raise KnowledgeError(f"{node.removeprefix(str(ROCO))} has no {prop.removeprefix(str(ROCO))}")
        return _vec3(value)

    def grasps(self, obj: str, arm: str) -> tuple[GraspAffordance, ...]:
        node = self._node(obj)
        g = self.graph
        out = []
        for aff in sorted(g.subjects(ROCO.affordanceOf, node), key=str):
            if (aff, RDF.type, ROCO.GraspAffordance) not in g or str(g.value(aff, ROCO.forArm)) != arm:
                continue
            assert isinstance(aff, URIRef)
            entry = g.value(aff, ROCO.entry)
            out.append(
                GraspAffordance(
                    name=aff.removeprefix(str(ROCO)),
                    grip_in_object=Pose(
                        position=self._vec3(aff, ROCO.gripPosition),
                        orientation=tuple(_vec(g.value(aff, ROCO.gripOrientation))),  # type: ignore[arg-type]
                        frame=obj,
                    ),
                    approach=self._vec3(aff, ROCO.approach),
                    distance=self._float(aff, ROCO.approachDistance),
                    spread=self._float(aff, ROCO.spread, 0.0),
                    preshape=self._float(aff, ROCO.preshape, 0.5),
                    entry=_vec3(entry) if entry is not None else None,
                    entry_distance=self._float(aff, ROCO.entryDistance, 0.0),
                    posture=_vec(g.value(aff, ROCO.posture) or ""),
                    lift=self._float(aff, ROCO.lift, 0.04),
                    retreat=self._vec3(aff, ROCO.retreat),
                    retreat_distance=self._float(aff, ROCO.retreatDistance, 0.25),
                )
            )
        return tuple(out)

    def placement(self, obj: str, surface: str) -> PlacementInfo:
        self._node(obj)
        node = self._node(surface)
        positions = tuple(sorted(_vec3(p) for p in self.graph.objects(node, ROCO.placementPosition)))
        if not positions:
            raise KnowledgeError(f"nothing can be put on {surface}")
        return PlacementInfo(
            surface=surface,
            positions=positions,
            clearance=self._float(node, ROCO.placeClearance, 0.005),
            approach=self._float(node, ROCO.placeApproach, 0.08),
            park=self._vec3(node, ROCO.parkOffset)
            if g_has(self.graph, node, ROCO.parkOffset)
            else (0.0, 0.0, 0.1),
        )

    def pour(self, source: str, target: str) -> PourAffordance | None:
        g = self.graph
        src, dst = self._node(source), self._node(target)
        for aff in g.subjects(ROCO.source, src):
            if (aff, ROCO.target, dst) in g:
                assert isinstance(aff, URIRef)
                return PourAffordance(
                    facing=self._float(aff, ROCO.facing),
                    source_in_target=self._vec3(aff, ROCO.sourceInTarget),
                    approach_height=self._float(aff, ROCO.approachHeight, 0.08),
                    pivot_in_target=self._vec3(aff, ROCO.pivotInTarget),
                    axis=self._vec3(aff, ROCO.axis),
                    angle=self._float(aff, ROCO.angle),
                    duration=self._float(aff, ROCO.duration),
                    wait=self._float(aff, ROCO.wait, 2.0),
                    untilt_duration=self._float(aff, ROCO.untiltDuration, 3.0),
                )
        return None

    def sparql(self, text: str) -> Answer:
        try:
            result: Result = self.graph.query(text, initNs={"roco": ROCO, "rdf": RDF, "rdfs": RDFS})
        except Exception as exc:  # rdflib raises parser-specific exceptions
            raise KnowledgeError(f"bad SPARQL: {str(exc).splitlines()[0]}") from None
        if result.type == "ASK":
            return Answer(boolean=bool(result.askAnswer))
        if result.type != "SELECT":
            raise KnowledgeError("only SELECT and ASK are answered")
        variables = tuple(str(v) for v in (result.vars or ()))
        rows = tuple(
            tuple(None if v is None else str(v) for v in row)  # type: ignore[union-attr]
            for row in result
        )
        return Answer(variables=variables, rows=rows)

    # ---- updates ----
    def apply(self, update: WorldUpdate) -> int:
        """Apply an update; returns the number of objects changed. Unknown objects are added
        as roco:PhysicalObject (something new was seen)."""
        g = self.graph
        if update.total_particles is not None:
            self.total_particles = update.total_particles
        for change in update.objects:
            node = ROCO[change.name]
            if (node, RDF.type, None) not in g:
                g.add((node, RDF.type, ROCO.PhysicalObject))
            if change.pose is not None:
                pose_node = ROCO[f"{change.name}_pose"]
                g.remove((pose_node, None, None))
                g.set((node, ROCO.hasPose, pose_node))
                g.add((pose_node, RDF.type, ROCO.Pose))
                g.add((pose_node, ROCO.position, _lit(list(change.pose.position))))
                g.add((pose_node, ROCO.orientation, _lit(list(change.pose.orientation))))
                g.add((pose_node, ROCO.frame, Literal(change.pose.frame)))
                g.add((pose_node, ROCO.stamp, Literal(update.stamp)))
                g.add((pose_node, ROCO.localised, Literal(True)))
            if change.held_by is not None:
                g.remove((node, ROCO.heldBy, None))
                if change.held_by:
                    g.add((node, ROCO.heldBy, ROCO[change.held_by]))
                    where = g.value(node, ROCO["in"]) or g.value(node, ROCO.on)
                    if where is not None:
                        g.set((node, ROCO.pickedFrom, where))
                    # held objects leave where they were; their pose is no longer localised
                    g.remove((node, ROCO["in"], None))
                    g.remove((node, ROCO.on, None))
                    held_pose = g.value(node, ROCO.hasPose)
                    if held_pose is not None:
                        g.set((held_pose, ROCO.localised, Literal(False)))
            if change.location is not None and change.relation in ("in", "on"):
                g.remove((node, ROCO["in"], None))
                g.remove((node, ROCO.on, None))
                if change.location:
                    g.add((node, ROCO[change.relation], ROCO[change.location]))
                    held_pose = g.value(node, ROCO.hasPose)
                    if held_pose is not None:
                        g.set((held_pose, ROCO.localised, Literal(False)))
            if change.particles is not None:
                g.set((node, ROCO.particles, Literal(change.particles)))
        return len(update.objects)
