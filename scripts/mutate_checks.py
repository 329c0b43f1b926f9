"""Mutation check: each of roco's checks, deleted, is caught by the tests named for it.

A check that can be deleted with every test green is not tested. This script deletes the checks
of :data:`MUTANTS` one at a time, each in a copy of the tree (never in the tree itself), and
runs the tests that must catch it there. Each :class:`Mutant` names a file, an exact source
snippet in it (it must occur exactly once), what replaces it (code that still runs with the
check gone: ``if False:``, an empty list of problems, no ``append``), and the pytest node ids
that must fail once it is applied. For each mutant the script

1. copies the tree to a temporary folder (:func:`copy_tree`: ``shutil.copytree`` without
   .venv, .git, runs/, build/, dist/, \\*.egg-info and caches), leaving out every compiled
   extension (``*.so``) under services/ and shared/ so that the Python sources are imported
   (mypyc compiles services/runtime in place: setup.py), and applies the mutant;
2. runs ``python -m pytest -x -q -p no:cacheprovider -n 0 NODE_IDS`` in the copy with the
   current interpreter and ``PYTHONPATH`` the copy, within ``--timeout`` seconds;
3. gives the mutant one row of the table it prints: ``caught`` (a test failed), ``SURVIVED``
   (they all passed), ``TIMEOUT`` or ``ERROR`` (pytest could not run them), with the seconds
   it took and the first failure pytest names.

Before the mutants, the tests of all of them run once on an unmutated copy (the baseline): they
must pass, and each mutated module must be imported from the copy's source (not from this
tree, nor from a compiled extension); else nothing a mutant shows would mean anything.

Usage: ``python scripts/mutate_checks.py [--only PREFIX]... [--list] [--timeout S]``. Run it
from the repository (the mutants run one after the other; a few minutes in all)::

    .venv/bin/python scripts/mutate_checks.py                      # every mutant
    .venv/bin/python scripts/mutate_checks.py --only verify.       # those whose name starts so
    .venv/bin/python scripts/mutate_checks.py --only verify.key --only plan-check.pour.
    .venv/bin/python scripts/mutate_checks.py --only chaos.task-done.
    .venv/bin/python scripts/mutate_checks.py --list               # the mutants; run nothing

``--only PREFIX`` may be given more than once (a mutant is selected when its name starts with
one of them); ``--list`` prints the selected mutants and whether each snippet applies to the
tree as it is, and runs no test.

Exit codes:

* 0: every mutant selected is caught (with ``--list``: every snippet applies);
* 1: a mutant survived, timed out or could not be tested (``ERROR``): a check no test catches;
* 2: the setup is not accepted, and no mutant (or no further one) ran: a snippet not found
  (or found twice) in its file, a mutated file that does not compile, no mutant selected, or
  a baseline that fails or imports the tree (or a compiled module) instead of the copy's source.

Adding mutants: the mutants are grouped by area in :data:`GROUPS`, one list each, keyed by the
prefix every name of the group starts with (``verify.``: the violation kinds of ``roco spec
verify``; ``plan-check.``: a_km's plan-check refusals; ``chaos.``: ``roco chaos``'s questions,
each side of "task done" apart, and each answer's part in the verdict it exits by). To test
another area, write a list of :class:`Mutant` s named ``<area>.<check>`` like
:data:`VERIFY_KINDS` and add it to :data:`GROUPS` under ``"<area>."``; then ``--list --only
<area>.`` shows whether its snippets apply and ``--only <area>.`` runs them. The snippet is the
check itself, as small as still occurs once; what replaces it must still import: a mutant that
breaks the module is caught by any test and shows nothing. Name as few tests as catch the
check: they run once per mutant.
"""

from __future__ import annotations

import argparse
import fnmatch
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
"""The repository (default of ``--root``)."""
LEFT_OUT_AT_TOP = (".venv", "venv", ".git", "runs", "build", "dist", "*.egg-info")
"""Folders at the top of the tree the copy leaves out (environments, history, build output)."""
LEFT_OUT_ANYWHERE = ("__pycache__", ".mypy_cache", ".ruff_cache", ".pytest_cache", ".hypothesis")
"""Folders left out wherever they are (caches)."""
COMPILED_UNDER = ("services", "shared")
"""Top folders of the tree whose compiled extensions (``*.so``) the copy leaves out."""
PYTEST = ("-m", "pytest", "-x", "-q", "-p", "no:cacheprovider", "-n", "0")
"""How the tests run: this interpreter's pytest, stopping at the first failure, no cache, in one
process (pyproject.toml's addopts asks xdist for a worker per core: a start-up cost per mutant)."""
DEFAULT_TIMEOUT_S = 300.0


