"""`roco chaos` finds a command the robot ran twice with one answer, in a real fleet: a planted
ag_ex (tests/support/twice_ex.py, named as ag_ex's implementation in a copy of the
specification) runs its first Observe twice and answers once. The record alone cannot tell (one
answer); ag_ex's ledger (velma/executor/ledger.py) shows two starts of that conversation, and
the "nothing executed twice" question fails. One fleet run: a pour with one pause of a_pl
(about 60–120 s on a 2-core VM)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from services.report.ledger import judge_ledger
from services.report.load import load_run
from services.scenario.chaos import CHAOS_FILE
from services.spec.model import DEFAULT_SPEC

pytestmark = [pytest.mark.slow, pytest.mark.fleet]
ROOT = Path(__file__).resolve().parents[2]
REAL = 'implementation = "services.agents.executor.agent:ExecutorAgent"'
PLANTED = 'implementation = "tests.support.twice_ex:TwiceExecutor"'


def test_an_observe_run_twice_by_a_planted_ag_ex_fails_nothing_executed_twice(tmp_path: Path) -> None:
    text = DEFAULT_SPEC.read_text(encoding="utf-8")
    assert text.count(REAL) == 1
    spec = tmp_path / "planted.toml"
    spec.write_text(text.replace(REAL, PLANTED), encoding="utf-8")
    runs = tmp_path / "runs"
    env = {**os.environ, "ROCO_SPEC": str(spec), "PYTHONPATH": str(ROOT)}
    chaos = ("chaos", "--seed", "0", "--services", "a_pl", "--count", "1", "--kinds", "pause", "--quiet")
    proc = subprocess.run(
        [sys.executable, "-m", "services.cli", *chaos, "--runs-dir", str(runs)],
        capture_output=True,
        text=True,
        timeout=1500,
        cwd=ROOT,
        env=env,
    )
    (run_dir,) = [p for p in runs.iterdir() if p.is_dir()]
    report = (run_dir / CHAOS_FILE).read_text()
    assert proc.returncode == 1, proc.stdout[-3000:] + proc.stderr[-2000:]
    assert "roco: the chaos run did not keep everything" in proc.stderr
    row = next(line for line in report.splitlines() if line.startswith("| nothing executed twice |"))
    assert row.startswith("| nothing executed twice | **no** ag_ex's ledger: "), row
    assert "executed twice: observe (c-" in row and "answered done, never ran" not in row
    # the task itself was done and nothing else failed: only the ledger tells
    assert report.count("**no**") == 1 and "| task done | yes |" in report
    v = judge_ledger(run_dir, load_run(run_dir).messages)
    assert len(v.twice) == 1 and v.lives == 1 and v.runs > 10
    assert "ag_ex's ledger" in (run_dir / "report.md").read_text()
