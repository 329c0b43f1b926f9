"""``roco spec trace RUN…``: the requirement tree (paper §5.1, Figure 5) with, for each
requirement, the evidence that it holds.

For each leaf requirement:

- **served by**: the decomposition steps that list it and the channels they create,
  reallocate or supplement, each with the two agents it joins in the end (paper §5.2;
  services/spec/requirements.py ``served``);
- **tests**: the tests that name it with ``@pytest.mark.requirement("R…")``, found by reading
  the test files (services/spec_check/marks.py; nothing is run);
- **properties**: per run, each of its ``properties`` (services/spec/properties.py; a leaf
  without them: one property per ``evidence`` statement, or per serving channel) evaluated over
  the run's communicates in causal order (services/recorder/causal.py) by
  services/spec_check/properties.py, with the times of the events that matched;
- **verdict**, one of :class:`Verdict`:

  - *violated*: in some run, ``roco spec verify`` (services/spec_check/conformance.py) found a
    violation on a channel serving the requirement; or the requirement says ``task = true``
    and a command of the run failed (a_co answered it on C2 with a failed ``CommandOutcome``,
    a failure or a refuse: services/report/coordination.py ``commands``; a command the person
    stopped did not fail); or the run matched a property's situation (its first
    ``exercised`` steps) and not the rest;
  - *shown*: not violated, and in one run every property matched;
  - *not exercised*: neither: no run brought about what it is about (or nothing serves it).

A requirement with children is judged from its leaves: violated when one is, shown when all
are, else not exercised. ``roco spec trace`` exits 0 when no leaf is violated (and, with
``--require-shown``, every leaf is shown); 1 when a leaf is violated or, with
``--require-shown``, one is not exercised; 2 for a specification, a run folder or a marker
that cannot be read.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from services.recorder.causal import causal_order, send_order
from services.report.coordination import commands
from services.report.load import Message, RunData, load_run
from services.report.model import RequirementRow
from services.runtime.run_folder import spec_for_run
from services.spec.decomposition import Decomposition, Requirement, load_decomposition
from services.spec.model import SpecError, SystemSpec, load, system_root
from services.spec.protocol_defs import protocols_of
from services.spec.requirements import Served, children, evidence_problems, leaves, properties_of, served
from services.spec_check.conformance import verify_run
from services.spec_check.marks import TESTS, MarkError, by_requirement, marked_tests
from services.spec_check.properties import Outcome, Verdict, evaluate
from shared.fipa_codec.protocols import Protocol

__all__ = [
    "LeafTrace",
    "Trace",
    "TraceError",
    "Verdict",
    "render",
    "report_rows",
    "trace",
    "trace_report",
    "trace_runs",
]


class TraceError(ValueError):
    """A specification, run folder or test marker that cannot be read; one line naming it."""


@dataclass(frozen=True)
class RunFacts:
    """What one run folder says: its ``label`` (the folder's name), its communicates
    (``messages``, copies left out, in causal order), the conformance ``violations`` per channel, the
    ``failed`` commands' texts, and ``notes`` on reading it."""

    label: str
    messages: tuple[Message, ...]
    violations: Counter[str]
    failed: tuple[str, ...]
    notes: tuple[str, ...] = ()


@dataclass(frozen=True)
class RunJudgement:
    """One leaf in one run: each property's outcome and the reasons the run violates the leaf
    besides its properties (empty: none)."""

    run: str
    outcomes: tuple[Outcome, ...]
    against: tuple[str, ...]

    @property
    def verdict(self) -> Verdict:
        if self.against or any(o.verdict == Verdict.VIOLATED for o in self.outcomes):
            return Verdict.VIOLATED
        if self.outcomes and all(o.verdict == Verdict.SHOWN for o in self.outcomes):
            return Verdict.SHOWN
        return Verdict.NOT_EXERCISED

    @property
    def span(self) -> tuple[float, float] | None:
        """The first and last matched event (s since the run began), None without one."""
        times = [m.t for o in self.outcomes for m in o.events]
        return (min(times), max(times)) if times else None


@dataclass(frozen=True)
class LeafTrace:
    """One leaf requirement with its evidence: how it is ``served``, the ``tests`` that name
    it (node ids), one judgement per run, and the verdict."""

    requirement: Requirement
    served: Served
    tests: tuple[str, ...]
    runs: tuple[RunJudgement, ...]

    @property
    def verdict(self) -> Verdict:
        verdicts = {j.verdict for j in self.runs}
        for v in (Verdict.VIOLATED, Verdict.SHOWN):
            if v in verdicts:
                return v
        return Verdict.NOT_EXERCISED


@dataclass
class Trace:
    """The whole tree traced: the specification's ``system`` and ``path``, the decomposition
    ``d`` (the tree), each leaf's trace by id, the channels' ends, the runs' labels and
    notes, and the tests marked on requirements that are not leaves (by id)."""

    system: str
    path: Path
    d: Decomposition
    leaves: dict[str, LeafTrace]
    ends: dict[str, tuple[str, str]]
    runs: list[str]
    inner_tests: dict[str, list[str]] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    def verdict(self, rid: str) -> Verdict:
        """A leaf's verdict, or a parent's from its leaves (see the module docstring)."""
        if rid in self.leaves:
            return self.leaves[rid].verdict
        below = [self.verdict(c.id) for c in children(self.d).get(rid, [])]
        if Verdict.VIOLATED in below:
            return Verdict.VIOLATED
        return Verdict.SHOWN if below and all(v == Verdict.SHOWN for v in below) else Verdict.NOT_EXERCISED

    def count(self, verdict: Verdict) -> list[str]:
        """The leaves with ``verdict``, in file order."""
        return [rid for rid, leaf in self.leaves.items() if leaf.verdict == verdict]


# ---------------------------------------------------------------------------------------------


def run_facts(run: RunData, spec: SystemSpec, protocols: Mapping[str, Protocol] | None = None) -> RunFacts:
    """The facts of a run folder already read: its conformance checked against ``spec`` and
    the state machines ``protocols`` (None: FIPA's, as :func:`verify_run`)."""
    conformance = verify_run(run.run_dir, spec, protocols=protocols)
    notes = [] if conformance.record.intact else [f"traffic record {conformance.record.summary()}"]
    causal, _ = causal_order([m for m in run.messages if m.copy_of is None])
    ordered, _ = send_order(causal)
    return RunFacts(
        label=Path(run.run_dir).name,
        messages=tuple(ordered),
        violations=Counter(v.channel for v in conformance.violations),
        failed=tuple(row.text for row in commands(run.messages) if row.outcome == "failed"),
        notes=tuple(notes),
    )


def judge(requirement: Requirement, serving: Served, facts: RunFacts) -> RunJudgement:
    """``requirement`` in one run: its properties evaluated, and what else violates it (a
    violation on a serving channel; a failed command when it says ``task = true``)."""
    against = [
        f"{facts.violations[c]} conformance violation(s) on {c} in {facts.label}"
        for c in serving.channels
        if facts.violations[c]
    ]
    if requirement.task:
        against += [f"command failed in {facts.label}: {text}" for text in facts.failed]
    outcomes = tuple(evaluate(p, facts.messages) for p in properties_of(requirement, serving))
    return RunJudgement(facts.label, outcomes, tuple(against))


def _tests(tests: Path | None, known: set[str]) -> dict[str, list[str]]:
    """Requirement id → the tests under ``tests`` that name it. Raises TraceError."""
    if tests is None:
        return {}
    try:
        return by_requirement(marked_tests(tests, known))
    except MarkError as exc:
        raise TraceError(str(exc)) from None


def trace_runs(
    spec_path: Path, d: Decomposition, spec: SystemSpec, facts: Sequence[RunFacts], tests: Path | None
) -> Trace:
    """The tree of ``d`` traced over the runs' ``facts`` and the tests under ``tests`` (None:
    no tests read). Raises TraceError for an evidence statement that does not fit the
    specification or a test marker that names no requirement."""
    problems = evidence_problems(d, spec)
    if problems:
        raise TraceError(f"{spec_path}: {problems[0]}")
    named = _tests(tests, {r.id for r in d.requirements})
    traced = _leaves(d, named, facts)
    return Trace(
        system=spec.system,
        path=spec_path,
        d=d,
        leaves=traced,
        ends={c.name: c.ends for c in spec.channels},
        runs=[f.label for f in facts],
        inner_tests={rid: t for rid, t in named.items() if rid not in traced},
        notes=[f"{f.label}: {n}" for f in facts for n in f.notes],
    )


def _leaves(d: Decomposition, named: dict[str, list[str]], facts: Sequence[RunFacts]) -> dict[str, LeafTrace]:
    """Each leaf of ``d`` (by id) with its tests (``named``) and its judgement in each run."""
    serving = served(d)
    out = {}
    for r in leaves(d):
        runs = tuple(judge(r, serving[r.id], f) for f in facts)
        out[r.id] = LeafTrace(r, serving[r.id], tuple(named.get(r.id, ())), runs)
    return out


def load_spec(spec_path: Path) -> tuple[Decomposition, SystemSpec, dict[str, Protocol]]:
    """The requirement tree, the channels and the protocols' state machines of ``spec_path``
    (as ``roco spec verify --spec`` reads them). Raises TraceError."""
    try:
        return load_decomposition(spec_path), load(spec_path), protocols_of(spec_path)
    except SpecError as exc:
        raise TraceError(str(exc)) from None


def tests_beside(spec_path: Path) -> Path:
    """The tests of the system ``spec_path`` specifies: ``tests/`` in its root
    (services/spec/model.py ``system_root``): roco's for the shipped specification, else the
    folder beside the specification."""
    return system_root(spec_path) / "tests"


def trace(spec_path: Path, run_dirs: Sequence[Path], tests: Path | None = TESTS) -> Trace:
    """Read the specification, the runs and the tests, and trace the tree (see the module
    docstring). Raises TraceError for anything that cannot be read."""
    d, spec, protocols = load_spec(spec_path)
    facts = []
    for run_dir in run_dirs:
        try:
            facts.append(run_facts(load_run(Path(run_dir)), spec, protocols))
        except FileNotFoundError:
            raise TraceError(f"{run_dir}: no such run folder") from None
    return trace_runs(spec_path, d, spec, facts, tests if tests is not None and tests.is_dir() else None)


# ---------------------------------------------------------------------------------------------


def _served_text(leaf: LeafTrace, ends: dict[str, tuple[str, str]]) -> str:
    if not leaf.served.steps:
        return "no step"
    steps = ", ".join(map(str, leaf.served.steps))
    channels = ", ".join(f"{c} ({'–'.join(ends[c])})" if c in ends else c for c in leaf.served.channels)
    return f"step{'s' if len(leaf.served.steps) > 1 else ''} {steps}; channels {channels or 'none'}"


def _tests_lines(tests: Sequence[str], pad: str) -> list[str]:
    if not tests:
        return [f"{pad}  tests: none"]
    return [f"{pad}  tests ({len(tests)}):", *(f"{pad}    {node}" for node in tests)]


def _leaf_lines(leaf: LeafTrace, t: Trace, pad: str) -> list[str]:
    lines = [f"{pad}  served by: {_served_text(leaf, t.ends)}", *_tests_lines(leaf.tests, pad)]
    for j in leaf.runs:
        lines.append(f"{pad}  in {j.run}: {j.verdict}" + ("" if j.outcomes else " (no property)"))
        lines += [f"{pad}    {o.prop.text}: {o.describe()}" for o in j.outcomes]
        lines += [f"{pad}    against it: {reason}" for reason in j.against]
    return lines


def _node_lines(t: Trace, r: Requirement, depth: int) -> list[str]:
    pad = "  " * depth
    lines = [f"{pad}{r.id} [{t.verdict(r.id)}] {r.text}"]
    if r.id in t.leaves:
        return lines + _leaf_lines(t.leaves[r.id], t, pad)
    if r.id in t.inner_tests:
        lines += _tests_lines(t.inner_tests[r.id], pad)
    for child in children(t.d).get(r.id, []):
        lines += _node_lines(t, child, depth + 1)
    return lines


def summary(t: Trace) -> str:
    """``leaves: 9 shown, 1 not exercised (R1.4), 0 violated``."""
    parts = []
    for v in Verdict:
        ids = t.count(v)
        parts.append(f"{len(ids)} {v}" + (f" ({', '.join(ids)})" if ids and v != Verdict.SHOWN else ""))
    return "leaves: " + ", ".join(parts)


def render(t: Trace) -> str:
    """The tree as text: each requirement with its verdict, each leaf with what serves it,
    its tests and its properties' outcomes per run; then the notes and the summary."""
    runs = ", ".join(t.runs) or "none"
    lines = [f"Requirements of {t.system} ({t.path}) traced to evidence; runs: {runs}"]
    for root in children(t.d).get(None, []):
        lines += _node_lines(t, root, 0)
    lines += [f"note: {n}" for n in t.notes]
    lines.append(summary(t))
    return "\n".join(lines)


def trace_report(
    run_dirs: Sequence[Path], spec_path: Path, *, require_shown: bool = False, tests: Path | None = TESTS
) -> tuple[int, str]:
    """``roco spec trace``: (exit code, text). 0: no leaf violated (and, with
    ``require_shown``, every leaf shown); 1: otherwise. Raises TraceError (exit 2)."""
    t = trace(spec_path, run_dirs, tests)
    failed = bool(t.count(Verdict.VIOLATED)) or (require_shown and bool(t.count(Verdict.NOT_EXERCISED)))
    return (1 if failed else 0), render(t)


# ---------------------------------------------------------------------------------------------


def _row(t: Trace, r: Requirement, depth: int) -> RequirementRow:
    """One requirement of ``t`` (traced over one run) as a row of the report."""
    leaf = t.leaves.get(r.id)
    serving = leaf.served if leaf is not None else served(t.d)[r.id]
    row = RequirementRow(
        id=r.id,
        depth=depth,
        text=r.text,
        steps=list(serving.steps),
        channels=[f"{c} ({'–'.join(t.ends[c])})" if c in t.ends else c for c in serving.channels],
        tests=len(leaf.tests) if leaf is not None else len(t.inner_tests.get(r.id, [])),
        verdict=str(t.verdict(r.id)),
    )
    if leaf is not None and leaf.runs:
        j = leaf.runs[0]
        row.evidence = [f"{o.prop.text}: {o.verdict}" for o in j.outcomes]
        row.against = list(j.against)
        row.first_t, row.last_t = j.span or (None, None)
    return row


def _rows(t: Trace, r: Requirement, depth: int) -> list[RequirementRow]:
    out = [_row(t, r, depth)]
    for child in children(t.d).get(r.id, []):
        out += _rows(t, child, depth + 1)
    return out


def report_rows(run: RunData) -> list[RequirementRow]:
    """The requirement tree traced to one run already read, as the report's rows (parents
    before their children), against the specification ``ROCO_SPEC`` names, else the one the
    run used, else the shipped one (services/runtime/run_folder.py ``spec_for_run``), and the
    system's tests (:func:`tests_beside`). Raises TraceError (a ValueError) when the
    specification or a test marker cannot be read."""
    path = spec_for_run(run.run_dir)
    d, spec, protocols = load_spec(path)
    tests = tests_beside(path)
    t = trace_runs(path, d, spec, [run_facts(run, spec, protocols)], tests if tests.is_dir() else None)
    return [row for root in children(d).get(None, []) for row in _rows(t, root, 0)]
