"""The sorting cell end to end, with roco's documented commands only (README.md beside cell.toml):
its specification checked, its fleet up under access control and TLS, a person's orders sent,
its sorter killed and started again with `roco fault`, its run verified, its requirements traced
(these tests' own marks), its report, its export and its compose file. One fleet serves every
test of the module."""

from __future__ import annotations

import json
import shutil
import socket
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

pytestmark = pytest.mark.xdist_group("sorting_cell")  # one fleet for the module, under pytest-xdist

SPEC = Path(__file__).resolve().parents[1] / "cell.toml"
ROCO = [sys.executable, "-m", "services.cli"]
"""``roco``, run by this interpreter (the console script of the same installation)."""
TIMEOUT_S = 120


def roco(*args: str, check: bool = False) -> subprocess.CompletedProcess[str]:
    """Run ``roco args…``; its exit status, stdout and stderr."""
    done = subprocess.run([*ROCO, *args], capture_output=True, text=True, timeout=TIMEOUT_S)
    if check:
        assert done.returncode == 0, done.stdout + done.stderr
    return done


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@dataclass
class CellRun:
    """The fleet's run folder and what roco said to each command."""

    run_dir: Path
    said: dict[str, subprocess.CompletedProcess[str]]
    status: subprocess.CompletedProcess[str]
    faults: dict[str, subprocess.CompletedProcess[str]]
    down: subprocess.CompletedProcess[str]


ORDERS = ("sort 3 bolts", "sort 2 apples", "hello", "sort 200 bolts")
"""Sorted; refused (no bin for apples); not understood; agreed, then failed: bin 1 holds 100
(the planted fault that violates R2.1, flagged live)."""
FAULTS = ("kill a_km", "kill a_so", "start a_so", "show")
"""`roco fault` on the fleet once the orders are done, in order: the kitchen's a_km is no service
of it; the sorter killed, then started again; every agent's fault settings."""


@pytest.fixture(scope="module")
def cell_run(tmp_path_factory: pytest.TempPathFactory) -> Iterator[CellRun]:
    """`roco up --spec cell.toml` (access control and TLS on, as by default), the
    ``ORDERS`` sent, `roco status`, the ``FAULTS``, `roco down`."""
    runs = tmp_path_factory.mktemp("cell_runs")
    up = roco("up", "--spec", str(SPEC), "--port", str(free_port()), "--runs-dir", str(runs))
    assert up.returncode == 0, up.stdout + up.stderr
    try:
        said = {line: roco("send", line, "--runs-dir", str(runs)) for line in ORDERS}
        status = roco("status", "--runs-dir", str(runs))
        faults = {args: roco("fault", *args.split(), "--runs-dir", str(runs)) for args in FAULTS}
    finally:
        down = roco("down", "--runs-dir", str(runs), check=True)
    (run_dir,) = [p for p in runs.iterdir() if p.is_dir()]
    yield CellRun(run_dir, said, status, faults, down)


def test_the_specification_is_sound_deadlock_free_and_the_code_matches_it() -> None:
    for tool in ("check", "deadlock", "verify-code"):
        roco("spec", tool, "--spec", str(SPEC), check=True)
    roco("spec", "names", "--check", "--spec", str(SPEC), check=True)


@pytest.mark.requirement("R1")
def test_a_person_s_order_is_taken_and_its_outcome_told(cell_run: CellRun) -> None:
    done = cell_run.said["sort 3 bolts"]
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines() == [
        "accepted: sorting 3 bolt(s)",
        "succeeded: 3 bolt(s) sorted into bin 1",
    ]
    refused = cell_run.said["sort 2 apples"]
    assert refused.returncode == 1 and refused.stdout.startswith("failed: the cell sorts bolt, nut")
    unread = cell_run.said["hello"]
    assert unread.returncode == 1 and unread.stdout.startswith("not-understood: say: sort <number> <item>")
    overflow = cell_run.said["sort 200 bolts"]
    assert overflow.returncode == 1 and overflow.stdout.splitlines()[-1] == "failed: bin 1 would overflow"


def test_status_lists_the_cell_s_agents_alive_and_the_requirement_violated_live(cell_run: CellRun) -> None:
    """The overflowing order failed after the sorter agreed: the recorder's live monitor flagged
    R2.1 as it happened, and `roco status` says so while the fleet runs."""
    assert cell_run.status.returncode == 0, cell_run.status.stderr
    lines = cell_run.status.stdout.splitlines()
    alive = [line.split()[0] for line in lines if " alive" in line]
    assert alive[:3] == ["a_cv", "a_so", "a_op"], cell_run.status.stdout
    (flag,) = [line for line in lines if line.startswith("violated")]
    assert (
        flag.startswith("violated  R2.1 “an agreed order is answered with the items sorted")
        and "failure" in flag
    )