@dataclass(frozen=True)
class Mutant:
    """One check deleted: in ``file`` (relative to the repository), the snippet ``old``, which
    must occur exactly once, is replaced by ``new``; ``tests`` (pytest node ids) must fail."""

    name: str
    file: str
    old: str
    new: str
    tests: tuple[str, ...]


# ------------------------------------------------------------------ verify.: roco spec verify

_CONFORMANCE = "services/spec_check/conformance.py"
_EVERY_KIND = "tests/spec_check/test_every_kind.py"
_PLANTED = f"{_EVERY_KIND}::test_a_planted_fault_is_reported_as_its_kind_on_the_planted_communicate"
_CLI = f"{_EVERY_KIND}::test_roco_spec_verify_exits_1_naming_the_kind_of_a_planted_fault"


def _planted(kind: str, plant: str, *, cli: bool = True) -> tuple[str, ...]:
    """The node ids of the planted fault ``plant`` of ``kind`` (test_every_kind.PLANTED) and,
    with ``cli`` (``plant`` is the kind's first), of its ``roco spec verify`` test."""
    return (f"{_PLANTED}[{kind}: {plant}]", *([f"{_CLI}[{kind}]"] if cli else []))


VERIFY_KINDS = [
    Mutant(
        "verify.malformed",
        _CONFORMANCE,
        """[("malformed", f"the payload on {rec.key or '?'} is not a communicate")]""",
        "[]",
        _planted("malformed", "a payload that is no communicate"),
    ),
    Mutant(
        "verify.key",
        _CONFORMANCE,
        "        problems += _key_mismatches(comm, m.rec.channel, parsed)\n",
        "",
        _planted("key", "a key naming another sender"),
    ),
    Mutant(
        "verify.channel.another",
        _CONFORMANCE,
        "        if self.between.name != self.m.rec.channel:\n",
        "        if False:\n",
        _planted("channel", "a key on a channel that does not join the agents"),
    ),
    Mutant(
        "verify.channel.none",
        _CONFORMANCE,
        """[("channel", f"no channel of the specification joins {sender} and {receiver}")]""",
        "[]",
        _planted("channel", "a receiver no channel joins the sender to", cli=False),
    ),
    Mutant(
        "verify.performative.role",
        _CONFORMANCE,
        """        if self.kind is not None:
            return None
        role = _role_of(""",
        """        if True:
            return None
        role = _role_of(""",
        _planted("performative", "a performative the sender's role may not send"),
    ),
    Mutant(
        "verify.performative.protocol",
        _CONFORMANCE,
        "        if self.protocol in {cp.protocol for cp in self.between.protocols}:\n",
        "        if True:\n",
        _planted("performative", "a protocol the channel does not carry", cli=False),
    ),
    Mutant(
        "verify.language.another",
        _CONFORMANCE,
        "        if self.kind.languages and language not in self.kind.languages:\n",
        "        if False:\n",
        _planted("language", "content in another language"),
    ),
    Mutant(
        "verify.language.none",
        _CONFORMANCE,
        """            return [("language", f"{self.perf} carries content but names no language")]""",
        """            return []""",
        _planted("language", "content in no language", cli=False),
    ),
    Mutant(
        "verify.ontology",
        _CONFORMANCE,
        "        if ontology != expected_ontology(language):\n",
        "        if False:\n",
        _planted("ontology", "the ontology of another language"),
    ),
    Mutant(
        "verify.content.decoding",
        _CONFORMANCE,
        """        except ContentError as exc:
            return [("content", str(exc))]""",
        """        except ContentError:
            return []""",
        _planted("content", "content that does not decode"),
    ),
    Mutant(
        "verify.content.term",
        _CONFORMANCE,
        "        if allowed_terms and type(term).__name__ not in allowed_terms:\n",
        "        if False:\n",
        _planted("content", "a term the specification does not list for the performative", cli=False),
    ),
    Mutant(
        "verify.protocol-state",
        _CONFORMANCE,
        """problems.append(("protocol-state", str(refusal)))""",
        "pass",
        _planted("protocol-state", "an answer in a conversation of its own"),
    ),
    Mutant(
        "verify.conversation.no-id",
        _CONFORMANCE,
        """problems.append(("conversation", f"a {protocol} communicate without conversation-id"))""",
        "pass",
        _planted("conversation", "a communicate without conversation-id"),
    ),
    Mutant(
        "verify.conversation.another-protocol",
        _CONFORMANCE,
        """problems.append(("conversation", str(refusal)))""",
        "pass",
        _planted("conversation", "an agree in another protocol than its conversation began with", cli=False),
    ),
    Mutant(
        "verify.unanswered",
        _CONFORMANCE,
        "                self._unanswered(key, result)\n",
        "                pass\n",
        _planted("unanswered", "a subscribe whose participant never answers"),
    ),
    Mutant(
        "verify.unanswered.lost-with-the-receiver",
        _CONFORMANCE,
        "        if gone is not None:\n",
        "        if False:\n",
        (
            f"{_EVERY_KIND}::test_a_subscribe_unanswered_because_its_receiver_was_away_is_lost_not_a_violation",
        ),
    ),
    Mutant(
        "verify.unanswered.lost-only-while-away",
        _CONFORMANCE,
        "        gone = away_between(self.absences.get(receiver, []), sent, until)\n",
        "        gone = next(iter(self.absences.get(receiver, [])), None)\n",
        (
            f"{_EVERY_KIND}::test_a_subscribe_unanswered_by_a_receiver_that_stayed_is_a_violation_with_a_presence_record",
        ),
    ),
    Mutant(
        "verify.kinds.conversation",
        _CONFORMANCE,
        """    "conversation": "the communicate cannot belong to its conversation",\n""",
        "",
        (f"{_EVERY_KIND}::test_every_kind_of_violation_has_a_planted_fault",),
    ),
    Mutant(
        "verify.cli.exit",
        "services/cli/spec.py",
        """    ok, text = verify_report(run, _run_spec(spec, [run]))
    typer.echo(text)
    if not ok:
        raise typer.Exit(1)
""",
        """    ok, text = verify_report(run, _run_spec(spec, [run]))
    typer.echo(text)
""",
        (f"{_CLI}[malformed]",),
    ),
]
"""Every check of ``roco spec verify`` behind a kind of violation (``KINDS`` of
services/spec_check/conformance.py) deleted in turn; tests/spec_check/test_every_kind.py plants
the fault each one finds."""


