"""Every way a fleet ends leaves its report and a run.json with the commands it was given and
their outcomes, and says what it stops as it stops it: ``roco down`` after ``roco up`` and
``roco send``; ``roco hosts down`` (the recorder-sync barrier, as ``roco down``); ``roco run``
interrupted by Ctrl-C (one line, exit 130, none of its processes left). ``roco status`` names
the fleet's router by its endpoint. Real fleets of processes: 20–60 s each."""

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
from shared.settings import Settings
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


def said(stream: str) -> list[str]:
    """The lines roco said (a stale compiled module's warning of a development checkout aside)."""
    return [line for line in stream.splitlines() if line.startswith("roco")]


def running(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except OSError:
        return False


def processes_of(run_dir: Path) -> list[int]:
    """Every process whose environment names ``run_dir`` as its run folder (a fleet's processes
    and their children: ag_ex's loop and camera processes)."""
    mark = f"ROCO_RUN_DIR={run_dir}".encode()
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            env = (entry / "environ").read_bytes().split(b"\0")
        except OSError:
            continue
        if mark in env and running(int(entry.name)):
            found.append(int(entry.name))
    return found


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


def test_down_says_what_it_stops_and_writes_the_commands_and_the_report(
    fleet: tuple[Path, int], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    run_dir, port = fleet
    sent = roco("send", POUR, "--runs-dir", str(tmp_path))
    assert sent.returncode == 0, sent.stdout + sent.stderr
    status = roco("status", "--runs-dir", str(tmp_path))
    assert f"router    at tls/127.0.0.1:{port}  refused 0" in status.stdout, status.stdout
    pids = json.loads((run_dir / "run.json").read_text())["processes"]
    assert set(pids.values()) <= set(processes_of(run_dir))  # the check below sees them
    # this report draws its figures, as for users (the fleet tests' reports do not: tests/conftest.py)
    monkeypatch.setenv(Settings.env_name("report_figures"), "1")
    down = roco("down", "--runs-dir", str(tmp_path))
    assert down.returncode == 0, down.stderr
    stopping, final = said(down.stdout)
    assert stopping.startswith("roco: stopping ") and stopping.endswith(
        "; recorder: traffic record complete; router"
    )
    assert sorted(stopping.removeprefix("roco: stopping ").split(";")[0].split()) == sorted(
        [*AGENT_ORDER, WORLD_SERVICE]
    )
    assert final.startswith("roco: fleet stopped after ") and "; 1 command: 1 succeeded; " in final
    assert final.endswith(f"communicates; report {run_dir / 'report.md'}")
    info = json.loads((run_dir / "run.json").read_text())
    assert info["commands"] == [POUR] and info["command"] == POUR
    assert [(c["text"], c["outcome"]) for c in info["outcomes"]] == [(POUR, "succeeded")]
    assert info["succeeded"] is True and info["ended"] > info["started"] > 0
    report = (run_dir / "report.md").read_text()
    assert POUR in report and "Specification coverage" in report  # counted for roco down too
    assert (run_dir / "figures" / "coverage.png").is_file()
    assert not [name for name, pid in pids.items() if running(pid)]
    assert processes_of(run_dir) == []


def test_hosts_down_confirms_the_traffic_record_as_roco_down_does(
    fleet: tuple[Path, int], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``roco hosts down`` of a fleet whose two hosts are stood in for (no root needed): its
    agents stop, the recorder confirms the record, the routers end with the hosts, the report
    is written."""
    import services.hosts.cli as hosts_cli

    run_dir, _ = fleet
    state = json.loads((tmp_path / ".fleet.json").read_text())
    router = state["pids"]["router"]
    (tmp_path / hosts_cli.HOSTS_FILE).write_text(
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

    monkeypatch.setattr(hosts_cli, "_pair", lambda state: Pair())
    result = CliRunner().invoke(hosts_cli.hosts_app, ["down", "--runs-dir", str(tmp_path)])
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
    assert not (tmp_path / ".fleet.json").exists() and not (tmp_path / hosts_cli.HOSTS_FILE).exists()
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
