"""``roco spec trace RUN…``: the requirement tree with the steps and channels serving each leaf,
the tests that name it, the run communicates that exercise it and a verdict
(services/spec_check/trace.py).

The runs are part of a recorded ``roco scenario urgent_mid_pour`` with a foreign agent's
sentence on C8 added (tests/spec_check/recorded.py), and synthetic traffic records of real
encoded communicates (tests/report/conftest.py's pour: one command, its messages without
reply-with, so few properties hold there); no fleet runs."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from services.report.build import write_report
from services.report.load import load_run
from services.runtime.run_folder import RunInfo, write_run_info
from services.spec.decomposition import load_decomposition
from services.spec.model import DEFAULT_SPEC
from services.spec.requirements import leaves
from services.spec_check.marks import TESTS, MarkError, marked_tests
from services.spec_check.trace import TraceError, Verdict, report_rows, trace, trace_report
from shared.fipa_codec.languages.l_hc import CommandOutcome, Sentence, SentenceReport
from shared.fipa_codec.languages.l_wm import Answer, HypotheticalQuery, ObjectQuery, SceneQuery, SparqlQuery
from tests.report.conftest import COMMAND_TEXT, STARTED, RunBuilder, pour_run, write_traffic
from tests.spec_check.recorded import URGENT, URGENT_LEAVES, Recorded
from tests.spec_check.walkthrough import NEXT

SHIPPED = DEFAULT_SPEC.read_text()
JADE = "da0@host:1099/JADE"
LEAVES = [r.id for r in leaves(load_decomposition(DEFAULT_SPEC))]


def _complete(b: RunBuilder) -> RunBuilder:
    """The synthetic pour with what it lacks to exercise every leaf: C7, C4's scene and
    hypothetical queries answered by inform-ref, and a foreign agent's sentence on C8."""
    q = {"protocol": "fipa-query"}
    b.add(5.0, "C7", "a_hi", "a_km", "query-ref", SparqlQuery("SELECT ?x WHERE {}"), conversation="w1", **q)
    b.add(5.1, "C7", "a_km", "a_hi", "inform-ref", Answer(), conversation="w1", **q)
    b.add(45.0, "C4", "a_pl", "a_km", "query-ref", SceneQuery(), conversation="q5", **q)
    b.add(45.1, "C4", "a_km", "a_pl", "inform-ref", Answer(), conversation="q5", **q)
    hypothetical = HypotheticalQuery(changes=(), query=ObjectQuery("bowl"))
    b.add(45.2, "C4", "a_pl", "a_km", "query-ref", hypothetical, conversation="q6", **q)
    b.add(45.3, "C4", "a_km", "a_pl", "inform-ref", Answer(), conversation="q6", **q)
    r = {"protocol": "fipa-request", "conversation": "j1"}
    b.add(46.0, "C8", JADE, "a_hi", "request", Sentence(text="what are you doing?"), **r)
    b.add(46.1, "C8", "a_hi", JADE, "inform", SentenceReport(kind="status", text="nothing"), **r)
    return b


def _run(tmp_path: Path, b: RunBuilder, name: str = "run") -> Path:
    """A run folder: ``run.json`` (its start: times count from STARTED) and ``b``'s traffic."""
    run_dir = tmp_path / name
    run_dir.mkdir()
    write_run_info(run_dir, RunInfo(command=COMMAND_TEXT, started=STARTED))
    write_traffic(run_dir, b)
    return run_dir


def _c8() -> RunBuilder:
    """A foreign agent's sentence answered on C8, 46 s into the run."""
    b = RunBuilder()
    r = {"protocol": "fipa-request", "conversation": "j1"}
    b.add(46.0, "C8", JADE, "a_hi", "request", Sentence(text="what are you doing?"), reply_with="j1-r", **r)
    b.add(
        46.1,
        "C8",
        "a_hi",
        JADE,
        "inform",
        SentenceReport(kind="status", text="nothing"),
        in_reply_to="j1-r",
        **r,
    )
    return b