# ------------------------------------------------------- plan-check.: a_km's plan-check refusals

_PLAN_CHECK = "services/agents/knowledge/plan_check.py"
_WORLD_MODEL = "services/agents/knowledge/world_model.py"
_REFUSALS = "tests/agents/knowledge/test_plan_check_refusals.py"


def _refusal_off(name: str, file: str, condition: str, test: str) -> Mutant:
    """The refusal guarded by ``condition`` (the text of an ``if``, and what follows where that
    alone occurs more than once) deleted: the ``if`` made false (``if False and …``); ``test``
    (a test function of tests/agents/knowledge/test_plan_check_refusals.py) must fail."""
    return Mutant(
        name, file, condition, condition.replace("if ", "if False and ", 1), (f"{_REFUSALS}::{test}",)
    )


PLAN_CHECK_REFUSALS = [
    # ---- grasp(object, arm)
    _refusal_off(
        "plan-check.grasp.hand-holds-something",
        _PLAN_CHECK,
        "    if holding:",
        "test_a_grasp_with_a_hand_that_already_holds_something_is_refused",
    ),
    _refusal_off(
        "plan-check.grasp.other-hand-holds-it",
        _PLAN_CHECK,
        '    if info.held_by:\n        return f"the {step.object} is already held',
        "test_a_grasp_of_an_object_the_other_hand_holds_is_refused",
    ),
    _refusal_off(
        "plan-check.grasp.no-grasp-for-the-hand",
        _PLAN_CHECK,
        "    if not grasps:",
        "test_a_grasp_with_a_hand_the_object_has_no_grasp_for_is_refused",
    ),
    _refusal_off(
        "plan-check.grasp.no-grasp-where-it-stands",
        _PLAN_CHECK,
        "    if where and not any(not g.on or where in g.on for g in grasps):",
        "test_a_grasp_with_no_grasp_valid_where_the_object_stands_is_refused",
    ),
    # ---- any step: an individual a_km does not know
    Mutant(
        "plan-check.step.unknown-individual-escapes",
        _PLAN_CHECK,
        "    except KnowledgeError as exc:\n        return str(exc)",
        "    except KnowledgeError:\n        raise",
        (f"{_REFUSALS}::test_a_step_about_an_object_a_km_does_not_know_is_refused",),
    ),
    # ---- put(object, furniture)
    _refusal_off(
        "plan-check.put.not-in-a-hand",
        _PLAN_CHECK,
        '    if not info.held_by:\n        return f"the {step.object} is not in a hand"',
        "test_a_put_down_of_an_object_no_hand_holds_is_refused",
    ),
    _refusal_off(
        "plan-check.put.footprint-leaves-the-area",
        _PLAN_CHECK,
        "    if area is not None and not (",
        "test_a_put_down_whose_footprint_leaves_the_furniture_is_refused",
    ),
    _refusal_off(
        "plan-check.put.another-object-there",
        _PLAN_CHECK,
        "        if apart < need:",
        "test_a_put_down_where_another_object_stands_is_refused",
    ),
    _refusal_off(
        "plan-check.put.area-not-four-numbers",
        _PLAN_CHECK,
        "    if len(v) != 4:",
        "test_a_place_area_that_is_not_four_numbers_is_refused_naming_the_furniture",
    ),
    # ---- pour(source, target)
    _refusal_off(
        "plan-check.pour.source-not-in-a-hand",
        _PLAN_CHECK,
        "    if not src.held_by:",
        "test_a_pour_from_a_source_no_hand_holds_is_refused",
    ),
    _refusal_off(
        "plan-check.pour.content-unknown",
        _PLAN_CHECK,
        "    if src.particles is None:",
        "test_a_pour_whose_source_content_is_unknown_is_refused",
    ),
    _refusal_off(
        "plan-check.pour.source-empty",
        _PLAN_CHECK,
        "    if src.particles == 0:",
        "test_a_pour_from_an_empty_source_is_refused",
    ),
    _refusal_off(
        "plan-check.pour.capacity-unknown",
        _PLAN_CHECK,
        '    if room is None:\n        return f"how much',
        "test_a_pour_into_a_target_whose_capacity_is_unknown_is_refused",
    ),
    _refusal_off(
        "plan-check.pour.target-too-small",
        _PLAN_CHECK,
        "    if there + src.particles > room:",
        "test_a_pour_into_a_target_too_small_for_the_content_is_refused",
    ),
    Mutant(
        "plan-check.pour.capacity-not-whole",
        _PLAN_CHECK,
        '    except ValueError:\n        raise KnowledgeError(f"{container}: capacity',
        '    except ArithmeticError:\n        raise KnowledgeError(f"{container}: capacity',
        (f"{_REFUSALS}::test_a_capacity_that_is_not_a_whole_number_is_refused_naming_the_container",),
    ),
    # ---- the goal check (WorldModel.hypothetical)
    _refusal_off(
        "plan-check.goal.step-that-cannot-run",
        _WORLD_MODEL,
        "                if why is not None:",
        "test_the_goal_check_refuses_the_first_step_that_cannot_run_in_the_state_before_it",
    ),
    _refusal_off(
        "plan-check.goal.nested-hypothetical",
        _WORLD_MODEL,
        "        if isinstance(query, HypotheticalQuery):\n            raise UnsupportedQuery(",
        "test_a_hypothetical_query_inside_a_hypothetical_query_is_refused",
    ),
    Mutant(
        "plan-check.goal.not-evaluated",
        _WORLD_MODEL,
        "            return scratch.answer(query)",
        "            return Answer(boolean=True)",
        (f"{_REFUSALS}::test_the_goal_check_answers_false_for_steps_that_run_but_miss_the_goal",),
    ),
    Mutant(
        "plan-check.goal.takes-declared-effects",
        _WORLD_MODEL,
        "                scratch._apply(effects(scratch, step), stamp=None)",
        "                scratch._apply(step.changes, stamp=None)",
        (
            f"{_REFUSALS}::test_a_pour_whose_declared_effect_overstates_the_content_does_not_reach_the_goal",
            f"{_REFUSALS}::test_a_grasp_whose_declared_effect_puts_something_elsewhere_does_not_reach_the_goal",
        ),
    ),
]
"""Every refusal of a_km's plan check (services/agents/knowledge/plan_check.py) and of the goal
check built on it (``WorldModel.hypothetical``) deleted in turn: its condition made false, or
the error it turns into a refusal left to escape; tests/agents/knowledge/
test_plan_check_refusals.py plants the fault each one refuses."""


