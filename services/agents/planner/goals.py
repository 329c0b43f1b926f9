"""What a plan claims to achieve, checked by a_km in a hypothetical state (paper §5.7:
"creation of the hypothetical state of the knowledge base").

``effects`` turns the plan's symbolic actions into L_WM object updates (held by a gripper,
put in or on furniture, content poured into a container); ``goal_query`` is the SPARQL ASK
that must hold after them. a_pl sends both to a_km as one ``HypotheticalQuery`` before it
answers a_co: a plan whose effects do not achieve its goal in a_km's own terms (ontology,
relations) is not sent.
"""

from __future__ import annotations

from typing import Any

from shared.fipa_codec.languages.l_wm import ObjectUpdate, SparqlQuery


def effects(actions: list[tuple[Any, ...]]) -> tuple[ObjectUpdate, ...]:
    """The knowledge changes of ``actions`` (``(name, path, *args)`` as the domain makes
    them), in order."""
    out: list[ObjectUpdate] = []
    for name, _path, *args in actions:
        if name == "a_held":
            obj, arm, _picked_from = args
            out.append(ObjectUpdate(name=obj, held_by=f"{arm}_gripper"))
        elif name == "a_put":
            obj, furniture, relation, _position = args
            out.append(ObjectUpdate(name=obj, location=furniture, relation=relation, held_by=""))
        elif name == "a_check":
            container, _share = args
            out.append(ObjectUpdate(name=container, particles=1))
    return tuple(out)


def goal_query(
    task: str, args: list[Any], actions: list[tuple[Any, ...]], complete: bool
) -> SparqlQuery | None:
    """The ASK that holds when the plan reached its goal (for a partial plan: the part it
    reaches before sensing). None when the plan only senses."""
    if task == "pour":
        dst = args[1]
        if complete:
            return SparqlQuery(f"ASK {{ roco:{dst} roco:particles ?n . FILTER(?n > 0) }}")
        puts = [a for a in actions if a[0] == "a_put" and a[2] == dst]
        if puts:
            _, _, obj, furniture, relation, _ = puts[-1]
            return SparqlQuery(f"ASK {{ roco:{obj} roco:{relation} roco:{furniture} . }}")
        return None
    if task == "move_to":
        obj, furniture = args[0], args[1]
        relation = next((a[4] for a in actions if a[0] == "a_put" and a[2] == obj), "on")
        return SparqlQuery(f"ASK {{ roco:{obj} roco:{relation} roco:{furniture} . }}")
    if task == "fetch":
        return SparqlQuery(f"ASK {{ roco:{args[0]} roco:heldBy ?gripper . }}")
    return None