COMPLETE_LEAVES = (*URGENT_LEAVES, "R1.4")
"""What ``complete`` shows: every leaf of the shipped specification."""
ADDED = [rid for rid in LEAVES if rid not in COMPLETE_LEAVES]
"""Leaves added to the specification since (none in the shipped one): ``complete`` shows none."""


@pytest.fixture
def complete(tmp_path: Path) -> Path:
    """The recorded urgent scenario with a sentence on C8: every shipped leaf shown."""
    return Recorded.read(URGENT).plus(_c8()).write(tmp_path / "complete")


def test_every_leaf_of_a_run_that_exercises_it_is_shown(complete: Path) -> None:
    t = trace(DEFAULT_SPEC, [complete], tests=None)
    verdicts = {rid: leaf.verdict for rid, leaf in t.leaves.items()}
    assert {rid: verdicts[rid] for rid in COMPLETE_LEAVES} == dict.fromkeys(COMPLETE_LEAVES, Verdict.SHOWN)
    assert t.count(Verdict.SHOWN) == [rid for rid in LEAVES if rid in COMPLETE_LEAVES]
    assert t.verdict("R") is (Verdict.NOT_EXERCISED if ADDED else Verdict.SHOWN)
    # R2.1: the urgent command at 18.3 s, the cancel at 18.4 s, Preempted 21.3 s, the cup's plan 21.5 s
    (judged,) = t.leaves["R2.1"].runs
    assert [round(m.t, 1) for m in judged.outcomes[0].events] == [8.3, 18.3, 18.4, 18.4, 21.3, 21.5]


def test_a_plain_pour_exercises_neither_the_decision_nor_the_interruption(tmp_path: Path) -> None:
    """The synthetic pour: one command (no decision between two), no cancel; its requests
    carry no reply-with, so nothing answers them; C4 answers by inform only; no C7, no C8."""
    run_dir = _run(tmp_path, pour_run())
    t = trace(DEFAULT_SPEC, [run_dir], tests=None)
    assert (
        t.leaves["R1.2"].verdict is Verdict.NOT_EXERCISED
        and t.leaves["R2.1"].verdict is Verdict.NOT_EXERCISED
    )
    assert t.count(Verdict.VIOLATED) == []
    assert t.verdict("R1") is Verdict.NOT_EXERCISED
    code, text = trace_report([run_dir], DEFAULT_SPEC, tests=None)
    assert code == 0
    assert (
        "a sentence from another platform is answered with its report: not exercised: no step matched" in text
    )
    assert "with two commands open, the next plan run is the more urgent one's, and it is answered: " in text
    assert "not exercised: step 1 matched, then no C2 fipa-request request HumanCommand" in text
    assert trace_report([run_dir], DEFAULT_SPEC, tests=None, require_shown=True)[0] == 1


def test_two_runs_together_show_what_each_shows(tmp_path: Path) -> None:
    urgent = Recorded.read(URGENT).write(tmp_path / "urgent")
    gateway_dir = _run(tmp_path, _c8(), "gateway")
    t = trace(DEFAULT_SPEC, [urgent, gateway_dir], tests=None)
    assert t.count(Verdict.NOT_EXERCISED) == ADDED  # R1.4 by the second run, the rest by the first
    assert [j.verdict for j in t.leaves["R1.4"].runs] == [Verdict.NOT_EXERCISED, Verdict.SHOWN]


def test_a_planted_requirement_that_nothing_serves_is_not_shown(complete: Path, tmp_path: Path) -> None:
    spec = tmp_path / "planted.toml"
    rid = NEXT.requirement  # R4 in the shipped specification
    planted = f'[[requirements]]\nid = "{rid}"\nparent = "R"\ntext = "fold the laundry"\n\n'
    assert SHIPPED.count("\n[[steps]]\nnumber = 1\n") == 1
    spec.write_text(SHIPPED.replace("\n[[steps]]\nnumber = 1\n", f"\n{planted}[[steps]]\nnumber = 1\n"))
    code, text = trace_report([complete], spec, tests=None)
    assert code == 0
    planted_lines = [
        f"{rid} [not exercised] fold the laundry",
        "served by: no step",
        "tests: none",
        "in complete: not exercised (no property)",
    ]
    assert "\n    ".join(planted_lines) in text
    assert "R [not exercised]" in text
    counted = re.search(r"leaves: 11 shown, (\d+) not exercised \(([^)]*)\), 0 violated", text)
    assert counted and sorted(counted[2].split(", ")) == sorted([*ADDED, rid]), text
    assert int(counted[1]) == len(ADDED) + 1
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "services.cli",
            "spec",
            "trace",
            str(complete),
            "--spec",
            str(spec),
            "--require-shown",
        ],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 1 and f"not exercised ({counted[2]})" in proc.stdout, proc.stdout + proc.stderr