# ------------------------------------------------------------------ chaos.: roco chaos's questions

_CHAOS = "services/scenario/chaos.py"
_CHAOS_WORLD = "tests/scenario/test_chaos_world.py"
_CHAOS_RUN = "tests/scenario/test_chaos.py"
_CHAOS_LEDGER = "tests/scenario/test_chaos_ledger.py"
_EACH_QUESTION = f"{_CHAOS_WORLD}::test_each_question_says_no_to_its_own_planted_fault"


def _each_question(plant: str) -> str:
    """The node id of the planted fault ``plant`` (an id of test_chaos_world's
    ``test_each_question_says_no_to_its_own_planted_fault``)."""
    return f"{_EACH_QUESTION}[{plant}]"


def _verdict_without(name: str, term: str, tests: tuple[str, ...]) -> Mutant:
    """The question ``term`` (a line ``and …`` of ``Verdict.ok``) left out of the verdict
    ``roco chaos`` exits by; ``tests`` must fail."""
    return Mutant(name, _CHAOS, f"            {term}\n", "", tests)


CHAOS_QUESTIONS = [
    # ---- task done: a_hi's reports, and the world (the pour's share, each placement, its tilt)
    Mutant(
        "chaos.task-done.reports",
        _CHAOS,
        "        return self.reported_done and self.world.agrees\n",
        "        return self.world.agrees\n",
        (
            _each_question("report failed"),
            f"{_CHAOS_WORLD}::test_a_world_that_shows_the_task_done_does_not_make_a_failed_report_done",
        ),
    ),
    Mutant(
        "chaos.task-done.world",
        _CHAOS,
        "        return self.reported_done and self.world.agrees\n",
        "        return self.reported_done\n",
        (
            _each_question("spheres missing"),
            f"{_CHAOS_WORLD}::test_a_bowl_not_where_the_plan_put_it_is_not_the_task_done",
        ),
    ),
    Mutant(
        "chaos.task-done.world.final-scene",
        _CHAOS,
        "    if judged is not None:\n",
        "    if False:\n",
        (
            f"{_CHAOS_WORLD}::test_a_reported_success_with_spheres_missing_from_the_bowl_is_not_the_task_done",
            f"{_CHAOS_RUN}::test_an_object_that_fell_after_its_last_observation_is_found_in_the_final_world",
        ),
    ),
    Mutant(
        "chaos.task-done.world.pour",
        _CHAOS,
        '        if goal.name == "pour" and len(goal.args) == 2:\n',
        "        if False:\n",
        (_each_question("spheres missing"),),
    ),
    Mutant(
        "chaos.task-done.world.pour.share",
        _CHAOS,
        "    if target.particles_inside / total >= CONTENT_SHARE_REQUIRED:\n",
        "    if True:\n",
        (
            f"{_CHAOS_WORLD}::test_the_bowl_must_hold_the_share_a_pour_needs_by_the_simulation_s_count[16-False]",
            _each_question("spheres missing"),
        ),
    ),
    Mutant(
        "chaos.task-done.world.pour.not-known",
        _CHAOS,
        """        check.found.append(f"the {name}'s content is not known")\n""",
        "        pass\n",
        (f"{_CHAOS_WORLD}::test_an_object_that_leans_or_is_not_in_the_world_is_not_where_the_plan_put_it",),
    ),
    Mutant(
        "chaos.task-done.world.place.distance",
        _CHAOS,
        """        wrong.append(f"the {name} stands {100 * d:.1f} cm from where the plan put it")\n""",
        "        pass\n",
        (f"{_CHAOS_WORLD}::test_a_bowl_not_where_the_plan_put_it_is_not_the_task_done",),
    ),
    Mutant(
        "chaos.task-done.world.place.tilt",
        _CHAOS,
        """        wrong.append(f"the {name} leans {math.degrees(tilt):.0f}°")\n""",
        "        pass\n",
        (f"{_CHAOS_WORLD}::test_an_object_that_leans_or_is_not_in_the_world_is_not_where_the_plan_put_it",),
    ),
    Mutant(
        "chaos.task-done.world.place.not-known",
        _CHAOS,
        """        check.found.append(f"the {name} is not known (the plan put it down)")\n""",
        "        pass\n",
        (f"{_CHAOS_WORLD}::test_an_object_that_leans_or_is_not_in_the_world_is_not_where_the_plan_put_it",),
    ),
    Mutant(
        "chaos.task-done.world.place.planned",
        _CHAOS,
        "        places.update({e.object: e for e in action.expect})\n",
        "        pass\n",
        (f"{_CHAOS_WORLD}::test_a_bowl_not_where_the_plan_put_it_is_not_the_task_done",),
    ),
    Mutant(
        "chaos.task-done.world.place.taken-again",
        _CHAOS,
        "        places.pop(action.subject, None)\n",
        "        pass\n",
        (
            f"{_CHAOS_WORLD}::"
            "test_the_places_are_those_of_the_placements_a_ta_began_and_an_object_taken_again_has_none",
        ),
    ),
    # ---- no command lost
    Mutant(
        "chaos.command-lost",
        _CHAOS,
        "        commands_lost=sum(c.final is None for c in outcome.commands),\n",
        "        commands_lost=0,\n",
        (_each_question("command lost"),),
    ),
    # ---- nothing executed twice: two different answers, and ag_ex's ledger
    Mutant(
        "chaos.executed-twice.answers",
        _CHAOS,
        "        return not self.executed_twice and self.ledger.ok\n",
        "        return self.ledger.ok\n",
        (_each_question("executed twice"),),
    ),
    Mutant(
        "chaos.executed-twice.answers.differ",
        _CHAOS,
        "for (s, r), v in answers.items() if len(v) > 1)",
        "for (s, r), v in answers.items() if False)",
        (f"{_CHAOS_RUN}::test_a_second_execution_a_dropped_object_and_a_lost_command_are_found",),
    ),
    Mutant(
        "chaos.executed-twice.ledger",
        _CHAOS,
        "        return not self.executed_twice and self.ledger.ok\n",
        "        return not self.executed_twice\n",
        (f"{_CHAOS_LEDGER}::test_a_command_started_twice_with_one_answer_fails_the_question",),
    ),
    # ---- no object dropped: below the furniture, or never observed
    Mutant(
        "chaos.dropped",
        _CHAOS,
        "for name, z in last.items() if z < DROPPED_BELOW_M}",
        "for name, z in last.items() if False}",
        (
            _each_question("dropped"),
            f"{_CHAOS_RUN}::test_an_object_that_fell_after_its_last_observation_is_found_in_the_final_world",
        ),
    ),
    Mutant(
        "chaos.dropped.not-observed",
        _CHAOS,
        "        last_observation=set(last) == set(MOVABLE),\n",
        "        last_observation=True,\n",
        (f"{_CHAOS_WORLD}::test_an_object_ag_ex_never_observed_is_not_known_and_fails_no_object_dropped",),
    ),
    # ---- record intact
    Mutant(
        "chaos.record",
        _CHAOS,
        "        record=run.integrity,\n",
        "        record=Integrity(),\n",
        (_each_question("record"),),
    ),
    # ---- no agent raised
    Mutant(
        "chaos.raised",
        _CHAOS,
        "        raised=outcome.raised_line(),\n",
        '        raised="",\n',
        (_each_question("raised"), f"{_CHAOS_RUN}::test_an_agent_that_raised_fails_the_verdict"),
    ),
    # ---- each answer in the verdict roco chaos exits by (Verdict.ok); "no command lost" is not
    # left out: a lost command ended not as expected, and "task done" says no to it as well
    Mutant(
        "chaos.ok.record",
        _CHAOS,
        "            self.record.intact\n            and self.task_done\n",
        "            self.task_done\n",
        (_each_question("record"),),
    ),
    _verdict_without("chaos.ok.task-done", "and self.task_done", (_each_question("spheres missing"),)),
    _verdict_without(
        "chaos.ok.executed-twice",
        "and self.once",
        (
            _each_question("executed twice"),
            f"{_CHAOS_LEDGER}::test_a_command_started_twice_with_one_answer_fails_the_question",
        ),
    ),
    _verdict_without("chaos.ok.dropped", "and not self.dropped", (_each_question("dropped"),)),
    _verdict_without(
        "chaos.ok.not-observed",
        "and self.last_observation",
        (f"{_CHAOS_WORLD}::test_an_object_ag_ex_never_observed_is_not_known_and_fails_no_object_dropped",),
    ),
    _verdict_without(
        "chaos.ok.raised",
        "and not self.raised",
        (_each_question("raised"), f"{_CHAOS_RUN}::test_an_agent_that_raised_fails_the_verdict"),
    ),
]
"""Every question of ``roco chaos``'s verdict (the module docstring of services/scenario/
chaos.py) deleted in turn, and each answer left out of ``Verdict.ok``; each side of "task done"
apart (a_hi's reports; the world: the final scene over the robot's count, the pour's share, each
placement's distance and tilt). tests/scenario/test_chaos_world.py plants the fault each one
finds (test_chaos.py and test_chaos_ledger.py too)."""


