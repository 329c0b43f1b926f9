"""``roco doctor``: each check finds what is there, says how to get what is not,
and the command exits 0 exactly when everything ``roco run`` needs is found."""

from __future__ import annotations

import datetime as dt
import hashlib
import json
import os
import socket
from collections.abc import Sequence
from pathlib import Path

import pytest
from packaging.requirements import Requirement
from typer.testing import CliRunner

import services.doctor
from services.cli import app
from services.doctor import credentials, environment, machine, tools
from services.doctor import settings as doctor_settings
from services.doctor.model import Check, Use, run_ready
from services.doctor.render import CAMERA_NEED, SETTINGS_TITLE, lines, settings_lines, verdict
from services.security.certs import issue
from shared.settings import deployment_name
from tests.support.machine import needs_gl


def test_python_below_3_11_is_missing_with_how_to_get_it() -> None:
    assert environment.python_check((3, 11, 0)).found
    old = environment.python_check((3, 10, 12))
    assert not old.found and old.use is Use.RUN and "3.11" in old.how


def test_libraries_are_checked_against_their_specifier() -> None:
    assert environment.library_check(Requirement("msgspec>=0.1")).found
    too_old = environment.library_check(Requirement("msgspec>=999"))
    assert not too_old.found and "msgspec>=999" in too_old.how
    absent = environment.library_check(Requirement("no-such-distribution-roco-24"))
    assert not absent.found and "not installed" in absent.detail


def test_requirements_come_from_pyproject(tmp_path: Path) -> None:
    names = {r.name for r in environment.requirements()}
    assert {"eclipse-zenoh", "mujoco", "typer", "small_gicp"} <= names
    own = tmp_path / "pyproject.toml"
    own.write_text('[project]\nname = "x"\ndependencies = ["msgspec>=0.19", "not a requirement !"]\n')
    assert [str(r) for r in environment.requirements(own)] == ["msgspec>=0.19"]


def test_a_child_probe_reports_the_last_line_of_its_error() -> None:
    assert machine.probe("pass") == (True, "exit status 0")
    assert machine.probe("import sys; print('x', file=sys.stderr); sys.exit('refused here')") == (
        False,
        "refused here",
    )


@needs_gl
def test_mujoco_renders_here_and_a_constant_image_or_no_egl_vendor_fails_the_probe() -> None:
    """The rendering probe (what `.ci/run` requires, ``needs_gl`` skips on): a lit box renders
    here; a scene with nothing in view renders one colour and fails; so does EGL with no vendor
    library to drive it (glvnd's ``__EGL_VENDOR_LIBRARY_FILENAMES`` pointing at nothing)."""
    assert machine.cannot_render() is None
    empty = machine.rendering_checks(model="<mujoco/>")
    assert not empty[0].found and "the rendered image is constant" in empty[0].detail
    why = machine.cannot_render({"__EGL_VENDOR_LIBRARY_FILENAMES": "/nonexistent/vendor.json"})
    assert why is not None and why.startswith("MuJoCo cannot render off-screen (EGL does not render: ")
    assert why.endswith(machine.GL_HOW["egl"])


def test_a_taken_router_port_is_named_and_a_free_one_found() -> None:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        run_port, up_port = machine.port_checks(router_port=port)
        assert run_port.found and run_port.use is Use.RUN
        assert not up_port.found and up_port.use is Use.UP and "--port" in up_port.how
    assert machine.port_checks(router_port=port)[1].found


def _runner(answers: dict[str, tuple[int, str]]) -> tools.Runner:
    def run(args: Sequence[str]) -> tuple[int, str]:
        return answers.get(" ".join(args[:2]), (1, "unknown"))

    return run