def test_a_violation_on_a_serving_channel_contradicts_the_requirement(tmp_path: Path) -> None:
    b = _complete(pour_run())
    # a_ta initiates fipa-request on C5: ag_ex's inform is not a_ta's to send
    b.add(47.0, "C5", "a_ta", "ag_ex", "inform", conversation="ex-9", protocol="fipa-request")
    run_dir = _run(tmp_path, b)
    t = trace(DEFAULT_SPEC, [run_dir], tests=None)
    # C5 serves R3.1 and R3.3 only (step 5, with C1 and C6): the others stand
    assert t.count(Verdict.VIOLATED) == ["R3.1", "R3.3"]
    assert t.leaves["R3.1"].runs[0].against == ("1 conformance violation(s) on C5 in run",)
    assert t.verdict("R3") is Verdict.VIOLATED and t.verdict("R") is Verdict.VIOLATED
    proc = subprocess.run(
        [sys.executable, "-m", "services.cli", "spec", "trace", str(run_dir)], capture_output=True, text=True
    )
    assert proc.returncode == 1 and "against it: 1 conformance violation(s) on C5 in run" in proc.stdout


def test_a_failed_command_contradicts_the_requirements_about_the_task(tmp_path: Path) -> None:
    failed = pour_run()
    outcome = failed.records.pop()  # the pour's outcome, replaced by a failed one
    failed.payloads.pop()
    assert (outcome.channel, outcome.performative) == ("C2", "inform")
    failed.add(
        44.0,
        "C2",
        "a_co",
        "a_hi",
        "inform",
        CommandOutcome(command_id="cmd-1", succeeded=False, detail="the jar slipped"),
        conversation="cmd-1",
        protocol="fipa-request",
    )
    t = trace(DEFAULT_SPEC, [_run(tmp_path, _complete(failed))], tests=None)
    assert t.count(Verdict.VIOLATED) == ["R3.1"]  # the only one with task = true
    assert t.leaves["R3.1"].runs[0].against == ("command failed in run: pour the jar into the bowl",)


