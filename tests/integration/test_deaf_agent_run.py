"""A receiving thread that ends ends its agent, which is started again, and the pour still
succeeds: ``roco run`` with a planted a_ta (tests/support/deaf_ta.py, named as a_ta's
implementation in a copy of the specification) whose receiving thread ends at a_co's plan. The
agent's process exits with code 70 (services/runtime/main.py ``EXIT_LOST``), the runner starts
it again (services/scenario/runner.py), a_co gives the plan again to the a_ta that came back
(docs/recovery.md), and the run says so in its last line and exits 1 (an agent exited by
itself), the task succeeded.

One fleet run (a pour, about 30-60 s on a 2-core VM)."""

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

pytestmark = [pytest.mark.slow, pytest.mark.fleet]
ROOT = Path(__file__).resolve().parents[2]
REAL = 'implementation = "services.agents.task_executor.agent:TaskExecutor"'
PLANTED = 'implementation = "tests.support.deaf_ta:DeafTaskExecutor"'
COMMAND = "pour the jar into the bowl"
QUIET = ("--quiet", "--no-record", "--timeout", "600")


def test_an_agent_whose_receiving_thread_ended_is_started_again_and_the_pour_succeeds(
    tmp_path: Path,
) -> None:
    text = DEFAULT_SPEC.read_text(encoding="utf-8")
    assert text.count(REAL) == 1
    spec = tmp_path / "planted.toml"
    spec.write_text(text.replace(REAL, PLANTED), encoding="utf-8")
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
    said = proc.stdout[-3000:] + proc.stderr[-3000:]
    assert (run_dir / MARKER).exists(), said  # the planted fault happened
    info = read_run_info(run_dir)
    assert info.succeeded is True and info.crashed == {"a_ta": [EXIT_LOST]}, said
    log = (run_dir / "logs" / "a_ta.log").read_text(encoding="utf-8")
    assert "the receiving thread of roco/fipa/*/*/a_ta ended: ThreadKiller: planted" in log
    assert "ended: the receiving thread" in log  # the process said why it ended
    crashed = f"a_ta exited (code {EXIT_LOST}) and was started again: see logs/a_ta.log"
    last = [line for line in proc.stdout.splitlines() if line.startswith("roco: ")][-1]
    assert last.startswith("roco: succeeded in ") and crashed in last, said
    assert proc.returncode == 1, said
    assert proc.stderr.strip().splitlines()[-1] == f"roco: agents raised: {crashed} (run folder {run_dir})"
