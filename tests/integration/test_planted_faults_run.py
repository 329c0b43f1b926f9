"""Faults inside agents surface in the run, and the pour still succeeds: one ``roco run`` of the
pour with three planted agents, each named as its agent's implementation in a copy of the
specification (``ROCO_SPEC``; roco itself never starts them):

- a_ta's receiving thread ends at a_co's plan (tests/support/deaf_ta.py): the agent's process
  exits with code 70 (services/runtime/main.py ``EXIT_LOST``), the runner starts it again
  (services/scenario/runner.py), a_co gives the plan again to the a_ta that came back
  (docs/recovery.md);
- a_hi's progress handler raises once (tests/support/raising_hi.py): counted in its
  ``handler_errors``, and the pour's end-to-end check (tests/support/raised.py) fails on it;
- ag_ex runs its first Observe twice and answers once (tests/support/twice_ex.py): the record
  alone cannot tell (one answer); ag_ex's ledger (velma/executor/ledger.py) shows two starts of
  that conversation, so `roco chaos`'s "nothing executed twice" (services/report/ledger.py) and
  the report's header say so.

Besides, the router is stopped (SIGSTOP) when a_hi tells the person the bowl is being checked,
and killed once a_hi's log says it told the outcome: the agents, linked directly, finish the pour
meanwhile, the runner starts the router again (as a crashed service) and hears the outcome it
missed (services/runtime/reports.py) — `roco run` prints it once.

The run's last line names what the agents raised with their logs, and the run exits 1 with one
``roco:`` line though the task succeeded. One fleet run (a pour, about 1–3 min on a 2-core VM),
checked each way."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

from services.report.ledger import judge_ledger
from services.report.load import load_run
from services.runtime.main import EXIT_LOST
from services.runtime.run_folder import read_run_info
from services.spec.model import DEFAULT_SPEC
from tests.support.deaf_ta import MARKER
from tests.support.lines import lines_of, wait_until
from tests.support.raised import assert_no_agent_raised

pytestmark = [pytest.mark.slow, pytest.mark.fleet]
ROOT = Path(__file__).resolve().parents[2]
COMMAND = "pour the jar into the bowl"
OPTIONS = ("--no-record", "--timeout", "600")
CHECKING = "/check_bowl"
"""The end of a_hi's progress line for the pour's last step (the bowl's content looked at)."""
TOLD = f"succeeded: {COMMAND}: succeeded"
"""a_hi's outcome, in its log and in the run's output."""
AGENTS = ("a_hi", "a_co", "a_pl", "a_km", "a_ta", "ag_ex")
PLANTS = {
    "services.agents.task_executor.agent:TaskExecutor": "tests.support.deaf_ta:DeafTaskExecutor",
    "services.agents.human_interface.agent:HumanInterface": "tests.support.raising_hi:RaisingHumanInterface",
    "services.agents.executor.agent:ExecutorAgent": "tests.support.twice_ex:TwiceExecutor",
}
RAISED = (
    "1 handler error in a_hi: see logs/a_hi.log; "
    f"a_ta exited (code {EXIT_LOST}) and was started again: see logs/a_ta.log; "
    "router exited (code -9) and was started again: see logs/router.stderr"
)


@dataclass(frozen=True)
class Planted:
    proc: subprocess.CompletedProcess[str]
    run_dir: Path
    told_before: bool | None
    """Whether a_hi had told the outcome when the router was stopped (None: never stopped)."""

    @property
    def out(self) -> str:
        return self.proc.stdout[-3000:] + self.proc.stderr[-3000:]


@pytest.fixture(scope="module")
def planted(tmp_path_factory: pytest.TempPathFactory) -> Planted:
    """``roco run`` of the pour with the three planted agents; its output and run folder."""
    tmp = tmp_path_factory.mktemp("planted")
    text = DEFAULT_SPEC.read_text(encoding="utf-8")
    for real, plant in PLANTS.items():
        line = f'implementation = "{real}"'
        assert text.count(line) == 1, real
        text = text.replace(line, f'implementation = "{plant}"')
    spec = tmp / "planted.toml"
    spec.write_text(text, encoding="utf-8")
    runs = tmp / "runs"
    env = {**os.environ, "ROCO_SPEC": str(spec), "PYTHONPATH": str(ROOT)}
    run = subprocess.Popen(
        [sys.executable, "-m", "services.cli", "run", COMMAND, "--runs-dir", str(runs), *OPTIONS],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=ROOT,
        env=env,
    )
    try:
        out = lines_of(run)
        seen: list[str] = []
        told_before = None  # whether a_hi had told the outcome when the router was stopped
        while (said := out.get(timeout=900)) is not None:
            seen.append(said)
            if told_before is None and said.endswith(CHECKING) and "a_hi → person" in said:
                told_before = _router_down_while_told(runs)
        run.wait(timeout=60)
        err = run.stderr.read() if run.stderr is not None else ""
    finally:
        if run.poll() is None:
            run.kill()
            run.wait()
    proc = subprocess.CompletedProcess(run.args, run.returncode, "\n".join(seen) + "\n", err)
    (run_dir,) = [p for p in runs.iterdir() if p.is_dir()]
    return Planted(proc, run_dir, told_before)


def _router_down_while_told(runs: Path) -> bool:
    """Stop the run's router, wait until a_hi's log says it told the outcome, kill the router.
    Whether a_hi had told it before the router stopped (then nothing was shown)."""
    (run_dir,) = [p for p in runs.iterdir() if p.is_dir()]
    router = read_run_info(run_dir).processes["router"]
    log = run_dir / "logs" / "a_hi.log"
    os.kill(router, signal.SIGSTOP)
    told_before = TOLD in log.read_text(errors="replace")
    wait_until(lambda: TOLD in log.read_text(errors="replace"), 300, "a_hi tells the outcome")
    os.kill(router, signal.SIGKILL)
    return told_before


def test_the_run_names_what_the_agents_raised_and_exits_1_though_the_pour_succeeded(planted: Planted) -> None:
    last = [line for line in planted.proc.stdout.splitlines() if line.startswith("roco: ")][-1]
    assert last.startswith("roco: succeeded in ") and f"; {RAISED}; " in last, planted.out
    assert planted.proc.returncode == 1, planted.out
    assert planted.proc.stderr.strip().splitlines()[-1] == (
        f"roco: agents raised: {RAISED} (run folder {planted.run_dir})"
    )


def test_the_outcome_told_while_the_router_was_down_is_printed_once(planted: Planted) -> None:
    assert planted.told_before is False, planted.out  # stopped before a_hi told the outcome
    told = [line for line in planted.proc.stdout.splitlines() if f"a_hi → person (#1): {TOLD}" in line]
    assert len(told) == 1, planted.out
    assert "router exited (code -9, see logs/router.stderr); started again (pid " in planted.proc.stdout
    assert read_run_info(planted.run_dir).crashed["router"] == [-9]


def test_an_agent_whose_receiving_thread_ended_is_started_again(planted: Planted) -> None:
    assert (planted.run_dir / MARKER).exists(), planted.out  # the planted fault happened
    info = read_run_info(planted.run_dir)
    assert info.succeeded is True and info.crashed == {"a_ta": [EXIT_LOST], "router": [-9]}, planted.out
    log = (planted.run_dir / "logs" / "a_ta.log").read_text(encoding="utf-8")
    assert "the receiving thread of roco/fipa/*/*/a_ta ended: ThreadKiller: planted" in log
    assert "ended: the receiving thread" in log  # the process said why it ended


def test_a_handler_that_raised_is_named_and_fails_the_end_to_end_check(planted: Planted) -> None:
    info = read_run_info(planted.run_dir)
    assert info.raised == {"a_hi": {"handler_errors": 1}}, planted.out
    log = (planted.run_dir / "logs" / "a_hi.log").read_text(encoding="utf-8")
    assert "planted: a_hi's progress handler raises once" in log
    with pytest.raises(AssertionError, match=r"1 handler error in a_hi: see logs/a_hi\.log"):
        assert_no_agent_raised(planted.run_dir, AGENTS)


def test_an_observe_run_twice_with_one_answer_is_found_by_ag_ex_s_ledger(planted: Planted) -> None:
    v = judge_ledger(planted.run_dir, load_run(planted.run_dir).messages)
    assert not v.ok and v.lives == 1 and v.runs > 10, v
    assert len(v.twice) == 1 and v.twice[0].startswith("observe (c-") and not v.never_ran, v
    header = (planted.run_dir / "report.md").read_text(encoding="utf-8")
    assert "ag_ex's ledger" in header and "executed twice: observe (c-" in header