def test_a_folder_that_is_not_a_run_or_a_bad_spec_is_one_line_and_exit_2(
    tmp_path: Path, complete: Path
) -> None:
    with pytest.raises(TraceError, match="no such run folder"):
        trace(DEFAULT_SPEC, [tmp_path / "nothing"], tests=None)
    bad = tmp_path / "bad.toml"
    bad.write_text(SHIPPED.replace('content = "SparqlQuery" }', 'content = "Nonsense" }', 1))
    with pytest.raises(TraceError, match=r"R1\.3, property 1 .*, step 1 .*lists no content Nonsense"):
        trace(bad, [complete], tests=None)
    proc = subprocess.run(
        [sys.executable, "-m", "services.cli", "spec", "trace", str(complete), "--spec", str(bad)],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 2 and proc.stderr.startswith("roco: ") and proc.stderr.count("\n") == 1


# ---- the tests that name requirements -------------------------------------------------------

MARKED = """\
import pytest
from pytest import mark

pytestmark = [pytest.mark.slow, pytest.mark.requirement("R3")]


@pytest.mark.parametrize("x", [1, 2])
@pytest.mark.requirement("R1.1", "R1.2")
def test_one(x): ...


def test_two(): ...


@mark.requirement("R2.1")
class TestThree:
    def test_a(self): ...

    def helper(self): ...


def helper(): ...
"""


def test_markers_are_read_from_functions_classes_and_modules(tmp_path: Path) -> None:
    folder = tmp_path / "tests"
    (folder / "sub").mkdir(parents=True)
    (folder / "sub" / "test_marked.py").write_text(MARKED)
    (folder / "test_plain.py").write_text("def test_nothing(): ...\n")
    (folder / "conftest.py").write_text(
        'import pytest\n\n@pytest.mark.requirement("R9")\ndef test_x(): ...\n'
    )
    found = marked_tests(folder, {"R", "R1.1", "R1.2", "R2.1", "R3"})
    assert [(t.node, t.line, t.requirements) for t in found] == [
        ("tests/sub/test_marked.py::test_one", 9, ("R3", "R1.1", "R1.2")),
        ("tests/sub/test_marked.py::test_two", 12, ("R3",)),
        ("tests/sub/test_marked.py::TestThree::test_a", 17, ("R3", "R2.1")),
    ]


@pytest.mark.parametrize(
    ("source", "says"),
    [
        (
            'import pytest\n\n@pytest.mark.requirement("R7")\ndef test_x(): ...\n',
            "test_bad.py:3: unknown requirement 'R7'",
        ),
        (
            "import pytest\n\n\nclass TestX:\n    pass\n\n@pytest.mark.requirement(ID)\ndef test_x(): ...\n",
            "test_bad.py:7: pytest.mark.requirement takes string literals",
        ),
        ("def test_x(:\n", "test_bad.py: not Python"),
    ],
)
def test_a_marker_naming_no_requirement_is_an_error_naming_its_place(
    tmp_path: Path, source: str, says: str
) -> None:
    folder = tmp_path / "tests"
    folder.mkdir()
    (folder / "test_bad.py").write_text(source)
    with pytest.raises(MarkError, match=says.replace("(", r"\(")):
        marked_tests(folder, {"R1"})
    with pytest.raises(TraceError):
        trace(DEFAULT_SPEC, [], tests=folder)


def test_the_projects_markers_name_known_requirements_and_every_leaf_has_a_test() -> None:
    ids = {r.id for r in load_decomposition(DEFAULT_SPEC).requirements}
    found = marked_tests(TESTS, ids)
    named = {rid for t in found for rid in t.requirements}
    untested = sorted(set(LEAVES) - named)
    assert not untested, f"no test marked @pytest.mark.requirement(...) for {', '.join(untested)}"
    assert all(t.node.startswith("tests/") and "::test" in t.node for t in found)


# ---- the run report's table ----------------------------------------------------------------


def test_the_report_lists_the_requirements_with_their_verdicts(complete: Path) -> None:
    rows = report_rows(load_run(complete))
    assert [r.id for r in rows][:3] == ["R", "R1", "R1.1"] and len(rows) == len(
        load_decomposition(DEFAULT_SPEC).requirements
    )
    r14 = next(r for r in rows if r.id == "R1.4")
    assert (
        r14.verdict == "shown" and (r14.first_t, r14.last_t) == pytest.approx((46.0, 46.1)) and r14.tests >= 1
    )
    assert r14.channels == ["C8 (x_fipa–a_hi)"] and r14.steps == [8]
    md = write_report(complete, tracer=report_rows).read_text()
    assert "Requirements traced to this run (paper Table 7 generalised)" in md
    assert "| R1.4 take commands from agents of other FIPA platforms" in md and "**shown**" in md
    assert "Requirements traced" not in write_report(complete).read_text()  # no tracer: no section


def test_a_report_whose_requirements_cannot_be_traced_says_why(
    complete: Path, monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text("not toml [")
    monkeypatch.setenv("ROCO_SPEC", str(bad))
    md = write_report(complete, tracer=report_rows).read_text()
    assert "requirements not traced: " in md and "Requirements traced" not in md


def test_the_report_a_fleet_s_end_writes_traces_the_requirements(complete: Path) -> None:
    """``roco down`` and ``roco hosts down`` pass the tracer to services/report/ending.py."""
    from services.report.ending import end

    ending = end(complete, ended=STARTED + 50.0, tracer=report_rows)
    assert ending.problem == "" and ending.path is not None
    md = ending.path.read_text()
    assert "Requirements traced to this run" in md and "| R3.2 update the environment model" in md
