"""What a user sees on the command line's bad paths: one line starting with ``roco:`` that names
the problem and the fix, a non-zero exit, and nothing started or written — a runs folder where
no run folder can be made, a folder that is not a run folder, no fleet to reach, a port in use.
Also: each ``--runs-dir`` says what it is for in its command, and ``roco run`` has the
``--record/--no-record`` and ``--view`` options of ``roco scenario``."""

from __future__ import annotations

import errno
import os
import socket
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from typer.testing import CliRunner

import services.cli as cli
from services.fleet.launcher import free_port
from services.runtime.run_folder import RunFolderError, new_run_dir

MAKES_A_RUN = {
    "run": ["run", "pour the jar into the bowl"],
    "scenario": ["scenario", "urgent_mid_pour"],
    "chaos": ["chaos"],
    "up": ["up", "--port", "0"],  # the port is filled in by the test
    "hosts up": ["hosts", "up"],
}


def invoke(args: list[str]) -> tuple[int, list[str]]:
    result = CliRunner().invoke(cli.app, args, prog_name="roco")
    return result.exit_code, result.output.strip().splitlines()


@pytest.fixture
def nothing_starts(monkeypatch: pytest.MonkeyPatch) -> None:
    """Any start of a fleet, a scenario runner or the two hosts fails the test."""

    def started(*args: object, **kwargs: object) -> None:
        raise AssertionError("something was started")

    monkeypatch.setattr("services.scenario.runner.ScenarioRunner.__init__", started)
    monkeypatch.setattr("services.fleet.launcher.Fleet.__post_init__", started)
    monkeypatch.setattr("services.hosts.fleet.TwoHosts.start", started)
    monkeypatch.setattr("services.hosts.netns.unavailable", lambda link=True: None)  # root, ip, nft
    monkeypatch.setattr("signal.signal", lambda *args: None)  # pytest keeps its SIGTERM


def _args(name: str, runs: Path) -> list[str]:
    args = list(MAKES_A_RUN[name])
    if name == "up":
        args[-1] = str(free_port())
    return [*args, "--runs-dir", str(runs)]


@pytest.mark.parametrize("name", MAKES_A_RUN)
def test_a_file_in_the_way_of_the_runs_folder_is_one_line(
    name: str, tmp_path: Path, nothing_starts: None
) -> None:
    in_the_way = tmp_path / "runs"
    in_the_way.write_text("not a folder")
    for runs in (in_the_way, in_the_way / "deeper"):
        code, lines = invoke(_args(name, runs))
        assert code == 2
        assert lines == [
            f"roco: cannot make a run folder in {runs}: a file is in the way, not a folder; "
            "give --runs-dir a folder you can write to"
        ]
    assert in_the_way.read_text() == "not a folder"


@pytest.mark.parametrize(
    ("error", "why"),
    [
        (errno.EROFS, "it is on a read-only file system"),
        (errno.EACCES, "no permission to write there"),
        (errno.ENOSPC, "no space is left on its device"),
    ],
)
@pytest.mark.parametrize("name", ["run", "up", "hosts up"])
def test_a_runs_folder_that_cannot_be_written_is_one_line(
    name: str, error: int, why: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, nothing_starts: None
) -> None:
    runs = tmp_path / "runs"

    def refused(self: Path, *args: object, **kwargs: object) -> None:
        raise OSError(error, os.strerror(error), str(self))

    monkeypatch.setattr(Path, "mkdir", refused)
    code, lines = invoke(_args(name, runs))
    assert code == 2
    assert lines == [
        f"roco: cannot make a run folder in {runs}: {why}; give --runs-dir a folder you can write to"
    ]


def test_hosts_up_where_two_hosts_cannot_be_made_makes_nothing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, nothing_starts: None
) -> None:
    why = "nftables' nft is not installed (apt-get install nftables)"
    monkeypatch.setattr("services.hosts.netns.unavailable", lambda link=True: why)
    code, lines = invoke(["hosts", "up", "--runs-dir", str(tmp_path / "runs")])
    assert (code, lines) == (2, [f"roco: cannot make two hosts here: {why}"])
    assert not (tmp_path / "runs").exists()


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into a folder without write permission")
def test_a_folder_without_write_permission_is_refused(tmp_path: Path) -> None:
    locked = tmp_path / "locked"
    locked.mkdir(mode=0o555)
    with pytest.raises(RunFolderError, match="no permission to write there"):
        new_run_dir(locked / "runs")