# ------------------------------------------------------------------------------- all of them

GROUPS: dict[str, list[Mutant]] = {
    "verify.": VERIFY_KINDS,
    "plan-check.": PLAN_CHECK_REFUSALS,
    "chaos.": CHAOS_QUESTIONS,
}
"""The mutants by area: the prefix every name of the group starts with, and the group."""

MUTANTS: list[Mutant] = [mutant for group in GROUPS.values() for mutant in group]
"""Every mutant, in the order they run."""


# ---------------------------------------------------------------------------------------------


class SetupError(Exception):
    """The setup is not accepted: what a mutant would show would mean nothing."""


@dataclass(frozen=True)
class Outcome:
    """What the tests did in a copy: pytest's exit code (None: timed out), the seconds they
    took, and pytest's output."""

    returncode: int | None
    seconds: float
    output: str

    @property
    def verdict(self) -> str:
        """``caught`` (tests failed, or could not be collected), ``SURVIVED``, ``TIMEOUT``, or
        ``ERROR`` (pytest found no tests or was misused: rc 3–5)."""
        if self.returncode is None:
            return "TIMEOUT"
        if self.returncode == 0:
            return "SURVIVED"
        return "caught" if self.returncode in (1, 2) else f"ERROR (pytest exit {self.returncode})"

    @property
    def first_failure(self) -> str:
        """The first line of pytest's summary that names a failure or an error, else ''."""
        return next((line for line in self.output.splitlines() if line.startswith(("FAILED ", "ERROR "))), "")


