"""The images and their services' limits, read from deploy/Dockerfile and deploy/compose.yaml
without a Docker engine (scripts/compose_smoke.sh checks the built images and the running
fleet): the runtime stage has no compiler, no headers, no Mesa and no Rerun CLI and runs as a
non-root user who owns the mount points of the compose file's volumes; the viewer target adds
the Rerun CLI and the robot target Mesa, each on the runtime image; each service runs the image
it needs; every service has a memory, CPU and PIDs limit and runs as that user; the entrypoint
names a run folder it cannot write."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
from pathlib import Path
from typing import Any

import pytest

from services.deploy.compose import COMPOSE_FILE, IMAGES, LIMITS, UID, render
from services.spec.model import default_spec

yaml = pytest.importorskip("yaml", reason="PyYAML reads the compose file: pip install -e '.[dev]'")

ROOT = Path(__file__).resolve().parents[2]
DOCKERFILE = ROOT / "deploy" / "Dockerfile"
ENTRYPOINT = ROOT / "deploy" / "entrypoint.sh"
BUILD_ONLY = re.compile(r"(?<![\w.-])(g\+\+|gcc|clang|build-essential|(lib)?python3(\.\d+)?-dev)(?![\w.+-])")
"""Debian packages of a compiler or of Python's headers."""
MESA = re.compile(
    r"(?<![\w.-])(libegl1|libegl-mesa0|libgl1-mesa-dri|libgl1|libopengl0|libosmesa6)(?![\w.+-])"
)
"""Debian packages of Mesa's OpenGL (the robot target's)."""
CLI_IN_VENV = "/opt/venv/lib/python3.11/site-packages/rerun_cli/rerun"
"""Where rerun-sdk installs the Rerun CLI's binary in the venv."""


def stages(text: str) -> list[tuple[str, str]]:
    """The Dockerfile's stages: (its FROM line, its instructions), comment lines left out."""
    lines = [line for line in text.splitlines() if not line.lstrip().startswith("#")]
    found: list[tuple[str, list[str]]] = []
    for line in lines:
        if line.startswith("FROM "):
            found.append((line, []))
        elif found:
            found[-1][1].append(line)
    return [(head, "\n".join(body)) for head, body in found]


def stage(text: str, name: str) -> str:
    """The instructions of the stage ``FROM ... AS name`` ("" when there is none)."""
    return next((body for head, body in stages(text) if head.endswith(f" AS {name}")), "")


def runtime_problems(text: str) -> list[str]:
    """What keeps the Dockerfile's runtime stage from being lean and non-root: a compiler,
    Python's headers or Mesa installed, the venv not taken from the build stage, no USER or a
    root one."""
    found = []
    all_stages = stages(text)
    if len(all_stages) < 2:
        return ["one stage: the compiler is in the image"]
    body = stage(text, "runtime")
    if not body:
        return ["no stage named runtime"]
    for line in body.splitlines():
        if "apt-get install" in line and (m := BUILD_ONLY.search(line)):
            found.append(f"the runtime stage installs {m.group(0)}")
        if "apt-get install" in line and (m := MESA.search(line)):
            found.append(f"the runtime stage installs {m.group(0)}")
    if "COPY --from=build /opt/venv /opt/venv" not in body:
        found.append("the runtime stage does not take the venv from the build stage")
    users = re.findall(r"^USER\s+(\S+)", body, re.M)
    if not users:
        found.append("the runtime stage has no USER: it runs as root")
    elif users[-1].split(":")[0] in ("0", "root"):
        found.append(f"the runtime stage runs as {users[-1]}")
    return found


def target_problems(text: str) -> list[str]:
    """What keeps the Dockerfile's targets apart as docs/deploy.md says: the Rerun CLI's binary
    moved out of the venv in the build stage, the runtime stage checking it is absent and
    refusing a base with Mesa; ``viewer`` and ``robot`` each the runtime image plus the CLI or
    Mesa; the stages in the order the legacy builder builds them (runtime, viewer, mesa, robot:
    each target builds the stages before it)."""
    found = []
    build, runtime, viewer, robot = (stage(text, n) for n in ("build", "runtime", "viewer", "robot"))
    if f"mv {CLI_IN_VENV} /opt/rerun-cli/rerun" not in build:
        found.append("the build stage leaves the Rerun CLI in the venv")
    if f"test ! -e {CLI_IN_VENV}" not in runtime:
        found.append("the runtime stage does not check that the Rerun CLI is absent")
    if "libEGL_mesa" not in runtime:
        found.append("the runtime stage does not refuse a base with Mesa")
    if f"COPY --from=build /opt/rerun-cli/rerun {CLI_IN_VENV}" not in viewer:
        found.append("the viewer target has no Rerun CLI")
    if "COPY --from=mesa /opt/mesa /" not in robot or "MUJOCO_GL=egl" not in robot:
        found.append("the robot target has no Mesa, or does not render with it")
    heads = [head for head, _ in stages(text)]
    for name in ("viewer", "robot"):
        if f"FROM runtime AS {name}" not in heads:
            found.append(f"the {name} target is not built on the runtime image")
    order = [n for head in heads for n in ("runtime", "viewer", "mesa", "robot") if head.endswith(f" AS {n}")]
    if order != ["runtime", "viewer", "mesa", "robot"]:
        found.append(f"the stages are in the order {', '.join(order)}")
    return found