def test_a_run_folder_is_made_where_it_can_be(tmp_path: Path) -> None:
    made = new_run_dir(tmp_path / "a" / "b")
    assert made.parent == tmp_path / "a" / "b" and (made / "logs").is_dir()
    assert [p.name for p in made.iterdir()] == ["logs"]  # the probe of writing leaves nothing
    assert new_run_dir(tmp_path / "a" / "b") != made


@pytest.mark.parametrize("command", [["report"], ["spec", "verify"], ["view"]])
def test_a_folder_that_is_not_a_run_is_refused_and_nothing_is_written(
    command: list[str], tmp_path: Path
) -> None:
    folder = tmp_path / "holiday-photos"
    folder.mkdir()
    (folder / "beach.jpg").write_bytes(b"\xff\xd8")
    code, lines = invoke([*command, str(folder)])
    assert code == 2
    assert lines == [
        f"roco: {folder} is not a run folder: it holds neither run.json nor traffic.jsonl; "
        "give one that roco run or roco up made (runs/<timestamp>/)"
    ]
    assert sorted(p.name for p in folder.iterdir()) == ["beach.jpg"]


def test_report_refuses_a_missing_folder_and_a_file(tmp_path: Path) -> None:
    code, lines = invoke(["report", str(tmp_path / "gone")])
    assert (code, lines) == (2, [f"roco: {tmp_path / 'gone'}: no such run folder"])
    (tmp_path / "f").write_text("")
    code, lines = invoke(["report", str(tmp_path / "f")])
    assert (code, lines) == (2, [f"roco: {tmp_path / 'f'} is not a run folder: it is a file"])


def test_report_writes_the_report_of_a_folder_with_a_run_json(tmp_path: Path) -> None:
    from services.runtime.run_folder import RunInfo, write_run_info

    write_run_info(tmp_path, RunInfo(started=1.0, command="pour the jar into the bowl"))
    code, lines = invoke(["report", str(tmp_path)])
    assert code == 0 and lines == [str(tmp_path / "report.md")]
    assert "pour the jar into the bowl" in (tmp_path / "report.md").read_text()


NO_FLEET = [
    ["send", "pour the jar into the bowl"],
    ["status"],
    ["sniff"],
    ["disturb", "jar", "--dx", "0.1"],
    ["gateway", "--port", "PORT"],
    ["ros2", "--all"],
    ["fault", "show"],
    ["fault", "net", "a_pl", "--delay", "0.1"],
    ["fault", "msg", "C4", "--drop", "0.5"],
    ["fault", "clear"],
]