def _left_out(root: Path, directory: str, names: list[str]) -> set[str]:
    """Of ``names`` in ``directory`` (a folder of ``root``), those the copy leaves out: the
    ``ignore`` of ``shutil.copytree``."""
    where = Path(directory).relative_to(root).parts
    at_top = not where
    compiled = bool(where) and where[0] in COMPILED_UNDER
    left: set[str] = set()
    for name in names:
        if os.path.isdir(os.path.join(directory, name)):
            patterns = LEFT_OUT_ANYWHERE + (LEFT_OUT_AT_TOP if at_top else ())
            if any(fnmatch.fnmatchcase(name, pattern) for pattern in patterns):
                left.add(name)
        elif compiled and name.endswith(".so"):
            left.add(name)
    return left


def copy_tree(root: Path, dest: Path) -> None:
    """``dest`` (new or empty) made a copy of ``root`` to mutate: without the folders of
    :data:`LEFT_OUT_AT_TOP` and :data:`LEFT_OUT_ANYWHERE`, and with no compiled extension under
    :data:`COMPILED_UNDER`. Symbolic links are copied as links."""
    root = root.resolve()
    shutil.copytree(
        root,
        dest,
        symlinks=True,
        ignore=lambda directory, names: _left_out(root, directory, names),
        dirs_exist_ok=True,
    )


