"""The person hears the outcome of a pour that ended while the router was down.

A fleet of real processes (router, recorder, the agents linked to each other directly: one
hop), and `roco send "pour the jar into the bowl"` as a process of its own, a client of the
router. When `roco send` shows the pour tilting the jar, the router is SIGKILLed; once a_hi's
log says it told the person the pour succeeded (into the outage: nobody of the router's side
could hear it), the router is started again on the same endpoint. `roco send` then prints the
outcome, once, and exits 0 (services/runtime/reports.py). Every wait reads a line, a queue or
a log file against a deadline.
"""

from __future__ import annotations

import os
import queue
import re
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from services.fleet.launcher import AGENT_ORDER, Fleet, free_port
from services.runtime.session import open_client
from tests.support.lines import lines_of, wait_until

pytestmark = [pytest.mark.slow, pytest.mark.fleet]
ROOT = Path(__file__).resolve().parents[2]
POUR = "pour the jar into the bowl"
TOLD = re.compile(r"a_hi INFO to person \[\w+\] (.*)$", re.MULTILINE)
"""A report in a_hi's log (services/agents/human_interface/agent.py ``_report``): kind: text."""
TILTING = "/pour_into_bowl/tilt_pour/tilt"
"""The end of the progress line of the pour's tilt (seconds before the pour ends)."""


@pytest.fixture
def fleet(tmp_path: Path) -> Iterator[Fleet]:
    (tmp_path / "logs").mkdir()
    f = Fleet(tmp_path, f"tcp/127.0.0.1:{free_port()}", env={"ROCO_RERUN": "0"}, acl=False)
    try:
        f.start_router()
        session = open_client(f.endpoint)
        try:
            f.start_recorder()
            f.start_agents()
            f.wait_alive(session, ["recorder", *AGENT_ORDER], timeout=180)
        finally:
            session.close()
        yield f
    finally:
        f.stop()


def told_success(log: Path) -> bool:
    return log.is_file() and f"succeeded: {POUR}: succeeded" in log.read_text(errors="replace")


def test_send_prints_the_outcome_a_hi_gave_while_the_router_was_down(fleet: Fleet) -> None:
    a_hi_log = fleet.run_dir / "logs" / "a_hi.log"
    send = subprocess.Popen(
        [sys.executable, "-m", "services.cli", "send", POUR, "--router", fleet.endpoint, "--timeout", "400"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=ROOT,
    )
    seen: list[str] = []
    try:
        out = lines_of(send)
        while not (seen and seen[-1].endswith(TILTING)):
            line = out.get(timeout=300)
            assert line is not None, "\n".join([*seen, send.stderr.read() if send.stderr else ""])
            seen.append(line)
        router = fleet.processes["router"]
        os.kill(router.pid, signal.SIGKILL)
        router.wait(timeout=10)
        assert not told_success(a_hi_log), "the pour ended before the router was killed"
        wait_until(lambda: told_success(a_hi_log), 300, "a_hi tells the person the pour succeeded")
        fleet.start_router()
        while True:
            try:
                line = out.get(timeout=120)
            except queue.Empty:
                pytest.fail(
                    "roco send printed no outcome within 120 s of the router's restart:\n" + "\n".join(seen)
                )
            if line is None:
                break
            seen.append(line)
        send.wait(timeout=30)
        err = send.stderr.read() if send.stderr is not None else ""
    finally:
        if send.poll() is None:
            send.kill()
            send.wait()
    assert send.returncode == 0, (seen, err)
    finals = [line for line in seen if line.startswith("succeeded: ")]
    assert len(finals) == 1 and finals[0].startswith(f"succeeded: {POUR}: succeeded"), seen
    # each report a_hi told shown once, in order, up to the outcome (a replan repeats steps)
    told = TOLD.findall(a_hi_log.read_text(errors="replace"))
    assert seen == told[: told.index(finals[0]) + 1]
