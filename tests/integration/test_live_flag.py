"""A requirement flagged violated as it happens, in a real fleet: ``roco scenario`` with a
planted a_ta (tests/support/hasty_ta.py, named as a_ta's implementation in a copy of the
specification) that reports Preempted without putting down what it holds. The person asks for
the pour and says stop while Velma carries the bowl with the jar in the other hand; a_co
cancels; the planted a_ta reports Preempted with both in hand. Both commands end stopped, as
the scenario expects: only the live flag makes the exit non-zero.

One fleet run (about 40 s on a 2-core VM), checked for: the exit and its one ``roco:`` line
naming R3.3, the flag in the run folder (raised by the recorder while traffic still came,
before the run ended), the recorder's log, the report's lines beside the requirements'
verdicts, and `roco status`'s line from a recorder started again on the run folder."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from services.cli.status import _flag_lines
from services.fleet.launcher import Fleet, free_port
from services.recorder.flags import ask_flags, read_flags
from services.report.load import load_run
from services.runtime.run_folder import read_run_info
from services.runtime.session import open_client
from services.spec.model import DEFAULT_SPEC
from shared.fipa_codec.languages.l_sw import SWState, SWStatus

pytestmark = [pytest.mark.slow, pytest.mark.fleet, pytest.mark.requirement("R3.3")]
ROOT = Path(__file__).resolve().parents[2]
QUIET = ("--quiet", "--no-record")
REAL = 'implementation = "services.agents.task_executor.agent:TaskExecutor"'
PLANTED = 'implementation = "tests.support.hasty_ta:HastyTaskExecutor"'
SCENARIO = """name = "stop mid-pour, planted a_ta"
description = "The person says stop while Velma carries the bowl with the jar in the other hand."

[[steps]]
say = "pour the jar into the bowl"
expect = "stopped"

[[steps]]
say = "stop"
after = { step = "place_bowl/carry" }
expect = "stopped"
"""


@pytest.fixture(scope="module")
def planted(tmp_path_factory: pytest.TempPathFactory) -> tuple[subprocess.CompletedProcess[str], Path]:
    tmp = tmp_path_factory.mktemp("planted")
    text = DEFAULT_SPEC.read_text(encoding="utf-8")
    assert text.count(REAL) == 1
    spec = tmp / "planted.toml"
    spec.write_text(text.replace(REAL, PLANTED), encoding="utf-8")
    scenario = tmp / "stop_planted.toml"
    scenario.write_text(SCENARIO, encoding="utf-8")
    runs = tmp / "runs"
    env = {**os.environ, "ROCO_SPEC": str(spec), "PYTHONPATH": str(ROOT)}
    proc = subprocess.run(
        [sys.executable, "-m", "services.cli", "scenario", str(scenario), "--runs-dir", str(runs), *QUIET],
        capture_output=True,
        text=True,
        timeout=900,
        cwd=ROOT,
        env=env,
    )
    (run_dir,) = [p for p in runs.iterdir() if p.is_dir()]
    return proc, run_dir


def test_the_planted_a_ta_is_flagged_live_and_the_run_exits_non_zero(
    planted: tuple[subprocess.CompletedProcess[str], Path], tmp_path: Path
) -> None:
    proc, run_dir = planted
    said = [line for line in proc.stderr.splitlines() if line.startswith("roco: requirement")]
    assert proc.returncode == 1 and len(said) == 1, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert said[0].startswith("roco: requirement R3.3 violated during the run: R3.3 “a plan cancelled")
    assert "C1 a_ta → a_co inform SWStatus state=Preempted" in said[0] and str(run_dir) in said[0]
    # the planted fault happened: Preempted, and a_ta never told a_km the jar was put down
    run = load_run(run_dir)
    states = [m for m in run.messages if isinstance(m.content, SWStatus) and m.sender == "a_ta"]
    assert any(m.content.state is SWState.PREEMPTED for m in states)  # type: ignore[union-attr]

    (flag,) = read_flags(run_dir)
    preempted = next(m for m in run.messages if m.rec.seq == flag.seq)
    assert isinstance(preempted.content, SWStatus) and preempted.content.state is SWState.PREEMPTED
    assert flag.requirement == "R3.3" and "came while waiting for C6" in flag.why
    # live: raised by the recorder as the violating communicate came (the record then held it and
    # at most what came after it), before the run ended; the planted a_ta's Preempted may be the
    # run's last communicate, so nothing need come after the flag
    assert flag.seq < flag.recorded <= len(run.messages)
    info = read_run_info(run_dir)
    assert info.ended is not None and flag.flagged < info.ended
    # raised on arrival, not by what the monitor evaluates once the recording stopped
    log = (run_dir / "logs" / "recorder.log").read_text()
    assert 0 <= log.find("requirement violated: R3.3") < log.find("recording stopped:"), log[-2000:]

    report = (run_dir / "report.md").read_text()
    assert f"- **violated** {flag.line(info.started)}" in report
    assert "| R3.3 leave the robot safe" in report and "violated at" not in report.split("| R3.3")[0]
    row = next(line for line in report.splitlines() if line.startswith("| R3.3 "))
    assert row.endswith("| **violated** |"), row

    # a recorder on this run folder answers roco status with the flag (a router and a recorder
    # on a loopback endpoint; tests/recorder/test_flags_query.py for the query itself)
    fleet = Fleet(
        run_dir,
        f"tcp/127.0.0.1:{free_port()}",
        env={"ROCO_SPEC": str(run_dir.parent.parent / "planted.toml")},
    )
    fleet.start_router()
    fleet.start_recorder()
    try:
        session = open_client(fleet.endpoint)
        try:
            fleet.wait_alive(session, ["recorder"], timeout=30.0)
            reply = ask_flags(session, timeout=30.0)
        finally:
            session.close()
    finally:
        fleet.stop()
    assert reply is not None and _flag_lines(reply) == [f"violated  {flag.line()}"]