def mutated(mutant: Mutant, source: str) -> str:
    """``source`` with ``mutant`` applied; SetupError when its snippet is not there exactly
    once or the result does not compile."""
    found = source.count(mutant.old)
    if found != 1:
        where = "not found" if found == 0 else f"found {found} times"
        raise SetupError(f"{mutant.name}: its snippet is {where} in {mutant.file}")
    changed = source.replace(mutant.old, mutant.new)
    try:
        compile(changed, mutant.file, "exec")
    except SyntaxError as exc:
        raise SetupError(f"{mutant.name}: {mutant.file} does not compile once mutated ({exc.msg})") from None
    return changed


def applies(root: Path, mutant: Mutant) -> None:
    """SetupError unless ``mutant`` can be applied to the tree ``root`` as it is."""
    path = root / mutant.file
    if not path.is_file():
        raise SetupError(f"{mutant.name}: no file {mutant.file}")
    mutated(mutant, path.read_text())


def check_snippets(root: Path, mutants: Sequence[Mutant]) -> None:
    """SetupError for the first mutant that cannot be applied to the tree as it is."""
    for mutant in mutants:
        applies(root, mutant)


def _environment(copy: Path) -> dict[str, str]:
    """The environment that imports ``copy``: it alone on ``PYTHONPATH``; no bytecode written
    (a mutated module and its source may share size and mtime)."""
    return {**os.environ, "PYTHONPATH": str(copy), "PYTHONDONTWRITEBYTECODE": "1"}


