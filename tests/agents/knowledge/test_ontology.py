"""O_RoCo (services/agents/knowledge/o_roco.ttl) declares every term the knowledge base uses, and the
kitchen's facts and a_km's updates conform to its domains and ranges."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from rdflib import OWL, RDF, RDFS, Graph, Literal, URIRef
from rdflib.collection import Collection
from rdflib.term import Node

from services.agents.knowledge import world_model
from services.agents.knowledge.world_model import KITCHEN_FILE, ONTOLOGY_FILE, ROCO, WorldModel
from shared.fipa_codec.languages.common import Pose
from shared.fipa_codec.languages.l_wm import ObjectUpdate, WorldUpdate

XSD = "http://www.w3.org/2001/XMLSchema#"  # (rdflib's XSD namespace object upsets pytest's collection)
XSD_STRING, XSD_DOUBLE = URIRef(XSD + "string"), URIRef(XSD + "double")
PROPERTY_KINDS = (OWL.ObjectProperty, OWL.DatatypeProperty)
VECTOR_SIZES: dict[Node, int | None] = {ROCO.Vec3: 3, ROCO.Quat: 4, ROCO.Posture: None}


@pytest.fixture(scope="module")
def ontology() -> Graph:
    g = Graph()
    g.parse(ONTOLOGY_FILE, format="turtle")
    return g


@pytest.fixture(scope="module")
def data() -> Graph:
    """O_RoCo with the kitchen, as a_km loads it."""
    g = Graph()
    for f in (ONTOLOGY_FILE, KITCHEN_FILE):
        g.parse(f, format="turtle")
    return g


def roco_terms_in_code() -> set[str]:
    """Every roco: term world_model.py names (ROCO.x, ROCO["x"], roco:x in SPARQL text)."""
    source = Path(world_model.__file__).read_text()
    names = set(re.findall(r"\bROCO\.([A-Za-z_]\w*)", source))
    names |= set(re.findall(r"\bROCO\[\"([A-Za-z_]\w*)\"\]", source))
    names |= set(re.findall(r"\broco:([A-Za-z_]\w*)", source))
    return names


def is_declared(g: Graph, term: URIRef, *kinds: URIRef) -> bool:
    return any((term, RDF.type, k) in g for k in kinds)


def test_every_predicate_and_class_used_is_declared(ontology: Graph, data: Graph) -> None:
    used_predicates = {p for p in data.predicates() if isinstance(p, URIRef) and p.startswith(str(ROCO))}
    used_classes = {
        o for o in data.objects(None, RDF.type) if isinstance(o, URIRef) and o.startswith(str(ROCO))
    }
    for name in roco_terms_in_code():
        if is_declared(ontology, ROCO[name], RDFS.Datatype):
            continue  # roco:Vec3, roco:Quat
        (used_classes if name[0].isupper() else used_predicates).add(ROCO[name])
    assert len(used_predicates) > 30 and ROCO.pickedFrom in used_predicates
    undeclared = sorted(str(p) for p in used_predicates if not is_declared(ontology, p, *PROPERTY_KINDS))
    assert not undeclared, f"not declared as owl:ObjectProperty/DatatypeProperty: {undeclared}"
    not_classes = sorted(str(c) for c in used_classes if not is_declared(ontology, c, OWL.Class))
    assert not not_classes, f"not declared as owl:Class: {not_classes}"


@pytest.mark.requirement("R2.3")
def test_the_ontology_covers_the_kitchen_and_the_robot(ontology: Graph) -> None:
    classes = [
        "PhysicalObject",
        "Container",
        "Content",
        "Surface",
        "Furniture",
        "Table",
        "Cabinet",
        "RobotPart",
        "Gripper",
        "Arm",
        "Head",
        "Torso",
        "Pose",
        "Affordance",
        "GraspAffordance",
        "PourAffordance",
    ]
    for name in classes:
        assert is_declared(ontology, ROCO[name], OWL.Class), name
    for name in ["in", "on", "heldBy", "pickedFrom", "hasPose", "affordanceOf", "source", "target", "partOf"]:
        assert is_declared(ontology, ROCO[name], OWL.ObjectProperty), name
    for name in [
        "position",
        "orientation",
        "frame",
        "stamp",
        "localised",
        "placementPosition",
        "gripPosition",
        "axis",
    ]:
        assert is_declared(ontology, ROCO[name], OWL.DatatypeProperty), name
    for relation in ("in", "on", "heldBy", "pickedFrom"):
        assert (ROCO[relation], RDFS.subPropertyOf, ROCO.spatialRelation) in ontology
    assert (ROCO.hasPose, RDFS.range, ROCO.Pose) in ontology
    assert (ROCO.stamp, RDFS.range, XSD_DOUBLE) in ontology


def test_every_roco_class_and_property_has_a_comment(ontology: Graph) -> None:
    declared = {
        s
        for kind in (OWL.Class, *PROPERTY_KINDS, RDFS.Datatype)
        for s in ontology.subjects(RDF.type, kind)
        if isinstance(s, URIRef) and s.startswith(str(ROCO))
    }
    assert len(declared) > 50
    missing = sorted(str(s) for s in declared if ontology.value(s, RDFS.comment) is None)
    assert not missing, f"no rdfs:comment: {missing}"
    for p in (p for p in declared if is_declared(ontology, p, *PROPERTY_KINDS)):
        if p != ROCO.spatialRelation:
            assert ontology.value(p, RDFS.range) is not None, f"{p} has no range"


# ---- conformance of the data to domains and ranges -------------------------------------------


class Schema:
    def __init__(self, g: Graph) -> None:
        self.g = g

    def ancestors(self, node: Node) -> set[Node]:
        out: set[Node] = set()
        todo = list(self.g.objects(node, RDF.type))
        while todo:
            c = todo.pop()
            if c not in out:
                out.add(c)
                todo.extend(self.g.objects(c, RDFS.subClassOf))
        return out

    def is_a(self, node: Node, cls: Node) -> bool:
        ancestors = self.ancestors(node)
        union = self.g.value(cls, OWL.unionOf)
        members = list(Collection(self.g, union)) if union is not None else [cls]
        return any(m in ancestors for m in members)

    def literal_fits(self, value: Node, datatype: Node) -> bool:
        if not isinstance(value, Literal) or value.language:
            return False
        actual = value.datatype or XSD_STRING
        if datatype in VECTOR_SIZES:
            try:
                numbers = [float(v) for v in str(value).split()]
            except ValueError:
                return False
            size = VECTOR_SIZES[datatype]
            return actual == XSD_STRING and len(numbers) == (size or len(numbers)) and len(numbers) > 0
        return actual == datatype

    def violations(self, triples: list[tuple[Node, Node, Node]]) -> list[str]:
        out = []
        for s, p, o in triples:
            if not (isinstance(p, URIRef) and p.startswith(str(ROCO))):
                continue
            domain, range_ = self.g.value(p, RDFS.domain), self.g.value(p, RDFS.range)
            if domain is not None and not self.is_a(s, domain):
                out.append(f"{s} {p}: subject is not a {domain}")
            if range_ is None:
                continue
            if is_declared(self.g, p, OWL.ObjectProperty) and not self.is_a(o, range_):
                out.append(f"{s} {p} {o}: object is not a {range_}")
            if is_declared(self.g, p, OWL.DatatypeProperty) and not self.literal_fits(o, range_):
                out.append(f"{s} {p} {o!r}: not a {range_}")
        return out


def test_the_kitchen_conforms_to_domains_and_ranges(data: Graph) -> None:
    assert Schema(data).violations(list(data)) == []


@pytest.mark.requirement("R2.4")
def test_updates_keep_the_knowledge_base_conformant() -> None:
    world = WorldModel()
    world.apply(
        WorldUpdate(
            stamp=1.0,
            objects=(
                ObjectUpdate(name="jar", pose=Pose((0.8, 0.22, 0.9)), particles=18),
                ObjectUpdate(name="bowl", pose=Pose((0.8, -0.2, 0.9), frame="world"), particles=0),
            ),
            total_particles=18,
        )
    )
    world.apply(WorldUpdate(stamp=-1.0, objects=(ObjectUpdate(name="jar", held_by="left_gripper"),)))
    world.apply(
        WorldUpdate(stamp=-1.0, objects=(ObjectUpdate(name="bowl", location="table", relation="on"),))
    )
    triples = list(world.triples())
    assert (ROCO.jar, ROCO.pickedFrom, ROCO.cabinet) in triples
    assert Schema(world.graph).violations(triples) == []