def _project(tmp_path: Path, wheelhouse: bool) -> Path:
    """A project folder with a pyproject.toml and, when ``wheelhouse``, the wheelhouse's stamp
    that matches it (scripts/build_image.sh writes it)."""
    tmp_path.mkdir(parents=True, exist_ok=True)
    (tmp_path / "pyproject.toml").write_text('[project]\nname = "x"\n')
    if wheelhouse:
        stamp = tmp_path / tools.WHEELHOUSE / ".pyproject.sha256"
        stamp.parent.mkdir(parents=True)
        stamp.write_text(hashlib.sha256((tmp_path / "pyproject.toml").read_bytes()).hexdigest() + "\n")
    return tmp_path


def test_docker_missing_engine_and_compose_fallback_and_image(tmp_path: Path) -> None:
    root = _project(tmp_path, wheelhouse=True)
    none = tools.docker_checks(_runner({}), which=lambda name: None, root=root)
    assert [(c.name, c.found) for c in none] == [
        ("docker", False),
        ("Compose", False),
        ("debootstrap", False),
        ("wheelhouse", True),
        ("host folders", False),
    ]
    assert "docker.io" in none[0].how and "docker-compose" in none[1].how and "debootstrap" in none[2].how
    unreachable = tools.docker_checks(
        _runner({"docker version": (1, "Cannot connect to the Docker daemon")}),
        which=lambda name: f"/usr/bin/{name}",
        root=root,
    )
    assert [(c.name, c.found) for c in unreachable] == [
        ("docker", True),
        ("Docker engine", False),
        ("Compose", False),
        ("debootstrap", True),
        ("wheelhouse", True),
        ("host folders", False),
    ]
    assert "Cannot connect" in unreachable[1].detail
    assert "without systemd: service docker start, or dockerd &" in unreachable[1].how
    ready = tools.docker_checks(
        _runner(
            {
                "docker version": (0, "26.1.5"),
                "docker compose": (1, "not a docker command"),
                "docker-compose version": (0, "1.29.2"),
                "docker image": (1, "No such image"),
            }
        ),
        which=lambda name: f"/usr/bin/{name}",
        root=root,
    )
    assert [(c.name, c.found) for c in ready] == [
        ("docker", True),
        ("Docker engine", True),
        ("Compose", True),
        ("images", False),
        ("debootstrap", True),
        ("wheelhouse", True),
        ("host folders", False),
    ]
    assert ready[2].detail == "docker-compose 1.29.2" and "build_image.sh" in ready[3].how
    assert ready[3].detail == "not built: roco:latest, roco-viewer:latest, roco-robot:latest"
    answers = {"docker version": (0, "26.1.5"), "docker compose": (0, "2.27.0")}

    def without_robot(args: Sequence[str]) -> tuple[int, str]:  # planted: only the robot image missing
        if args[:2] == ["docker", "image"]:
            return (1, "No such image") if args[-1] == "roco-robot:latest" else (0, "sha")
        return answers.get(" ".join(args[:2]), (1, "unknown"))

    partly = tools.docker_checks(without_robot, which=lambda name: f"/usr/bin/{name}", root=root)
    assert [(c.name, c.found, c.detail) for c in partly if c.name == "images"] == [
        ("images", False, "not built: roco-robot:latest")
    ]
    unmade = _project(tmp_path / "unmade", wheelhouse=False)
    for folder in ("runs", "deploy/certs"):
        (unmade / folder).mkdir(parents=True)
    built = tools.docker_checks(
        _runner(
            {"docker version": (0, "26.1.5"), "docker compose": (0, "2.27.0"), "docker image": (0, "sha")}
        ),
        which=lambda name: None if name == "debootstrap" else f"/usr/bin/{name}",
        root=unmade,
        env={"ROCO_UID": str(os.getuid())},  # the folders' owner
    )
    # neither debootstrap nor the wheelhouse is needed once the image is built
    assert [c.name for c in built if c.missing] == []
    assert built[2].detail == "docker compose 2.27.0"