def test_roco_fault_kills_and_starts_the_cell_s_agents(cell_run: CellRun) -> None:
    """`roco fault` with no --spec: the fleet's run folder keeps its specification, whose agents
    are the services it knows."""
    wrong, kill, start, show = (cell_run.faults[args] for args in FAULTS)
    assert wrong.returncode == 2 and wrong.stderr.splitlines() == [
        "roco: no service 'a_km' in a local fleet (services: router, recorder, a_cv, a_so, a_op)"
    ]
    assert kill.returncode == 0 and kill.stdout.startswith("roco: killed a_so (pid "), kill.stderr
    assert start.returncode == 0 and start.stdout.startswith("roco: started a_so (pid "), start.stderr
    assert show.returncode == 0, show.stderr
    assert [line.split()[0] for line in show.stdout.splitlines()] == ["a_cv", "a_so", "a_op"]


@pytest.mark.requirement("R2.1", "R2.2")
def test_the_run_conforms_and_its_requirements_are_traced(cell_run: CellRun) -> None:
    """Every conversation followed its protocol (the failed order too); R1 and R2.2 are shown,
    R2.1 is violated by the order that failed after the sorter agreed."""
    verified = roco("spec", "verify", str(cell_run.run_dir))  # the run remembers its specification
    assert verified.returncode == 0 and "full conformance: yes" in verified.stdout, verified.stdout
    traced = roco("spec", "trace", str(cell_run.run_dir))
    assert traced.returncode == 1, traced.stdout + traced.stderr
    assert "leaves: 2 shown, 0 not exercised, 1 violated (R2.1)" in traced.stdout
    assert "tests: none" not in traced.stdout  # these tests' marks are read


def test_a_mutated_record_does_not_verify(cell_run: CellRun, tmp_path: Path) -> None:
    """The planted fault: the sorter's first agree rewritten as an inform in a copy of the record."""
    copy = tmp_path / "run"
    shutil.copytree(cell_run.run_dir, copy)
    traffic = copy / "traffic.jsonl"
    lines = traffic.read_text().splitlines()
    i = next(i for i, line in enumerate(lines) if json.loads(line).get("performative") == "agree")
    lines[i] = lines[i].replace('"performative":"agree"', '"performative":"inform"')
    traffic.write_text("\n".join(lines) + "\n")
    verified = roco("spec", "verify", str(copy))
    assert verified.returncode == 1 and "full conformance: no" in verified.stdout, verified.stdout


def test_the_report_is_the_cell_s_without_kitchen_sections(cell_run: CellRun) -> None:
    report = (cell_run.run_dir / "report.md").read_text()
    assert "| System | SortingCell |" in report
    assert "| C1 | a_op–a_so |" in report and "| C2 | a_so–a_cv |" in report
    for kitchen in ("Spheres", "ag_ex", "paper (§5.7)", "Planning phases", "Control loop", "a_co"):
        assert kitchen not in report, kitchen
    # roco down's last line counts the run's communicates, not the kitchen's commands
    assert "14 communicates; report" in cell_run.down.stdout and "command" not in cell_run.down.stdout


def test_the_export_renders_the_cell_s_terms(cell_run: CellRun, tmp_path: Path) -> None:
    """`roco export RUN --mcap` reads the content in the languages of the run's specification:
    the person's first order is the JSON of the cell's Order term."""
    reader = pytest.importorskip("mcap.reader", reason="the ros2 extra's mcap is not installed")
    from services.ros2 import messages

    roco("export", str(cell_run.run_dir), "--mcap", str(tmp_path / "bag"), check=True)
    store = messages.typestore()
    with next((tmp_path / "bag").glob("*.mcap")).open("rb") as f:
        sent: list[Any] = [
            store.deserialize_cdr(m.data, schema.name)
            for schema, _, m in reader.make_reader(f).iter_messages()
            if schema.name == messages.COMMUNICATE
        ]
    orders = [c.content for c in sent if c.language == "L_ORD" and c.performative == "request"]
    assert orders, [(c.language, c.performative) for c in sent]
    assert {"item": "bolt", "count": 3}.items() <= json.loads(orders[0]).items(), orders[0]


def test_the_agents_that_take_only_communicates_replay_as_they_ran(cell_run: CellRun) -> None:
    """`roco replay RUN` with the run's own specification: the sorter and the conveyor send again
    what they sent; the operator, whose input is the person's lines, is not replayed."""
    replayed = roco("replay", str(cell_run.run_dir))
    assert replayed.returncode == 0, replayed.stdout + replayed.stderr
    lines = dict(line.split(": ", 1) for line in replayed.stdout.splitlines())
    assert lines["a_so"].startswith("reproduced") and lines["a_cv"].startswith("reproduced")
    assert lines["a_op"].startswith("not replayed")
