"""What a plan claims to achieve, checked by a_km in a hypothetical state (paper §5.7:
"creation of the hypothetical state of the knowledge base").

``effects`` turns the plan's operators into L_WM object updates (held by a gripper, put in
or on furniture, the content poured from one container into another: ``a_poured``);
``goal_query`` is the SPARQL ASK that must hold after them. a_pl sends both to a_km as one
``HypotheticalQuery`` before it answers a_co: a plan whose effects do not achieve its goal in
a_km's own terms (ontology, relations) is not sent.

The goal is stated from the task and a_km's knowledge before the plan, never from the plan:
a pour's goal is that the target holds what it held plus ``CONTENT_SHARE_REQUIRED`` of what
the source holds now (a_km's last counts). The plan's own sensing steps (``a_check``) test the
real world when a_ta runs them and change nothing here.
"""

from __future__ import annotations

import math
from typing import Any

from services.agents.planner.domain import CONTENT_SHARE_REQUIRED
from services.agents.planner.knowledge import Knowledge
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
        elif name == "a_poured":
            src, dst, amount, into = args
            if amount is None:
                continue  # a_km does not know how much the source holds: no effect to state
            out.append(ObjectUpdate(name=src, particles=0))
            out.append(ObjectUpdate(name=dst, particles=into + amount))
    return tuple(out)


def goal_query(
    task: str, args: list[Any], actions: list[tuple[Any, ...]], complete: bool, k: Knowledge
) -> SparqlQuery | None:
    """The ASK that holds when the plan reached its goal (for a partial plan: the part it
    reaches before sensing), from the task, its arguments and a_km's knowledge ``k`` as it is
    before the plan. None when the plan only senses. A complete pour whose source's content
    a_km does not know cannot be shown to reach its goal: its ASK is false."""
    if task == "pour":
        src, dst = args
        if complete:
            held = k.objects[src].particles if src in k.objects else None
            if held is None:
                return SparqlQuery("ASK { FILTER(false) }")
            there = k.objects[dst].particles if dst in k.objects else None
            need = (there or 0) + math.ceil(CONTENT_SHARE_REQUIRED * held - 1e-9)
            return SparqlQuery(f"ASK {{ roco:{dst} roco:particles ?n . FILTER(?n >= {need}) }}")
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
