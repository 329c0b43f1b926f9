"""`roco up`, `roco status`, `roco send`, `roco down` against one fleet of real processes (the ACL
gateway one of them: `roco up --gateway`): commands a_hi does not understand, questions, a stop
with nothing to stop, a foreign agent's notice, then a pour, and `roco down`, which says what it
stops as it stops it and leaves the report and a run.json with the commands and their outcomes
(the other ways a fleet ends: tests/cli/test_fleet_end.py). The commands are the subject, not the
robot: ag_ex moves the kinematic robot double (tests/support/kinematic_ex.py)."""

from __future__ import annotations

import json
import select
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from services.fleet.launcher import AGENT_ORDER, free_port
from services.report.build import NOTHING_RAISED
from services.runtime.counters import read_counters
from services.runtime.session import listening
from shared.settings import Settings
from tests.support.jade_platform import JADE, JadePlatform
from tests.support.kinematic_ex import kinematic_spec, ran_kinematic
from tests.support.processes import processes_of, running, said
from velma.world.mode import WORLD_SERVICE

pytestmark = [pytest.mark.slow, pytest.mark.fleet]
ROOT = Path(__file__).resolve().parents[2]
POUR = "pour the jar into the bowl"


def roco(*args: str, timeout: float = 180) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "services.cli", *args], capture_output=True, text=True, timeout=timeout
    )


def _a_foreign_notice_is_counted_and_shown(runs: str, gateway: int) -> None:
    """A foreign agent tells the person something (roco-notify on C8, through the gateway):
    `roco status` counts it in a_hi's line once a_hi has passed it on (asked again until then:
    the gateway's post returns before a_hi has it), and `roco send` shows it with its sender
    (a_hi's cached reports come first)."""
    notice = json.dumps({"type": "notice", "text": "the jar tipped over", "severity": "warning"})
    jade = JadePlatform()
    try:
        acl = jade.acl("a_hi", notice, "N1_jade", performative="INFORM")
        acl = acl.replace(":protocol  fipa-request", ":protocol  roco-notify")
        assert jade.request(f"http://127.0.0.1:{gateway}/acc", "a_hi", acl) == 200
    finally:
        jade.close()
    line = ""
    for _ in range(20):
        status = roco("status", "--runs-dir", runs)
        line = next(x for x in status.stdout.splitlines() if x.startswith("a_hi "))
        if "notices 1" in line:
            break
    assert "notices 1" in line, line
    shown = roco("send", "what are you doing?", "--runs-dir", runs, timeout=60)
    assert f"notice from {JADE} (warning): the jar tipped over" in shown.stdout, shown.stdout