def run_tests(copy: Path, tests: Sequence[str], timeout_s: float) -> Outcome:
    """``tests`` run in ``copy`` with this interpreter, killed (with all it started) after
    ``timeout_s``."""
    started = time.monotonic()
    with subprocess.Popen(
        [sys.executable, *PYTEST, *tests],
        cwd=copy,
        env=_environment(copy),
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        start_new_session=True,
    ) as proc:
        try:
            output, _ = proc.communicate(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            output, _ = proc.communicate()
            return Outcome(None, time.monotonic() - started, output)
    return Outcome(proc.returncode, time.monotonic() - started, output)


def module_of(file: str) -> str | None:
    """The module a Python file of the repository is imported as; None for another file."""
    path = Path(file)
    if path.suffix != ".py":
        return None
    parts = path.with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def check_imports(copy: Path, modules: Sequence[str]) -> None:
    """SetupError unless each of ``modules`` is imported from its source in ``copy``."""
    probe = (
        "import importlib, sys\n"
        "for name in sys.argv[1:]: print('mutate_checks:', importlib.import_module(name).__file__)"
    )
    found = subprocess.run(
        [sys.executable, "-c", probe, *modules],
        cwd=copy,
        env=_environment(copy),
        capture_output=True,
        text=True,
    )
    if found.returncode != 0:
        raise SetupError(f"the mutated modules do not import from the copy:\n{found.stderr}")
    marker = "mutate_checks: "  # what a module prints as it is imported is no file of it
    files = [line.removeprefix(marker) for line in found.stdout.splitlines() if line.startswith(marker)]
    for name, file in zip(modules, files, strict=True):
        if not Path(file).resolve().is_relative_to(copy.resolve()) or not file.endswith(".py"):
            raise SetupError(f"{name} is imported from {file}, not from the copy's source")


def baseline(root: Path, mutants: Sequence[Mutant], timeout_s: float) -> float:
    """The tests of ``mutants`` run on an unmutated copy; SetupError unless they pass and every
    mutated module is imported from the copy. Returns the seconds they took."""
    tests = list(dict.fromkeys(t for m in mutants for t in m.tests))
    modules = sorted({name for m in mutants if (name := module_of(m.file)) is not None})
    with tempfile.TemporaryDirectory(prefix="mutate_checks_") as folder:
        copy = Path(folder)
        copy_tree(root, copy)
        check_imports(copy, modules)
        outcome = run_tests(copy, tests, timeout_s * 2)
    if outcome.returncode != 0:
        raise SetupError(f"the tests fail without a mutant ({outcome.verdict}):\n{outcome.output}")
    return outcome.seconds


def run_mutant(root: Path, mutant: Mutant, timeout_s: float) -> Outcome:
    """``mutant`` applied to a copy of the tree, and its tests run there."""
    with tempfile.TemporaryDirectory(prefix="mutate_checks_") as folder:
        copy = Path(folder)
        copy_tree(root, copy)
        path = copy / mutant.file
        path.write_text(mutated(mutant, path.read_text()))
        return run_tests(copy, mutant.tests, timeout_s)


def table(rows: Sequence[tuple[str, str, str, str]]) -> str:
    """``rows`` (mutant, verdict, seconds, first failure) as aligned text under a header."""
    header = ("mutant", "verdict", "s", "first failure")
    width = [max(len(r[k]) for r in (header, *rows)) for k in range(3)]
    return "\n".join(
        f"{r[0]:<{width[0]}}  {r[1]:<{width[1]}}  {r[2]:>{width[2]}}  {r[3]}".rstrip()
        for r in (header, *rows)
    )


def selected(mutants: Sequence[Mutant], prefixes: Sequence[str]) -> list[Mutant]:
    """The ``mutants`` whose name starts with one of ``prefixes`` (all of them when none)."""
    return [m for m in mutants if not prefixes or m.name.startswith(tuple(prefixes))]


def list_mutants(root: Path, mutants: Sequence[Mutant]) -> int:
    """Print each of ``mutants`` and whether it applies to ``root``; 2 when one does not."""
    bad = 0
    for m in mutants:
        try:
            applies(root, m)
            state = "ok"
        except SetupError as exc:
            state, bad = f"NOT APPLICABLE: {exc}", bad + 1
        print(f"{m.name}  {m.file}  {len(m.tests)} test(s)  {state}")
    print(f"{len(mutants)} mutant(s)" + (f"; {bad} not applicable" if bad else ""))
    return 2 if bad else 0


def _arguments(argv: Sequence[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument(
        "--only",
        action="append",
        default=[],
        metavar="PREFIX",
        help="only the mutants whose name starts so (repeatable: those of any of them)",
    )
    parser.add_argument(
        "--timeout",
        type=float,
        default=DEFAULT_TIMEOUT_S,
        metavar="S",
        help="seconds each mutant's tests may take",
    )
    parser.add_argument("--root", type=Path, default=ROOT, help="the repository to copy (default: this one)")
    parser.add_argument(
        "--list", action="store_true", help="list the mutants selected and whether they apply; run nothing"
    )
    return parser.parse_args(argv)


def main(argv: Sequence[str] | None = None, mutants: Sequence[Mutant] | None = None) -> int:
    """The script (``mutants``: :data:`MUTANTS` unless given); its exit code."""
    args = _arguments(argv)
    root: Path = args.root.resolve()
    chosen = selected(MUTANTS if mutants is None else mutants, args.only)
    if args.list:
        return list_mutants(root, chosen)
    rows: list[tuple[str, str, str, str]] = []
    try:
        if not chosen:
            raise SetupError(f"no mutant's name starts with {' or '.join(map(repr, args.only))}")
        check_snippets(root, chosen)
        seconds = baseline(root, chosen, args.timeout)
        print(f"baseline: the tests of {len(chosen)} mutant(s) pass unmutated ({seconds:.1f} s)", flush=True)
        for mutant in chosen:
            outcome = run_mutant(root, mutant, args.timeout)
            rows.append((mutant.name, outcome.verdict, f"{outcome.seconds:.1f}", outcome.first_failure))
            print(f"  {mutant.name}: {outcome.verdict}", file=sys.stderr, flush=True)
    except SetupError as exc:
        if rows:
            print(table(rows))
        print(f"mutate_checks: setup not accepted: {exc}", file=sys.stderr)
        return 2
    print(table(rows))
    missed = [name for name, verdict, _, _ in rows if verdict != "caught"]
    summary = f"{len(rows) - len(missed)} of {len(rows)} mutant(s) caught"
    print(summary + (f"; not caught: {', '.join(missed)}" if missed else ""))
    return 1 if missed else 0


if __name__ == "__main__":
    sys.exit(main())