def image_problems(compose: dict[str, Any]) -> list[str]:
    """The services not in the image they need: ag_ex the robot image (its camera process
    renders), the viewer and the recorder (`rerun rrd merge`) the viewer image, every other the
    runtime image."""
    needs = {"ag_ex": "robot", "viewer": "viewer", "recorder": "viewer"}
    found = []
    for name, service in compose["services"].items():
        want = needs.get(name, "runtime")
        if service.get("build", {}).get("target") != want or IMAGES[want].default not in service.get(
            "image", ""
        ):
            found.append(f"{name}: not the {want} image")
    return found


def volume_mount_points(compose: dict[str, Any]) -> set[str]:
    """The container paths of the compose file's named volumes."""
    named = set(compose.get("volumes") or {})
    points = set()
    for service in compose["services"].values():
        for volume in service.get("volumes", []):
            source, target, *_ = volume.split(":")
            if source in named:
                points.add(target)
    return points


def unowned_mount_points(dockerfile: str, compose: dict[str, Any]) -> list[str]:
    """The named volumes' mount points the runtime stage does not create for its user (a new
    volume takes its mount point's owner and mode: otherwise root's)."""
    body = stage(dockerfile, "runtime")
    made = re.search(r"install -d -o roco -g roco -m 1777 ([^;\n]+)", body)
    created = set(made.group(1).split()) if made else set()
    return sorted(volume_mount_points(compose) - created)


def unlimited(compose: dict[str, Any]) -> list[str]:
    """The services without a memory, CPU or PIDs limit, or running as root."""
    found = []
    for name, service in compose["services"].items():
        missing = [key for key in ("mem_limit", "cpus", "pids_limit") if not service.get(key)]
        if missing:
            found.append(f"{name}: no {', '.join(missing)}")
        user = str(service.get("user", "")).replace("${ROCO_UID:-", "").split(":")[0].rstrip("}")
        if user in ("", "0", "root"):
            found.append(f"{name}: runs as root")
    return found


def test_the_runtime_stage_has_no_compiler_and_runs_as_roco() -> None:
    text = DOCKERFILE.read_text()
    assert runtime_problems(text) == []
    build, runtime = stages(text)[:2]
    assert build[0] == "FROM ${BUILD_BASE} AS build" and runtime[0] == "FROM ${BASE} AS runtime"
    assert "USER 10001:10001" in runtime[1] and f"--uid {UID}" in runtime[1]


def test_the_targets_runtime_viewer_and_robot() -> None:
    assert target_problems(DOCKERFILE.read_text()) == []


def test_the_check_catches_the_cli_or_mesa_in_the_wrong_target() -> None:
    """Planted faults: the CLI left in the venv, Mesa installed in the runtime stage, the viewer
    without the CLI, the robot without Mesa or on another base, the stages out of order."""
    text = DOCKERFILE.read_text()

    def planted(old: str, new: str) -> str:
        assert old in text, old
        return text.replace(old, new)

    cli_kept = planted(f"mv {CLI_IN_VENV} /opt/rerun-cli/rerun", f"cp {CLI_IN_VENV} /opt/rerun-cli/rerun")
    assert target_problems(cli_kept) == ["the build stage leaves the Rerun CLI in the venv"]
    mesa = planted("$need $want;", "$need $want libgl1-mesa-dri;")
    assert runtime_problems(mesa) == ["the runtime stage installs libgl1-mesa-dri"]
    no_cli = planted(f"COPY --from=build /opt/rerun-cli/rerun {CLI_IN_VENV}", "")
    assert target_problems(no_cli) == ["the viewer target has no Rerun CLI"]
    no_mesa = planted("COPY --from=mesa /opt/mesa /", "")
    assert target_problems(no_mesa) == ["the robot target has no Mesa, or does not render with it"]
    own_base = planted("FROM runtime AS robot", "FROM ${BASE} AS robot")
    assert target_problems(own_base) == ["the robot target is not built on the runtime image"]
    robot_first = text.split("# --- robot")[1]
    reordered = text.replace("# --- robot" + robot_first, "").replace(
        "# --- viewer", "# --- robot" + robot_first + "# --- viewer"
    )
    assert target_problems(reordered) == ["the stages are in the order runtime, robot, viewer, mesa"]