def test_up_status_send_down(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    runs = str(tmp_path)
    gateway = free_port()
    port = free_port()
    spec = kinematic_spec(tmp_path / "kinematic.toml")
    monkeypatch.setenv("PYTHONPATH", str(ROOT))  # the agents import the double from tests/support
    up = roco("up", "--port", str(port), "--gateway", str(gateway), "--runs-dir", runs, "--spec", str(spec))
    assert up.returncode == 0, up.stderr
    try:
        assert "fleet up on tls/127.0.0.1:" in up.stdout
        assert f"gateway http://127.0.0.1:{gateway}/acc" in up.stdout
        assert listening(f"tcp/127.0.0.1:{gateway}")
        again = roco("up", "--runs-dir", runs)
        assert again.returncode == 1 and "already up" in again.stderr
        status = roco("status", "--runs-dir", runs)
        assert status.returncode == 0, status.stdout + status.stderr
        for agent in ("a_hi", "a_co", "a_pl", "a_km", "a_ta", "ag_ex"):
            assert f"{agent:9s} alive" in status.stdout
        assert "gateway   alive  received 0, forwarded 0, refused 0, answered 0" in status.stdout
        sent = roco("send", "sing me a song", "--runs-dir", runs, timeout=60)
        assert sent.returncode == 1
        # a_hi names the word it does not know
        assert sent.stdout.startswith("not-understood: ") and "'sing'" in sent.stdout
        asked = roco("send", "what are you doing?", "--runs-dir", runs, timeout=60)
        assert asked.returncode == 0, asked.stdout + asked.stderr
        assert asked.stdout.startswith("status: ")
        # roco sniff shows the fleet's live traffic in FIPA string form
        sniffer = subprocess.Popen(
            [sys.executable, "-m", "services.cli", "sniff", "--runs-dir", runs, "--channel", "C2"],
            stdout=subprocess.PIPE,
            text=True,
        )
        try:
            seen = ""
            # The sniffer subscribes after it starts: ask until it shows a query-ref. Other C2
            # traffic may come first (a_hi subscribes to a_co's progress again when an earlier
            # subscribe went unanswered), so read on past it.
            for _ in range(20):
                roco("send", "what are you doing?", "--runs-dir", runs, timeout=60)
                while "(query-ref" not in seen:
                    ready, _, _ = select.select([sniffer.stdout], [], [], 5.0)
                    if not ready:
                        break
                    seen += sniffer.stdout.readline()  # type: ignore[union-attr]
                if "(query-ref" in seen:
                    break
            assert "C2  a_hi → a_co" in seen and "(query-ref" in seen, seen
        finally:
            # SIGTERM ends roco sniff as Ctrl-C does (a job started in the background of a
            # non-interactive shell inherits SIGINT ignored, and Python keeps it so)
            sniffer.send_signal(signal.SIGTERM)
            try:
                sniffer.wait(timeout=30)
            except subprocess.TimeoutExpired:
                sniffer.kill()
                sniffer.wait()
                raise
        stopped = roco("send", "stop", "--runs-dir", runs, timeout=60)
        assert stopped.returncode == 0, stopped.stdout + stopped.stderr
        assert "nothing to stop" in stopped.stdout.lower()
        _a_foreign_notice_is_counted_and_shown(runs, gateway)
        run_dir, pids = _a_pour(runs, port)
        # this report draws its figures, as for users (the fleet tests' reports do not: tests/conftest.py)
        monkeypatch.setenv(Settings.env_name("report_figures"), "1")
    finally:
        down = roco("down", "--runs-dir", runs)
    assert down.returncode == 0, down.stderr
    _down_said_what_it_stopped(down.stdout, run_dir)
    assert not listening(f"tcp/127.0.0.1:{gateway}")
    assert not (tmp_path / ".fleet.json").exists()
    _the_run_keeps_its_commands_and_report(run_dir, pids)
    assert ran_kinematic(run_dir)
    # the agents' counters were kept before they stopped: the report says what they raised
    assert set(read_counters(run_dir)) >= {"a_hi", "a_co", "a_pl", "a_km", "a_ta", "ag_ex"}
    report = (run_dir / "report.md").read_text()
    assert f"| Agents raised | {NOTHING_RAISED} |" in report
    notices = report[report.index("Notices to the person") :]
    assert f"| {JADE} | warning | — | the jar tipped over |" in notices
    after = roco("down", "--runs-dir", runs)
    assert after.returncode == 1 and after.stderr.startswith("roco: no fleet is up")


def _a_pour(runs: str, port: int) -> tuple[Path, dict[str, int]]:
    """`roco send` of the pour, which succeeds; `roco status` names the router by its endpoint.
    The run folder and the fleet's processes (run.json), each of which :func:`processes_of` sees."""
    sent = roco("send", POUR, "--runs-dir", runs, timeout=300)
    assert sent.returncode == 0, sent.stdout + sent.stderr
    status = roco("status", "--runs-dir", runs)
    assert f"router    at tls/127.0.0.1:{port}  refused 0" in status.stdout, status.stdout
    run_dir = Path(json.loads((Path(runs) / ".fleet.json").read_text())["run_dir"])
    pids: dict[str, int] = json.loads((run_dir / "run.json").read_text())["processes"]
    assert set(pids.values()) <= set(processes_of(run_dir))  # the check after `down` sees them
    return run_dir, pids


def _down_said_what_it_stopped(out: str, run_dir: Path) -> None:
    """`roco down`'s two lines: what it stops (every agent, the world, the gateway; the recorder
    answered the sync), then the commands' summary and the report."""
    stopping, final = said(out)
    assert stopping.startswith("roco: stopping ") and stopping.endswith(
        "; recorder: traffic record complete; router"
    ), stopping
    assert sorted(stopping.removeprefix("roco: stopping ").split(";")[0].split()) == sorted(
        [*AGENT_ORDER, WORLD_SERVICE, "gateway"]
    )
    assert final.startswith("roco: fleet stopped after ") and "; 1 command: 1 succeeded; " in final, final
    assert final.endswith(f"communicates; report {run_dir / 'report.md'}")


def _the_run_keeps_its_commands_and_report(run_dir: Path, pids: dict[str, int]) -> None:
    """run.json holds the command with its outcome, the report counts the specification's
    coverage and draws its figure, and none of the fleet's processes is left."""
    info = json.loads((run_dir / "run.json").read_text())
    assert info["commands"] == [POUR] and info["command"] == POUR
    assert [(c["text"], c["outcome"]) for c in info["outcomes"]] == [(POUR, "succeeded")]
    assert info["succeeded"] is True and info["ended"] > info["started"] > 0
    report = (run_dir / "report.md").read_text()
    assert POUR in report and "Specification coverage" in report  # counted for roco down too
    assert (run_dir / "figures" / "coverage.png").is_file()
    assert not [name for name, pid in pids.items() if running(pid)]
    assert processes_of(run_dir) == []