def test_the_host_folders_must_be_the_services_users(tmp_path: Path) -> None:
    """The run and credentials folders the compose services write: theirs (ROCO_UID), else the
    check names each and how to give it them. Planted faults: a missing folder (Docker would
    make it root's) and one of another uid."""
    (tmp_path / "deploy").mkdir()
    me = str(os.getuid())
    missing = tools.host_folders_check(tmp_path, {"ROCO_UID": me})
    assert missing.missing and f"{tmp_path / 'runs'} missing" in missing.detail
    assert missing.how.startswith(
        f"mkdir -p {tmp_path / 'runs'} {tmp_path / 'deploy' / 'certs'} && chown {me}:"
    )
    (tmp_path / "runs").mkdir(mode=0o755)
    (tmp_path / "deploy" / "certs").mkdir(mode=0o755)
    assert tools.host_folders_check(tmp_path, {"ROCO_UID": me}).found
    other = str(os.getuid() + 1)
    theirs = tools.host_folders_check(tmp_path, {"ROCO_UID": other})
    assert theirs.missing and f"{tmp_path / 'runs'} is uid {me}'s" in theirs.detail
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir(mode=0o777)
    elsewhere.chmod(0o777)  # writable by all (the umask aside): any uid may write it
    moved = {"ROCO_UID": other, "ROCO_RUNS": str(elsewhere), "ROCO_CERTS": str(elsewhere)}
    assert tools.host_folders_check(tmp_path, moved).found
    assert deployment_name("uid") == "ROCO_UID"
    with pytest.raises(KeyError, match="no deployment variable ROCO_NOT_ONE"):
        deployment_name("not_one")


def test_the_wheelhouse_must_match_pyproject_until_the_image_is_built(tmp_path: Path) -> None:
    made = _project(tmp_path / "made", wheelhouse=True)
    assert tools.wheelhouse_check(built=False, root=made).found
    (made / "pyproject.toml").write_text('[project]\nname = "x"\nversion = "2"\n')  # changed since
    stale = tools.wheelhouse_check(built=False, root=made)
    assert stale.missing and "PyPI" in stale.how
    assert not tools.wheelhouse_check(built=True, root=made).missing
    assert tools.wheelhouse_check(built=False, root=tmp_path).missing  # none made