def test_each_service_runs_the_image_it_needs() -> None:
    compose = yaml.safe_load(COMPOSE_FILE.read_text())
    assert image_problems(compose) == []
    planted = COMPOSE_FILE.read_text().replace(
        "    <<: *roco-robot\n", "    <<: *roco\n"
    )  # ag_ex without Mesa
    assert image_problems(yaml.safe_load(planted)) == ["ag_ex: not the robot image"]
    planted = COMPOSE_FILE.read_text().replace("    <<: *roco-viewer\n", "    <<: *roco\n", 1)
    assert image_problems(yaml.safe_load(planted)) == ["recorder: not the viewer image"]


def test_the_check_catches_a_compiler_or_root_in_the_runtime_stage() -> None:
    """Planted faults: g++ installed in the runtime stage, USER root, and no USER at all."""
    text = DOCKERFILE.read_text()
    with_gxx = text.replace(
        "--no-install-recommends $need $want;", "--no-install-recommends $need $want g++;"
    )
    assert with_gxx != text
    assert runtime_problems(with_gxx) == ["the runtime stage installs g++"]
    as_root = text.replace("USER 10001:10001", "USER root")
    assert runtime_problems(as_root) == ["the runtime stage runs as root"]
    no_user = text.replace("USER 10001:10001\n", "")
    assert runtime_problems(no_user) == ["the runtime stage has no USER: it runs as root"]
    one_stage = text.split("# --- runtime")[0]
    assert runtime_problems(one_stage) == ["one stage: the compiler is in the image"]


def test_the_image_user_owns_every_volumes_mount_point() -> None:
    compose = yaml.safe_load(COMPOSE_FILE.read_text())
    assert volume_mount_points(compose) == {"/var/lib/roco/fleet", "/var/lib/roco/km", "/var/lib/roco/co"}
    assert unowned_mount_points(DOCKERFILE.read_text(), compose) == []
    planted = DOCKERFILE.read_text().replace(" /var/lib/roco/km ", " ")  # a_km's store left to root
    assert unowned_mount_points(planted, compose) == ["/var/lib/roco/km"]


def test_every_service_is_limited_and_not_root() -> None:
    compose = yaml.safe_load(COMPOSE_FILE.read_text())
    assert unlimited(compose) == []
    # every limit is a measured one, of a service; a service without one is an agent added since
    assert set(LIMITS) <= set(compose["services"])
    shipped = {"a_km", "a_pl", "a_co", "ag_ex", "a_ta", "a_hi"}
    assert set(compose["services"]) - set(LIMITS) <= set(default_spec().agent_names) - shipped
    new_agent = yaml.safe_load(render(default_spec()).replace("a_pl", "a_new"))
    assert unlimited(new_agent) == []
    planted = COMPOSE_FILE.read_text().replace("    pids_limit: 128\n", "", 1)
    assert (
        len(unlimited(yaml.safe_load(planted))) == 1
        and "no pids_limit" in unlimited(yaml.safe_load(planted))[0]
    )
    as_root = COMPOSE_FILE.read_text().replace('user: "${ROCO_UID:-10001}:${ROCO_GID:-10001}"', 'user: "0:0"')
    assert len(unlimited(yaml.safe_load(as_root))) == len(compose["services"])


@pytest.mark.skipif(shutil.which("sh") is None, reason="needs sh")
def test_the_entrypoint_names_a_run_folder_it_cannot_write(tmp_path: Path) -> None:
    blocked = tmp_path / "runs"
    blocked.write_text("a file where the run folder's parent should be")
    env = {"PATH": os.environ["PATH"], "ROCO_RUN": "r1", "ROCO_RUN_DIR": f"{blocked}/{{run}}"}
    done = subprocess.run(
        ["sh", str(ENTRYPOINT), "true"], capture_output=True, text=True, env=env, timeout=30, check=False
    )
    assert done.returncode == 2
    assert done.stderr.startswith(f"roco-entrypoint: cannot write {blocked}/r1 as uid ")
    assert "ROCO_UID" in done.stderr and "docs/deploy.md" in done.stderr
    env["ROCO_RUN_DIR"] = f"{tmp_path}/ok/{{run}}"
    done = subprocess.run(
        ["sh", str(ENTRYPOINT), "true"], capture_output=True, text=True, env=env, timeout=30, check=False
    )
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "ok" / "r1" / "logs").is_dir()
