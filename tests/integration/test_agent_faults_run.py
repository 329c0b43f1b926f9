"""Faults inside an agent surface in the run (``roco run`` with a planted agent named as its
implementation in a copy of the specification), and the pour still succeeds:

- a_ta's receiving thread ends (tests/support/deaf_ta.py) at a_co's plan: the agent's process
  exits with code 70 (services/runtime/main.py ``EXIT_LOST``), the runner starts it again
  (services/scenario/runner.py), a_co gives the plan again to the a_ta that came back
  (docs/recovery.md);
- a_hi's progress handler raises once (tests/support/raising_hi.py): counted in its
  ``handler_errors``, and the pour's end-to-end check (tests/support/raised.py) fails on it.

Either way the run's last line names it with the agent's log, and the run exits 1 with one
``roco:`` line, the task succeeded. Two fleet runs (a pour each, about 1-3 min on a 2-core VM)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from services.runtime.main import EXIT_LOST
from services.runtime.run_folder import read_run_info
from services.spec.model import DEFAULT_SPEC
from tests.support.deaf_ta import MARKER
from tests.support.raised import assert_no_agent_raised

pytestmark = [pytest.mark.slow, pytest.mark.fleet]
ROOT = Path(__file__).resolve().parents[2]
COMMAND = "pour the jar into the bowl"
QUIET = ("--quiet", "--no-record", "--timeout", "600")
AGENTS = ("a_hi", "a_co", "a_pl", "a_km", "a_ta", "ag_ex")


def _planted_run(tmp_path: Path, real: str, planted: str) -> tuple[subprocess.CompletedProcess[str], Path]:
    """``roco run`` of the pour with the implementation ``real`` replaced by ``planted`` (both
    ``module:Class``) in a copy of the specification; its output and run folder."""
    text = DEFAULT_SPEC.read_text(encoding="utf-8")
    line = f'implementation = "{real}"'
    assert text.count(line) == 1
    spec = tmp_path / "planted.toml"
    spec.write_text(text.replace(line, f'implementation = "{planted}"'), encoding="utf-8")
    runs = tmp_path / "runs"
    env = {**os.environ, "ROCO_SPEC": str(spec), "PYTHONPATH": str(ROOT)}
    proc = subprocess.run(
        [sys.executable, "-m", "services.cli", "run", COMMAND, "--runs-dir", str(runs), *QUIET],
        capture_output=True,
        text=True,
        timeout=900,
        cwd=ROOT,
        env=env,
    )
    (run_dir,) = [p for p in runs.iterdir() if p.is_dir()]
    return proc, run_dir


def _said(proc: subprocess.CompletedProcess[str], raised: str, run_dir: Path) -> None:
    """The run's last line names ``raised`` beside its success; it exits 1 with one line."""
    out = proc.stdout[-3000:] + proc.stderr[-3000:]
    last = [line for line in proc.stdout.splitlines() if line.startswith("roco: ")][-1]
    assert last.startswith("roco: succeeded in ") and f"; {raised}; " in last, out
    assert proc.returncode == 1, out
    assert proc.stderr.strip().splitlines()[-1] == f"roco: agents raised: {raised} (run folder {run_dir})"


def test_an_agent_whose_receiving_thread_ended_is_started_again_and_the_pour_succeeds(
    tmp_path: Path,
) -> None:
    proc, run_dir = _planted_run(
        tmp_path, "services.agents.task_executor.agent:TaskExecutor", "tests.support.deaf_ta:DeafTaskExecutor"
    )
    out = proc.stdout[-3000:] + proc.stderr[-3000:]
    assert (run_dir / MARKER).exists(), out  # the planted fault happened
    info = read_run_info(run_dir)
    assert info.succeeded is True and info.crashed == {"a_ta": [EXIT_LOST]}, out
    log = (run_dir / "logs" / "a_ta.log").read_text(encoding="utf-8")
    assert "the receiving thread of roco/fipa/*/*/a_ta ended: ThreadKiller: planted" in log
    assert "ended: the receiving thread" in log  # the process said why it ended
    _said(proc, f"a_ta exited (code {EXIT_LOST}) and was started again: see logs/a_ta.log", run_dir)


def test_a_handler_that_raised_is_named_and_fails_the_end_to_end_check(tmp_path: Path) -> None:
    proc, run_dir = _planted_run(
        tmp_path,
        "services.agents.human_interface.agent:HumanInterface",
        "tests.support.raising_hi:RaisingHumanInterface",
    )
    out = proc.stdout[-3000:] + proc.stderr[-3000:]
    info = read_run_info(run_dir)
    assert info.succeeded is True and info.raised == {"a_hi": {"handler_errors": 1}}, out
    assert "planted: a_hi's progress handler raises once" in (run_dir / "logs" / "a_hi.log").read_text()
    _said(proc, "1 handler error in a_hi: see logs/a_hi.log", run_dir)
    with pytest.raises(AssertionError, match=r"1 handler error in a_hi: see logs/a_hi\.log"):
        assert_no_agent_raised(run_dir, AGENTS)
