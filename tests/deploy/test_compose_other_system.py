"""A system that is not roco's kitchen, in a folder outside roco's tree, in containers
(``roco deploy compose --spec``, services/deploy/layout.py): the compose file runs roco's images
as they are (no build, no roco checkout as the context), mounts the system's folder read-only in
every roco service with ``ROCO_SPEC`` naming its specification there, has no world and no robot
image without a robot, keeps the credentials outside the system's folder, and its ``certs``
service issues that system's identities; ``--check`` names them, and a planted fault in the
file makes it fail naming the difference.

The system is the one ``roco spec init`` writes, and roco runs as a user runs it (the CLI in a
process of its own): the system's package is imported there, not in the test's process."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import msgspec
import pytest
from typer.testing import CliRunner

from services.cli.deploy import deploy_app
from services.deploy.compose import BUILD, COMPOSE_FILE, IMAGES, agent_extras, render
from services.deploy.layout import KITCHEN, SYSTEM_IN, LayoutError, layout_for
from services.security import certs
from services.spec.model import DEFAULT_SPEC, default_spec
from shared.settings import DEPLOYMENT, Settings, names
from tests.support.codec_registry import languages_leave_with_each_test  # noqa: F401  (autouse)

yaml = pytest.importorskip("yaml", reason="PyYAML reads the compose file: pip install -e '.[dev]'")

ROCO = [sys.executable, "-m", "services.cli"]
NAME = "depot"
AGENTS = ["a_wk", "a_ui"]  # roco spec init's, in its start order
IDENTITIES = ["a_ui", "a_wk", "recorder", "operator", "router"]
KITCHEN_AGENTS = set(default_spec().agent_names)
SPEC_VAR = Settings.env_name("spec")
CERTS_VAR = next(d.name for d in DEPLOYMENT if d.name.endswith("_CERTS"))
runner = CliRunner()


def roco(
    *args: str, cwd: Path | None = None, env: dict[str, str] | None = None
) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [*ROCO, *args],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=cwd,
        env={**os.environ, **(env or {})},
    )


@dataclass(frozen=True)
class Written:
    """A system ``roco spec init`` wrote in ``folder`` (outside roco's tree), its specification
    ``spec`` and the compose file ``roco deploy compose --spec --file`` wrote in the folder."""

    folder: Path
    spec: Path
    compose: Path

    @property
    def text(self) -> str:
        return self.compose.read_text()

    def check(self, text: str) -> subprocess.CompletedProcess[str]:
        """``roco deploy compose --check`` of a copy of the file holding ``text``."""
        planted = self.compose.with_name("planted.yaml")
        planted.write_text(text)  # beside the file: the same layout, the same override
        return roco("deploy", "compose", "--spec", str(self.spec), "--file", str(planted), "--check")


@pytest.fixture(scope="module")
def written(tmp_path_factory: pytest.TempPathFactory) -> Written:
    folder = tmp_path_factory.mktemp("elsewhere") / NAME
    done = roco("spec", "init", NAME, str(folder))
    assert done.returncode == 0, done.stderr
    spec, compose = folder / f"{NAME}.toml", folder / "compose.yaml"
    done = roco("deploy", "compose", "--spec", str(spec), "--file", str(compose))
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith(
        f"roco: wrote {compose}: router, recorder, viewer and the agents a_wk, a_ui\n"
    )
    return Written(folder, spec, compose)


def expand(value: str, env: dict[str, str] | None = None) -> str:
    """``${VAR:-default}`` and ``${VAR-default}`` as compose interpolates them."""
    return re.sub(r"\$\{([A-Z_]+):?-([^}]*)\}", lambda m: (env or {}).get(m.group(1)) or m.group(2), value)


def host(value: str, compose: Path) -> Path:
    """A volume's host path (``SOURCE:TARGET[:ro]``), as Compose resolves it: relative to the
    compose file's folder."""
    return (compose.parent / expand(value).split(":")[0]).resolve()


ROCO_SERVICES = ("certs", "router", "recorder", *AGENTS)


def _service_problems(name: str, service: dict[str, Any], compose: Path, folder: Path) -> list[str]:
    """What keeps roco service ``name`` of the file at ``compose`` from running the system of
    ``folder``: its folder not at /system, ROCO_SPEC not its specification there."""
    found = []
    mounted = {expand(v).split(":")[1]: host(v, compose) for v in service.get("volumes", [])}
    if mounted.get(SYSTEM_IN) != folder:
        found.append(f"{name}: the system's folder is not at {SYSTEM_IN}")
    spec_in = f"{SYSTEM_IN}/{NAME}.toml"
    if (service.get("environment") or {}).get(SPEC_VAR) != spec_in:
        found.append(f"{name}: {SPEC_VAR} is not {spec_in}")
    return found


def problems(text: str, compose: Path, folder: Path) -> list[str]:
    """What keeps compose file ``text`` (at ``compose``) from running the system of ``folder``
    without roco's checkout, or exposes a credential to a service through the system's mount."""
    loaded: dict[str, Any] = yaml.safe_load(text)
    services: dict[str, Any] = loaded["services"]
    found = [f"a service {s}" for s in sorted(set(services) - {*ROCO_SERVICES, "viewer"})]
    if built := [name for name, service in services.items() if "build" in service]:
        found.append(f"images built from roco's checkout ({', '.join(built)})")
    found += [f"{key}: the robot image, without a robot" for key in loaded if key == "x-roco-robot"]
    for name in ROCO_SERVICES:
        found += _service_problems(name, services.get(name, {}), compose, folder)
    if undeclared := sorted(set(re.findall(r"\b(ROCO_[A-Z0-9_]+)", text)) - set(names())):
        found.append(f"variables shared/settings.py does not declare: {', '.join(undeclared)}")
    credentials = host(services["certs"]["volumes"][0], compose)
    if credentials.is_relative_to(folder):
        found.append(f"the credentials ({credentials}) are in the system's folder, which every service sees")
    return found


def test_the_file_runs_the_system_from_its_folder_in_roco_s_images(written: Written) -> None:
    assert problems(written.text, written.compose, written.folder) == []
    loaded = yaml.safe_load(written.text)
    services = loaded["services"]
    assert list(services) == ["certs", "router", "recorder", *AGENTS, "viewer"]  # no world
    assert services["a_ui"]["image"] == services["certs"]["image"] == "${ROCO_IMAGE:-roco:latest}"
    assert services["recorder"]["image"] == "${ROCO_VIEWER_IMAGE:-roco-viewer:latest}"
    assert SYSTEM_IN not in str(services["viewer"])  # no roco code runs there
    assert SPEC_VAR in written.text and CERTS_VAR in written.text  # problems(): only declared ones
    assert f"#   identities:  {', '.join(IDENTITIES)}\n" in written.text


def test_each_service_mounts_its_own_identity_and_the_folder_beside_the_file(written: Written) -> None:
    services = yaml.safe_load(written.text)["services"]
    assert f"    - .:{SYSTEM_IN}:ro\n" in written.text  # relative to the file, written in the folder
    assert (written.folder / f"{NAME}.toml").is_file() and (written.folder / NAME / "names.py").is_file()
    for name in ("a_ui", "a_wk", "recorder"):  # each its own identity, from the folder outside
        own = [v for v in services[name]["volumes"] if f"/certs/{name}:" in v]
        assert own == [f"${{{CERTS_VAR}:-../{NAME}-certs}}/{name}:/certs/{name}:ro"], services[name][
            "volumes"
        ]


def test_the_check_of_the_system_finds_each_planted_problem(written: Written) -> None:
    """:func:`problems`' checks, each seen failing on a fault planted in the file."""
    text = written.text
    check = lambda planted: problems(planted, written.compose, written.folder)  # noqa: E731
    built = text.replace(
        "  image: ${ROCO_IMAGE:-roco:latest}\n", "  image: ${ROCO_IMAGE:-roco:latest}\n" + BUILD
    )
    assert check(built) == [f"images built from roco's checkout ({', '.join([*ROCO_SERVICES, 'viewer'])})"]
    world = text.replace(
        "  viewer:\n", '  world:\n    <<: *roco\n    command: ["python", "-m", "velma.world"]\n\n  viewer:\n'
    )
    assert check(world) == ["a service world"]
    robot = text.replace("x-env: &env\n", "x-roco-robot: &roco-robot\n  <<: *roco\n\nx-env: &env\n")
    assert check(robot) == ["x-roco-robot: the robot image, without a robot"]
    unmounted = text.replace(f"\n    - .:{SYSTEM_IN}:ro\n", "\n")  # the anchor's: the services keep theirs
    unmounted = unmounted.replace(f"      - .:{SYSTEM_IN}:ro\n", "", 2)  # and certs', router's
    assert check(unmounted) == [
        f"certs: the system's folder is not at {SYSTEM_IN}",
        f"router: the system's folder is not at {SYSTEM_IN}",
    ]
    kitchen_spec = text.replace(f"{SPEC_VAR}: {SYSTEM_IN}/{NAME}.toml", f"{SPEC_VAR}: {DEFAULT_SPEC}")
    assert len(check(kitchen_spec)) == len(ROCO_SERVICES)
    assert check(text + "# ROCO_BOGUS\n") == ["variables shared/settings.py does not declare: ROCO_BOGUS"]
    inside = text.replace(f"${{{CERTS_VAR}:-../{NAME}-certs}}", f"${{{CERTS_VAR}:-./certs}}")
    assert check(inside) == [
        f"the credentials ({written.folder / 'certs'}) are in the system's folder, which every service sees"
    ]


def test_the_certs_service_issues_the_system_s_identities(written: Written, tmp_path: Path) -> None:
    """The ``certs`` service's command, run as in its container: ``ROCO_SPEC`` as the file sets it,
    the system's folder where the file mounts it (here: /system is the folder itself)."""
    service = yaml.safe_load(written.text)["services"]["certs"]
    command = service["command"]
    assert command[:3] == ["python", "-m", "services.cli"] and command[3:] == [
        "deploy",
        "certs",
        "/certs",
        "--keep",
    ]
    spec_in = service["environment"][SPEC_VAR]
    out = tmp_path / "certs"
    done = roco(
        *command[3:5], str(out), *command[6:], env={SPEC_VAR: spec_in.replace(SYSTEM_IN, str(written.folder))}
    )
    assert done.returncode == 0, done.stderr
    assert sorted(certs.identities(out)) == sorted(IDENTITIES[:-1]) and (out / "router.pem").is_file()
    assert not KITCHEN_AGENTS & set(certs.identities(out))
    # --spec does the same; and a kept folder of another system (the kitchen's) says what it lacks
    done = roco("deploy", "certs", str(tmp_path / "given"), "--spec", str(written.spec))
    assert done.returncode == 0 and "roco: credentials for a_ui, a_wk, recorder, operator in" in done.stdout
    kitchen = tmp_path / "kitchen"
    assert roco("deploy", "certs", str(kitchen)).returncode == 0
    done = roco("deploy", "certs", str(kitchen), "--keep", "--spec", str(written.spec))
    assert done.returncode == 0 and "; none for a_ui, a_wk of the specification" in done.stdout, done.stdout
    assert not {"a_ui", "a_wk"} & set(certs.identities(kitchen))  # kept as it was: nothing issued


def test_the_check_passes_and_names_the_identities(written: Written) -> None:
    done = roco("deploy", "compose", "--spec", str(written.spec), "--file", str(written.compose), "--check")
    assert done.returncode == 0, done.stderr
    first, second = done.stdout.splitlines()
    assert first == (
        f"roco: {written.compose} is what the specification gives (identities: {', '.join(IDENTITIES)}; "
        f"the system's folder (.) read-only at {SYSTEM_IN}, {SPEC_VAR}={SYSTEM_IN}/{NAME}.toml)"
    )
    assert (
        second
        == f"roco: {written.compose.with_name('compose.netfault.yaml')} is what the specification gives"
    )


def _in(service: str, old: str, new: str = "") -> Callable[[str], str]:
    """A planted fault: ``old`` replaced by ``new`` in ``service``'s block only (``x-…``: that
    anchor's)."""
    header = f"\n{service}:" if service.startswith("x-") else f"\n  {service}:"

    def plant(text: str) -> str:
        start = text.index(header, 0 if service.startswith("x-") else text.index("\nservices:\n"))
        end = text.index("\n\n", start) + 1
        block = text[start:end]
        assert old in block, (service, old)
        return text[:start] + block.replace(old, new) + text[end:]

    return plant


PLANTED: dict[str, tuple[Callable[[str], str], str]] = {
    "an agent's system mount dropped": (
        _in("a_wk", f"      - .:{SYSTEM_IN}:ro\n"),
        f"service a_wk does not mount the system's folder (.:{SYSTEM_IN}:ro)",
    ),
    "the anchor's system mount dropped": (
        _in("x-roco", f"    - .:{SYSTEM_IN}:ro\n"),
        f"x-roco does not mount the system's folder (.:{SYSTEM_IN}:ro)",
    ),
    "an identity dropped": (
        _in("a_ui", f"      - ${{{CERTS_VAR}:-../{NAME}-certs}}/a_ui:/certs/a_ui:ro\n"),
        "service a_ui does not mount its identity a_ui",
    ),
    "another's identity mounted": (
        _in(
            "a_ui",
            "/a_ui:/certs/a_ui:ro\n",
            f"/a_ui:/certs/a_ui:ro\n      - ${{{CERTS_VAR}:-x}}/a_wk:/certs/a_wk:ro\n",
        ),
        "service a_ui mounts credentials not its own (a_wk)",
    ),
    "the recorder's identity dropped": (
        _in("recorder", f"      - ${{{CERTS_VAR}:-../{NAME}-certs}}/recorder:/certs/recorder:ro\n"),
        "service recorder does not mount its identity recorder",
    ),
    "the kitchen's specification in the environment": (
        _in("x-env", f"  {SPEC_VAR}: {SYSTEM_IN}/{NAME}.toml\n", ""),
        f"x-env does not set {SPEC_VAR} to {SYSTEM_IN}/{NAME}.toml",
    ),
    "certs without the specification": (
        _in(
            "certs",
            f"      {SPEC_VAR}: {SYSTEM_IN}/{NAME}.toml\n",
            f"      {SPEC_VAR}: {SYSTEM_IN}/cell.toml\n",
        ),
        f"service certs does not set {SPEC_VAR} to {SYSTEM_IN}/{NAME}.toml: "
        "it would issue another system's identities",
    ),
    "an agent's service dropped": (
        lambda text: text.replace(text[text.index("\n  a_wk:") : text.index("\n\n  a_ui:")], ""),
        "no service for agent a_wk",
    ),
}


@pytest.mark.parametrize("fault", list(PLANTED))
def test_a_planted_fault_fails_the_check_naming_it(written: Written, fault: str) -> None:
    plant, named = PLANTED[fault]
    planted = plant(written.text)
    assert planted != written.text
    done = written.check(planted)
    assert done.returncode == 1 and done.stdout == "", done.stdout
    assert done.stderr == (
        f"roco: {written.compose.with_name('planted.yaml')} differs from what the specification gives "
        f"({named}): run `roco deploy compose --spec {written.spec} --file "
        f"{written.compose.with_name('planted.yaml')}`\n"
    )


def test_without_file_it_writes_in_the_system_s_folder_not_roco_s(written: Written) -> None:
    kitchen = COMPOSE_FILE.read_bytes()
    done = roco("deploy", "compose", "--spec", str(written.spec), cwd=written.folder.parent)
    assert done.returncode == 0, done.stderr
    target = written.folder / "deploy" / "compose.yaml"
    assert done.stdout.startswith(f"roco: wrote {NAME}/deploy/compose.yaml: "), done.stdout
    assert f"      - ..:{SYSTEM_IN}:ro\n" in target.read_text()  # its folder, from deploy/
    assert (written.folder / "deploy" / "compose.netfault.yaml").is_file()
    assert COMPOSE_FILE.read_bytes() == kitchen


NEW_AGENT = """
[[agents]]
name = "a_lg"
group = "wk"
implementation = "depot.logger.agent:Logger"
job = "keeps a log of the tasks"

[[channels]]
name = "C2"
ends = ["a_wk", "a_lg"]
transmits = "the tasks done"
  [[channels.protocols]]
  protocol = "fipa-request"
  initiator = "a_wk"
  [channels.protocols.languages]
  request = "L_DEPOT"
  agree = "L_DEPOT"
  inform = "L_DEPOT"
  failure = "L_DEPOT"
  refuse = "L_DEPOT"
  [channels.protocols.contents]
  request = ["Task"]
  inform = ["Done"]
  refuse = ["Refused"]
  failure = ["Refused"]
"""


def test_new_agent_brings_the_system_s_file_up_to_date_in_its_layout(tmp_path: Path) -> None:
    folder = tmp_path / NAME
    assert roco("spec", "init", NAME, str(folder)).returncode == 0
    spec = folder / f"{NAME}.toml"
    assert roco("deploy", "compose", "--spec", str(spec)).returncode == 0  # deploy/compose.yaml
    with spec.open("a") as toml:
        toml.write(NEW_AGENT)
    done = roco("spec", "new-agent", "a_lg", "--spec", str(spec))
    assert done.returncode == 0, done.stdout + done.stderr
    assert (
        f"roco: wrote {folder / 'deploy' / 'compose.yaml'}: one service per agent (a_wk, a_ui, a_lg)"
        in done.stdout
    )
    done = roco("deploy", "compose", "--spec", str(spec), "--check")
    assert done.returncode == 0, done.stderr
    assert (
        "(identities: a_ui, a_wk, a_lg, recorder, operator, router; the system's folder (..) " in done.stdout
    )


# ---------------------------------------------------------------- in the test's process
def test_layouts_are_relative_to_the_file_and_keep_the_credentials_outside(tmp_path: Path) -> None:
    spec = tmp_path / "sys" / "cell.toml"
    inside = layout_for(spec, tmp_path / "sys" / "compose.yaml")
    assert (inside.system, inside.runs, inside.certs, inside.spec_in) == (
        ".",
        "./runs",
        "../sys-certs",
        "/system/cell.toml",
    )
    below = layout_for(spec, tmp_path / "sys" / "deploy" / "compose.yaml")
    assert (below.system, below.runs, below.certs) == ("..", "../runs", "../../sys-certs")
    beside = layout_for(spec, tmp_path / "ops" / "compose.yaml")
    assert (beside.system, beside.runs, beside.certs) == ("../sys", "../sys/runs", "../sys-certs")
    above = layout_for(spec, tmp_path / "compose.yaml")
    assert (above.system, above.certs) == ("./sys", "./sys-certs")  # "./": a path, not a volume's name
    assert layout_for(DEFAULT_SPEC, tmp_path / "compose.yaml") == KITCHEN
    for bad in ("a b", "a:b", "a$b"):
        with pytest.raises(LayoutError, match="a compose file cannot name"):
            layout_for(tmp_path / bad / "cell.toml", tmp_path / bad / "compose.yaml")


def test_a_folder_a_compose_file_cannot_name_is_one_line_and_exit_2(tmp_path: Path) -> None:
    spec = tmp_path / "my system" / "spec.toml"
    spec.parent.mkdir()
    shutil.copy(DEFAULT_SPEC, spec)  # the kitchen's, elsewhere: its packages are roco's
    r = runner.invoke(deploy_app, ["compose", "--spec", str(spec), "--file", str(tmp_path / "c.yaml")])
    assert r.exit_code == 2 and r.output.count("\n") == 1, r.output
    assert r.output.startswith(f"roco: {spec.parent}: a compose file cannot name ")
    assert not (tmp_path / "c.yaml").exists()


def test_world_and_robot_image_follow_the_robot_role_not_the_name() -> None:
    spec = default_spec()
    assert spec.playing("robot") == "ag_ex" and agent_extras(spec, "ag_ex").image == "robot"
    no_robot = msgspec.structs.replace(
        spec,
        agents=tuple(msgspec.structs.replace(a, role="") if a.role == "robot" else a for a in spec.agents),
    )
    loaded = yaml.safe_load(render(no_robot))
    assert "world" not in loaded["services"] and "x-roco-robot" not in loaded
    assert loaded["services"]["ag_ex"]["image"] == "${ROCO_IMAGE:-roco:latest}"
    assert "ipc" not in loaded["services"]["ag_ex"]
    assert (
        yaml.safe_load(render(spec))["services"]["ag_ex"]["image"]
        == f"${{{IMAGES['robot'].variable}:-roco-robot:latest}}"
    )