def test_doctor_compose_names_each_missing_prerequisite(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A PATH without docker and docker-compose (nor debootstrap): `roco doctor --compose` names
    each on a line of its own with how to get it, and exits 1; its last line names them all."""
    monkeypatch.setenv("PATH", str(tmp_path))
    result = CliRunner().invoke(app, ["doctor", "--compose"])
    out = result.output.splitlines()
    assert result.exit_code == 1, result.output
    for name, how in (
        ("docker", "apt-get install docker.io"),
        ("Compose", "apt-get install docker-compose"),
        ("debootstrap", "apt-get install debootstrap"),
    ):
        line = next(i for i, text in enumerate(out) if text.split()[2:3] == [name])
        assert "not found" in out[line] and how in out[line + 1], result.output
    assert out[-1].startswith("roco: the compose fleet lacks docker, Compose, debootstrap")


def test_chromium_is_looked_up_by_its_names() -> None:
    assert tools.chromium_check(lambda name: None).how == "apt-get install chromium"
    found = tools.chromium_check(
        lambda name: "/usr/bin/chromium-browser" if name == "chromium-browser" else None
    )
    assert found.found and found.detail == "/usr/bin/chromium-browser"


def _fleet(runs: Path, security: bool) -> Path:
    run_dir = runs / "20261122-000000"
    run_dir.mkdir(parents=True)
    if security:
        issue(run_dir / "security", ["operator"], days=30)
    (runs / ".fleet.json").write_text(
        json.dumps({"endpoint": "tcp/127.0.0.1:1", "run_dir": str(run_dir), "pids": {}})
    )
    return run_dir


def test_fleet_credentials_found_expired_absent(tmp_path: Path) -> None:
    (none,) = credentials.checks(tmp_path / "runs")
    assert none.informative and not none.missing and "no fleet is up" in none.detail
    _fleet(tmp_path / "runs", security=True)
    (ok,) = credentials.checks(tmp_path / "runs")
    assert ok.found, ok.detail
    later = dt.datetime.now(dt.UTC) + dt.timedelta(days=31)
    (expired,) = credentials.checks(tmp_path / "runs", now=later)
    assert not expired.found and "expired" in expired.detail and "roco deploy issue" in expired.how
    _fleet(tmp_path / "open", security=False)
    (open_,) = credentials.checks(tmp_path / "open")
    assert open_.informative and "without access control" in open_.detail


def test_a_fleet_folder_without_the_operator_says_how_to_issue_it(tmp_path: Path) -> None:
    run_dir = _fleet(tmp_path / "runs", security=True)
    (run_dir / "security" / "operator" / "password").unlink()
    (check,) = credentials.checks(tmp_path / "runs")
    assert check.missing and check.how.startswith("roco deploy issue")


CAMERA_MISSING = [
    Check("Python", Use.RUN, True, "3.11.7"),
    Check("EGL", Use.CAMERA, False, "no context", machine.GL_HOW["egl"]),
    Check("OSMesa", Use.CAMERA, False, "no context", machine.GL_HOW["osmesa"]),
    Check("Docker engine", Use.COMPOSE, False, "no docker on PATH", tools.DOCKER_HOW),
    Check("fleet credentials", Use.FLEET, False, "no fleet is up", informative=True),
]


def test_lines_and_verdict_name_what_is_missing_and_how() -> None:
    text = "\n".join(lines(CAMERA_MISSING))
    assert "not found  EGL" in text and f"how to get it: {machine.GL_HOW['egl']}" in text
    assert "how to get it" not in text.split("fleet credentials:")[1]
    # the ground truth perceiving (ROCO_PERCEPTION=truth): roco run renders nothing
    assert run_ready(CAMERA_MISSING, camera=False)
    assert verdict(CAMERA_MISSING, camera=False) == (
        "roco: roco run has everything it needs; not ready: compose fleet, head camera"
    )
    # the head camera perceiving (the default): roco run needs a GL context
    assert not run_ready(CAMERA_MISSING)
    assert verdict(CAMERA_MISSING) == f"roco: roco run lacks {CAMERA_NEED}; not ready: compose fleet"
    with_osmesa = [*CAMERA_MISSING[:2], Check("OSMesa", Use.CAMERA, True, "opens"), *CAMERA_MISSING[3:]]
    assert run_ready(with_osmesa)
    lacking = [Check("msgspec", Use.RUN, False, "not installed", "pip install"), *CAMERA_MISSING]
    assert not run_ready(lacking, camera=False)
    assert verdict(lacking, camera=False).startswith("roco: roco run lacks msgspec;")


@pytest.mark.parametrize(
    ("checks", "perception", "gl", "code"),
    [
        (CAMERA_MISSING, "truth", "egl", 0),
        (CAMERA_MISSING, "camera", "egl", 1),
        (CAMERA_MISSING, "", "egl", 1),  # unset, libEGL installed: the camera, whose context fails
        ([Check("x", Use.RUN, False, "gone")], "truth", "egl", 1),
    ],
)
def test_doctor_exits_0_exactly_when_roco_run_has_what_it_needs(
    checks: list[Check], perception: str, gl: str, code: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(services.doctor, "run_checks", lambda runs_dir: checks)
    monkeypatch.setenv("ROCO_PERCEPTION", perception)
    monkeypatch.setenv("MUJOCO_GL", gl)
    result = CliRunner().invoke(app, ["doctor"])
    assert result.exit_code == code, result.output
    assert result.output.strip().splitlines()[-1] == verdict(checks, camera=perception != "truth")


def test_without_a_gl_library_doctor_says_the_robot_perceives_with_the_ground_truth(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """velma/gl.py found neither libEGL nor libOSMesa: roco run perceives with the ground truth."""
    monkeypatch.setattr(services.doctor, "run_checks", lambda runs_dir: CAMERA_MISSING)
    monkeypatch.setenv("ROCO_PERCEPTION", "")
    monkeypatch.setenv("MUJOCO_GL", "disable")
    result = CliRunner().invoke(app, ["doctor"])
    assert result.exit_code == 0, result.output
    assert result.output.strip().splitlines()[-1] == (
        "roco: roco run has everything it needs (perceiving with the ground truth: no GL library "
        "for the head camera); not ready: compose fleet, head camera"
    )


def test_settings_are_listed_with_their_values_and_a_bad_one_is_a_failed_item(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Every ROCO_* setting (shared/settings.py) after the checks: its value here or
    ``default``, its default, what it sets; a value that does not parse is a failed item."""
    monkeypatch.setenv("ROCO_CAMERA_IDLE_S", "soon")
    monkeypatch.setenv("ROCO_RUN_DIR", "/runs/x")
    monkeypatch.delenv("ROCO_SEED", raising=False)
    failed = doctor_settings.checks()
    assert [(c.name, c.use, c.missing) for c in failed] == [("ROCO_CAMERA_IDLE_S", Use.SETTINGS, True)]
    assert failed[0].detail.startswith("ROCO_CAMERA_IDLE_S='soon': expected a number of seconds")
    assert "unset it" in failed[0].how
    text = settings_lines(doctor_settings.readings())
    assert text[0] == SETTINGS_TITLE
    row = {line.split()[0]: line.split()[1:3] for line in text[1:] if line.startswith("  ROCO_")}
    assert row["ROCO_RUN_DIR"] == ["/runs/x", "—"] and row["ROCO_SEED"] == ["default", "0"]
    assert f"not valid: {failed[0].detail}" in [line.strip() for line in text]
    monkeypatch.setattr(services.doctor, "run_checks", lambda runs_dir: [*CAMERA_MISSING, *failed])
    monkeypatch.setenv("ROCO_PERCEPTION", "truth")
    result = CliRunner().invoke(app, ["doctor"])
    out = result.output.strip().splitlines()
    assert SETTINGS_TITLE in out and "not found  ROCO_CAMERA_IDLE_S" in result.output
    assert out[-1] == verdict([*CAMERA_MISSING, *failed], camera=False)
    assert "not ready: compose fleet, head camera, settings" in out[-1] and result.exit_code == 0


def test_doctor_on_this_machine_finds_what_roco_run_needs(tmp_path: Path) -> None:
    """The real checks (the test suite itself runs roco, so its needs are met here)."""
    result = CliRunner().invoke(app, ["doctor", "--runs-dir", str(tmp_path)])
    assert result.exit_code == 0, result.output
    for item in ("Python", "eclipse-zenoh", "mujoco", "loopback port", "SCHED_FIFO", "Chromium"):
        assert item in result.output


def test_the_cpu_latency_request_is_checked_where_the_loop_makes_it(tmp_path: Path) -> None:
    """The loop holds /dev/cpu_dma_latency (velma/executor/timing.py): the doctor says whether
    it exists and is writable, with how to get it when not."""
    device = tmp_path / "cpu_dma_latency"
    missing = machine.cpu_latency_check(str(device))
    assert missing.missing and missing.use is Use.REALTIME and "no " in missing.detail
    device.write_bytes(b"")
    device.chmod(0o600)
    found = machine.cpu_latency_check(str(device))
    assert found.found and found.how == ""
    device.chmod(0o400)
    refused = machine.cpu_latency_check(str(device))
    if os.geteuid() != 0:  # root may write anything: the refusal shows only for other users
        assert refused.missing and "--device" in refused.how
