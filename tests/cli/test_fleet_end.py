"""Every way a fleet ends leaves its report and a run.json, and says what it stops as it stops
it: ``roco hosts down`` (the recorder-sync barrier, as ``roco down``); ``roco run`` interrupted
by Ctrl-C (one line, exit 130, none of its processes left). ``roco down`` after ``roco up`` and a
pour sent: tests/integration/test_fleet_commands.py, in the fleet it checks the other commands
with. Real fleets of processes: 20–60 s each."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from typer.testing import CliRunner

from services.fleet.launcher import AGENT_ORDER, free_port
from tests.support.processes import processes_of, running, said
from velma.world.mode import WORLD_SERVICE

pytestmark = [pytest.mark.slow, pytest.mark.fleet]
ROOT = Path(__file__).resolve().parents[2]
POUR = "pour the jar into the bowl"


def roco(*args: str, timeout: float = 300) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "services.cli", *args],
        capture_output=True,
        text=True,
        timeout=timeout,
        cwd=ROOT,
    )


@pytest.fixture
def fleet(tmp_path: Path) -> Iterator[tuple[Path, int]]:
    """A fleet of ``roco up`` (as fast as it can); its run folder and port. Stopped at the end
    whatever the test did."""
    port = free_port()
    up = roco("up", "--port", str(port), "--runs-dir", str(tmp_path), "--no-realtime")
    assert up.returncode == 0, up.stderr
    run_dir = Path(json.loads((tmp_path / ".fleet.json").read_text())["run_dir"])
    try:
        yield run_dir, port
    finally:
        if (tmp_path / ".fleet.json").exists():
            roco("down", "--runs-dir", str(tmp_path))


def test_hosts_down_confirms_the_traffic_record_as_roco_down_does(
    fleet: tuple[Path, int], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``roco hosts down`` of a fleet whose two hosts are stood in for (no root needed): its
    agents stop, the recorder confirms the record, the routers end with the hosts, the report
    is written."""
    from services.cli.hosts import hosts_app
    from services.hosts.state import HOSTS_FILE, HostsState

    run_dir, _ = fleet
    state = json.loads((tmp_path / ".fleet.json").read_text())
    router = state["pids"]["router"]
    (tmp_path / HOSTS_FILE).write_text(
        json.dumps(
            {"tag": "t", "subnet": 1, "maker": os.getpid(), "run_dir": str(run_dir)}
            | {"endpoint": state["endpoint"], "shaping": "", "how": ""}
        )
    )

    class Pair:
        @property
        def link_dev(self) -> dict[str, str]:  # no such device: no link counters to record
            return {"robot": "rk000000r"}

        def netns(self, host: str) -> str:
            return f"roco-000000-{host}"

        def destroy(self) -> None:  # what the namespaces' removal ends: the router
            os.kill(router, signal.SIGTERM)

    monkeypatch.setattr(HostsState, "pair", lambda state: Pair())
    result = CliRunner().invoke(hosts_app, ["down", "--runs-dir", str(tmp_path)])
    assert result.exit_code == 0, result.output
    stopping, final = said(result.output)
    assert stopping.endswith("; recorder: traffic record complete; routers; both hosts removed"), stopping
    assert sorted(stopping.removeprefix("roco: stopping ").split(";")[0].split()) == sorted(
        [*AGENT_ORDER, WORLD_SERVICE]
    )
    assert final.startswith("roco: two hosts down after ") and "; no command given; " in final
    info = json.loads((run_dir / "run.json").read_text())
    assert info["ended"] is not None and info["detail"] == "no command was given"
    assert (run_dir / "report.md").is_file()
    assert not (run_dir / "link.jsonl").exists()  # the stand-in's link has no counters to record
    assert not (tmp_path / ".fleet.json").exists() and not (tmp_path / HOSTS_FILE).exists()
    stopped = [pid for name, pid in state["pids"].items() if name != "router"]
    assert not [pid for pid in stopped if running(pid)]


def test_ctrl_c_during_run_says_interrupted_once_and_leaves_nothing_running(tmp_path: Path) -> None:
    # as in a terminal's foreground job: SIGINT raises KeyboardInterrupt (a process started in
    # the background of a non-interactive shell inherits SIGINT ignored)
    entry = (
        "import signal, sys; signal.signal(signal.SIGINT, signal.default_int_handler); "
        "from services.cli import main; sys.argv[0] = 'roco'; main()"
    )
    args = ["run", POUR, "--runs-dir", str(tmp_path), "--no-record", "--no-live"]
    proc = subprocess.Popen(
        [sys.executable, "-c", entry, *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=ROOT,
    )
    seen = []
    try:
        assert proc.stdout is not None
        for line in proc.stdout:
            seen.append(line)
            if "all agents alive" in line:
                proc.send_signal(signal.SIGINT)
                break
        out, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert any("all agents alive" in line for line in seen), "".join(seen) + proc.stderr.read()  # type: ignore[union-attr]
    (run_dir,) = [p for p in tmp_path.iterdir() if p.is_dir()]
    assert proc.returncode == 130
    assert said(err) == [f"roco: interrupted; the fleet is stopped; report {run_dir / 'report.md'}"]
    assert "failed" not in out and "Traceback" not in err
    info = json.loads((run_dir / "run.json").read_text())
    assert set(info["processes"]) == {"router", "recorder", WORLD_SERVICE, *AGENT_ORDER}
    assert not [name for name, pid in info["processes"].items() if running(pid)]
    assert processes_of(run_dir) == []
    assert info["succeeded"] is False and info["detail"] == "interrupted"
    assert (run_dir / "report.md").is_file()
