"""`roco up`, `roco status`, `roco send`, `roco down` against a fleet of real processes (the ACL
gateway one of them: `roco up --gateway`)."""

from __future__ import annotations

import json
import select
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from services.fleet.launcher import free_port
from services.report.build import NOTHING_RAISED
from services.runtime.counters import read_counters
from services.runtime.session import listening
from tests.support.jade_platform import JADE, JadePlatform

pytestmark = [pytest.mark.slow, pytest.mark.fleet]


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


def test_up_status_send_down(tmp_path: Path) -> None:
    runs = str(tmp_path)
    gateway = free_port()
    up = roco("up", "--port", str(free_port()), "--gateway", str(gateway), "--runs-dir", runs)
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
    finally:
        down = roco("down", "--runs-dir", runs)
    assert down.returncode == 0, down.stderr
    assert "traffic record complete" in down.stdout, down.stdout  # the recorder answered the sync
    assert " gateway" in down.stdout.split(";")[0] and not listening(f"tcp/127.0.0.1:{gateway}")
    assert not (tmp_path / ".fleet.json").exists()
    # the agents' counters were kept before they stopped: the report says what they raised
    (run_dir,) = [p for p in tmp_path.iterdir() if p.is_dir()]
    assert set(read_counters(run_dir)) >= {"a_hi", "a_co", "a_pl", "a_km", "a_ta", "ag_ex"}
    report = (run_dir / "report.md").read_text()
    assert f"| Agents raised | {NOTHING_RAISED} |" in report
    notices = report[report.index("Notices to the person") :]
    assert f"| {JADE} | warning | — | the jar tipped over |" in notices
    after = roco("down", "--runs-dir", runs)
    assert after.returncode == 1 and after.stderr.startswith("roco: no fleet is up")