@pytest.mark.parametrize("command", NO_FLEET, ids=lambda c: " ".join(c[:2]))
def test_without_a_fleet_each_tool_names_the_router_and_the_fix(
    command: list[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr("services.runtime.foreground.signal.signal", lambda *args: None)
    monkeypatch.setattr("signal.signal", lambda *args: None)
    router = f"tcp/127.0.0.1:{free_port()}"
    args = [str(free_port()) if a == "PORT" else a for a in command]
    code, lines = invoke([*args, "--router", router, "--runs-dir", str(tmp_path)])
    prefix = f"roco: {command[0]}: " if command[0] in ("gateway", "ros2") else "roco: "
    assert code == 1
    fix = "start a fleet with 'roco up', or name its router with --router"
    assert lines == [f"{prefix}no router answers at {router}: {fix}"]


def in_use(port: int, option: str) -> str:
    return f"cannot listen on 127.0.0.1:{port}: the port is in use; choose another with {option}"


def test_a_fleet_state_whose_fleet_is_gone_says_how_to_clear_it(tmp_path: Path) -> None:
    """The machine restarted under a fleet of roco up: its state file names a router that is
    no more; 'roco up' would refuse while the file is there, so the line says to clear it."""
    router = f"tcp/127.0.0.1:{free_port()}"
    state = tmp_path / ".fleet.json"
    state.write_text(f'{{"endpoint": "{router}", "run_dir": "{tmp_path / "run"}", "pids": {{}}}}')
    code, lines = invoke(["status", "--runs-dir", str(tmp_path)])
    assert code == 1
    assert lines == [
        f"roco: no router answers at {router}: the fleet {state} names is gone; "
        "'roco down' clears its state, then 'roco up' starts one"
    ]


@pytest.fixture
def taken_port() -> Iterator[int]:
    """A port on 127.0.0.1 something listens on."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        yield int(s.getsockname()[1])


def test_up_refuses_a_port_in_use_before_it_starts_anything(
    taken_port: int, tmp_path: Path, nothing_starts: None
) -> None:
    code, lines = invoke(["up", "--port", str(taken_port), "--runs-dir", str(tmp_path / "runs")])
    assert code == 2
    assert lines == [f"roco: {in_use(taken_port, '--port')}"]
    assert not (tmp_path / "runs").exists()


@pytest.mark.parametrize("name", ["run", "scenario", "up"])
def test_a_gateway_port_in_use_is_refused_before_anything_starts(
    name: str, taken_port: int, tmp_path: Path, nothing_starts: None
) -> None:
    """``--gateway PORT`` (the ACL gateway as a process of the fleet) on a port in use: one
    line naming the option, exit 2, no run folder."""
    runs = tmp_path / "runs"
    code, lines = invoke([*_args(name, runs), "--gateway", str(taken_port)])
    assert code == 2
    assert lines == [f"roco: {in_use(taken_port, '--gateway')}"]
    assert not runs.exists()


def test_gateway_refuses_a_port_in_use_before_it_reaches_the_fleet(
    taken_port: int, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr("services.runtime.foreground.signal.signal", lambda *args: None)

    def reached(*args: object, **kwargs: object) -> None:
        raise AssertionError("the gateway opened a session")

    monkeypatch.setattr("services.gateway.serve.ZenohTransport", reached)
    router = f"tcp/127.0.0.1:{free_port()}"
    code, lines = invoke(
        ["gateway", "--port", str(taken_port), "--router", router, "--runs-dir", str(tmp_path)]
    )
    assert code == 1
    assert lines == [f"roco: gateway: {in_use(taken_port, '--port')}"]


@pytest.mark.parametrize("option", ["--web-port", "--grpc-port"])
def test_view_refuses_a_port_in_use_and_starts_no_viewer(
    option: str, taken_port: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    def started(*args: object, **kwargs: object) -> None:
        raise AssertionError("a viewer was started")

    monkeypatch.setattr("services.viewer.view.subprocess.Popen", started)
    code, lines = invoke(["view", "--web", option, str(taken_port)])
    assert code == 2
    assert lines == [f"roco: {in_use(taken_port, option)}"]


def test_view_web_port_is_the_web_viewer_s() -> None:
    code, lines = invoke(["view", "--native", "--web-port", str(free_port())])
    assert (code, lines) == (2, ["roco: --web-port is the web viewer's port: not with --native"])


def test_view_serves_on_the_ports_asked_for() -> None:
    from services.viewer.view import Viewer, stop_viewer

    web, grpc = free_port(), free_port()
    code, lines = invoke(["view", "--web-port", str(web), "--grpc-port", str(grpc)])
    assert code == 0, lines
    assert len(lines) == 1 and lines[0].startswith(f"roco: Rerun viewer http://127.0.0.1:{web}/?url=")
    assert f"127.0.0.1%3A{grpc}%2Fproxy" in lines[0]
    pid = int(lines[0].split("(pid ")[1].split(";")[0])
    assert stop_viewer(Viewer(pid=pid, grpc_url="", web_url=None, files=()))


RUNS_DIR_HELP = {
    ("run",): "made",
    ("scenario",): "made",
    ("chaos",): "made",
    ("up",): "made",
    ("hosts", "up"): "made",
    ("down",): "keeps",
    ("send",): "keeps",
    ("status",): "keeps",
    ("sniff",): "keeps",
    ("disturb",): "keeps",
    ("gateway",): "keeps",
    ("ros2",): "keeps",
    ("doctor",): "keeps",
    ("hosts", "partition"): "keeps",
    ("hosts", "heal"): "keeps",
    ("hosts", "status"): "keeps",
    ("hosts", "down"): "keeps",
}


def _option_help(path: tuple[str, ...], option: str) -> str:
    """The words of ``option``'s help in ``roco PATH --help`` (at 400 columns: one row), after
    the option's names and metavar."""
    result = CliRunner().invoke(cli.app, [*path, "--help"], env={"COLUMNS": "400"}, prog_name="roco")
    row = next(line for line in result.output.splitlines() if option in line.split())
    words = row.strip("│ ").split()
    return " ".join(w for w in words if not w.startswith("-") and w != "PATH")


@pytest.mark.parametrize("path", RUNS_DIR_HELP, ids=" ".join)
def test_runs_dir_says_what_it_is_for_in_each_command(path: tuple[str, ...]) -> None:
    """A command that makes a run folder says so; one that finds a fleet says where its state
    is kept, and never that a run folder is made."""
    text = _option_help(path, "--runs-dir")
    if RUNS_DIR_HELP[path] == "made":
        assert "folder is made" in text, text
    else:
        assert "keeps" in text and "made" not in text, text
        assert "roco hosts up" in text if path[0] == "hosts" else "roco up" in text, text


def test_run_takes_record_and_view_as_scenario_does(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    given: list[dict[str, object]] = []

    def run_scenario(sc: object, runs_dir: Path, **kwargs: object) -> None:
        given.append(kwargs)

    monkeypatch.setattr("services.cli.run.run_scenario", run_scenario)
    for args in ([], ["--no-record"], ["--view"], ["--no-record", "--view"]):
        code, lines = invoke(["run", "pour the jar into the bowl", *args, "--runs-dir", str(tmp_path)])
        assert code == 0, lines
    assert [(g["record"], g["view"]) for g in given] == [
        (True, False),
        (False, False),
        (True, True),
        (False, True),
    ]
    for option in ("--record", "--view"):
        assert _option_help(("run",), option) == _option_help(("scenario",), option) != ""


def test_the_subprocess_entry_point_prints_no_traceback_for_a_bad_runs_folder(tmp_path: Path) -> None:
    """As a user types it: the console script's process, one line on stderr."""
    (tmp_path / "runs").write_text("")
    done = subprocess.run(
        [sys.executable, "-m", "services.cli", "run", "pour", "--runs-dir", str(tmp_path / "runs")],
        capture_output=True,
        text=True,
        timeout=120,
        env={**os.environ, "ROCO_INTERPRETED": "1"},
        cwd=Path(__file__).resolve().parents[2],
    )
    assert done.returncode == 2 and done.stdout == ""
    assert [line for line in done.stderr.splitlines() if line.startswith("roco:")] == done.stderr.splitlines()
    assert len(done.stderr.splitlines()) == 1 and "Traceback" not in done.stderr


NO_GL = {"MUJOCO_GL": "disable"}  # velma/gl.py's choice where no libEGL or libOSMesa is installed


@pytest.mark.parametrize("name", ["run", "scenario", "chaos", "up"])
@pytest.mark.parametrize(
    ("env", "line"),
    [
        ({"ROCO_PERCEPTION": "oracle"}, "roco: ROCO_PERCEPTION='oracle': expected one of camera, truth"),
        (
            {"ROCO_PERCEPTION": "camera", **NO_GL},
            "roco: ROCO_PERCEPTION=camera, but no off-screen GL library (libEGL or libOSMesa) for the "
            "head camera: apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri libopengl0",
        ),
    ],
)
def test_a_perception_that_cannot_be_had_is_one_line_before_anything_is_made(
    name: str,
    env: dict[str, str],
    line: str,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    nothing_starts: None,
) -> None:
    for key, value in env.items():
        monkeypatch.setenv(key, value)
    code, lines = invoke(_args(name, tmp_path / "runs"))
    assert (code, lines) == (2, [line])
    assert not (tmp_path / "runs").exists()


def test_without_gl_roco_run_says_once_that_the_robot_perceives_with_the_truth(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, nothing_starts: None
) -> None:
    monkeypatch.delenv("ROCO_PERCEPTION", raising=False)
    monkeypatch.setenv("MUJOCO_GL", "disable")
    result = CliRunner().invoke(cli.app, _args("run", tmp_path / "runs"), prog_name="roco")
    assert isinstance(result.exception, AssertionError)  # it went on to start the fleet
    assert result.output.splitlines()[0] == (
        "roco: the robot perceives with the physics' ground truth: no off-screen GL library "
        "(libEGL or libOSMesa) for the head camera: "
        "apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri libopengl0"
    )
