"""What a plan claims to achieve, checked by a_km in a hypothetical state (paper §5.7:
"creation of the hypothetical state of the knowledge base").

``steps`` turns the plan's operators into L_WM plan steps (grasp, put, pour), each with its
knowledge changes (held by a gripper, put in or on furniture at a position, the content
poured from one container into another: ``a_poured``); ``goal_query`` is the SPARQL ASK that
must hold after them. a_pl sends both to a_km as one ``HypotheticalQuery`` before it answers
a_co: a_km checks each step's preconditions in the state the steps before it left
(services/agents/knowledge/plan_check.py) and answers ``failure`` naming the first step that
cannot run; a plan whose step cannot run, or whose steps do not achieve its goal in a_km's
own terms (ontology, relations), is not sent.

The goal is stated from the task and a_km's knowledge before the plan, never from the plan:
a pour's goal is that the target holds what it held plus ``CONTENT_SHARE_REQUIRED`` of what
the source holds now (a_km's last counts). The plan's own sensing steps (``a_check``) test the
real world when a_ta runs them and change nothing here.
"""

from __future__ import annotations

import math
from typing import Any

import msgspec

from services.agents.planner.hfsm import KNOWLEDGE_ONLY
from services.agents.planner.knowledge import Knowledge
from shared.fipa_codec.languages.l_hc import CONTENT_SHARE_REQUIRED
from shared.fipa_codec.languages.l_wm import GraspStep, ObjectUpdate, PlanStep, PourStep, PutStep, SparqlQuery


def steps(actions: list[tuple[Any, ...]]) -> tuple[PlanStep, ...]:
    """The steps of ``actions`` (``(name, path, *args)`` as the domain makes them) whose
    preconditions a_km checks, in order, each with its knowledge changes (held by a gripper;
    put in or on furniture at a position; the content poured from one container into another:
    ``a_poured``). A step's ``index`` is the number (1-based) of its leaf among the plan's
    leaves (hfsm.py): the grasp's, the put's, the pour's first tilt. A pour whose source's
    content a_pl does not know changes no counts."""
    out: list[PlanStep] = []
    leaf = grasp_leaf = tilt_leaf = 0
    for name, _path, *args in actions:
        if name not in KNOWLEDGE_ONLY:
            leaf += 1
        if name == "a_grasp":
            grasp_leaf = leaf
        elif name == "a_tilt":
            tilt_leaf = tilt_leaf or leaf
        step = _step(name, args, {"a_held": grasp_leaf, "a_put": leaf, "a_poured": tilt_leaf})
        if step is not None:
            out.append(step)
            tilt_leaf = 0 if isinstance(step, PourStep) else tilt_leaf
    return tuple(out)


def _step(name: str, args: list[Any], index: dict[str, int]) -> PlanStep | None:
    """The plan step of the action ``name`` with ``args`` (None: not a checked operator),
    numbered ``index[name]``."""
    if name == "a_held":
        obj, arm, _picked_from = args
        grasp = GraspStep(index=index[name], object=obj, arm=arm)
        return msgspec.structs.replace(grasp, changes=grasp.effects())
    if name == "a_put":
        obj, furniture, relation, (x, y, z) = args
        position = (float(x), float(y), float(z))
        put = PutStep(
            index=index[name], object=obj, furniture=furniture, relation=relation, position=position
        )
        return msgspec.structs.replace(put, changes=put.effects())
    if name == "a_poured":
        src, dst, amount, into = args
        counts: tuple[ObjectUpdate, ...] = ()
        if amount is not None:
            counts = (ObjectUpdate(name=src, particles=0), ObjectUpdate(name=dst, particles=into + amount))
        return PourStep(index=index[name], source=src, target=dst, changes=counts)
    return None


def effects(actions: list[tuple[Any, ...]]) -> tuple[ObjectUpdate, ...]:
    """The knowledge changes of ``actions``, in order: those of their :func:`steps`."""
    return tuple(change for step in steps(actions) for change in step.changes)


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
