"""A researcher's own system, outside roco's tree, with roco's documented commands only
(docs/method.md): ``roco spec init shop DIR`` writes it; a second agent is added as
docs/spec.md adds one (a decomposition step splitting the worker's group, the agent and its
channel in the specification, ``roco spec new-agent``, its handlers written, a test naming its
requirement); the worker serves the new channel too, and breaks a task it agreed to when told
to (the planted fault: R1's property says an agreed task is never failed). Then the system's
fleet runs under access control and TLS (``roco up --spec``), a person's lines are sent, ``roco
status`` names the violated requirement while the fleet runs (the live monitor), ``roco spec
verify`` gives full conformance, ``roco spec trace`` reads the system's own tests, its report
has no kitchen section, and ``roco deploy compose --spec`` writes a compose file whose
``--check`` names the system's identities. Nothing of roco is patched, nothing is imported from
roco but its public API (services/runtime/agent.py, roles), no ``sitecustomize``. One fleet
(no robot: about 15 s) serves every test of the module."""

from __future__ import annotations

import re
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from services.fleet.launcher import free_port
from tests.support.lines import wait_until

pytestmark = [pytest.mark.slow, pytest.mark.xdist_group("own_system")]
ROCO = [sys.executable, "-m", "services.cli"]
"""``roco``, run by this interpreter (the console script of the same installation)."""

SECOND = """
[[requirements]]
id = "R2"
parent = "R"
text = "audit the worker: ask it for a task of the auditor's own"

[[steps]]
number = 2
requirements = ["R2"]
split = "wk"
into = ["wo", "au"]
tasks = { wo = "does the tasks", au = "audits the worker" }
reallocated = [{ number = 1, from = "wk", to = "wo" }]
new_channels = [{ number = 2, ends = ["au", "wo"], transmits = "audit tasks and their outcome" }]
"""
"""The second agent's requirement and decomposition step (before the agents, as in the file)."""
AGENT = """
[[agents]]
name = "a_au"
group = "au"
implementation = "shop.audit.agent:Audit"
job = "auditor: asks the worker for a task of its own, once"

[[channels]]
name = "C2"
ends = ["a_au", "a_wk"]
transmits = "audit tasks and their outcome"
  [[channels.protocols]]
  protocol = "fipa-request"
  initiator = "a_au"
  languages = { LANGUAGES }
  contents = { request = ["Task"], inform = ["Done"], refuse = ["Refused"], failure = ["Refused"] }
"""
"""The second agent and its channel (at the end of the file)."""
LANGUAGES = ", ".join(
    f'{p} = "L_SHOP"' for p in ("request", "agree", "inform", "failure", "refuse", "cancel")
)
"""C2's fipa-request in the system's language, as C1's."""
SERVES = (
    "(\n        participant(C1, FIPA_REQUEST, L_SHOP),\n        participant(C2, FIPA_REQUEST, L_SHOP),\n    )"
)
"""The worker's roles: C1's, and the auditor's channel."""
OPENS = '''    def _periodically(self) -> None:
        """Ask the worker for one audit task, once."""
        if not self.asked:
            self.asked = True
            self.roles.open(C2, FIPA_REQUEST, Task(text="audit"))
'''
"""The auditor's ``_periodically``, in place of the one ``roco spec new-agent`` wrote."""
BREAKS = """        conv.reply(Performative.AGREE)
        if "break" in task.text:  # the planted fault: a task agreed to, then failed (R1 forbids it)
            conv.reply(Performative.FAILURE, Refused(reason="it broke"))
            return
"""
"""What the worker does with a task that says "break" (in place of its agree)."""
TRACED = '''"""The auditor's requirement."""

import pytest


@pytest.mark.requirement("R2")
def test_the_auditor_is_written() -> None:
    pass
'''


def roco(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    """``roco args…`` in a process of its own; its exit status, stdout and stderr."""
    return subprocess.run([*ROCO, *args], capture_output=True, text=True, timeout=180, cwd=cwd)


def ok(done: subprocess.CompletedProcess[str]) -> subprocess.CompletedProcess[str]:
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    return done


def grow(folder: Path) -> Path:
    """``roco spec init shop folder``, then the auditor added and the worker edited as a user
    does; the specification's path."""
    ok(roco("spec", "init", "shop", str(folder)))
    spec = folder / "shop.toml"
    text = spec.read_text()
    head, agents = text.split("\n[[agents]]", 1)
    text = head + "\n" + SECOND + "\n[[agents]]" + agents + AGENT.replace("LANGUAGES", LANGUAGES)
    text = text.replace('start_order = ["a_wk", "a_ui"]', 'start_order = ["a_wk", "a_au", "a_ui"]')
    worker_entry = 'name = "a_wk"\ngroup = "wk"'
    assert text.count(worker_entry) == 1
    spec.write_text(text.replace(worker_entry, 'name = "a_wk"\ngroup = "wo"'))
    worker = folder / "shop" / "worker" / "agent.py"
    code = worker.read_text()
    for old, new in (
        ("import C1, FIPA_REQUEST", "import C1, C2, FIPA_REQUEST"),
        ("(participant(C1, FIPA_REQUEST, L_SHOP),)", SERVES),
        ("        conv.reply(Performative.AGREE)\n", BREAKS),
    ):  # fmt: skip
        assert code.count(old) == 1, old
        code = code.replace(old, new)
    ok(roco("spec", "names", "--spec", str(spec)))  # C2 in the system's names, before the worker needs it
    worker.write_text(code)
    ok(roco("spec", "new-agent", "a_au", "--spec", str(spec)))
    auditor = folder / "shop" / "audit" / "agent.py"
    code = auditor.read_text()
    code = re.sub(
        r"    def _periodically\(self\) -> None:\n(?:        .*\n|\n)*?(?=    @handles)", OPENS + "\n", code
    )
    code = re.sub(
        r"raise NotImplementedError\(\n(?:\s+\".*\"\n)+\s+\)",
        'self.log.info("a_wk answered %s", conv.content)',
        code,
    )
    code = code.replace('    name = "a_au"\n', '    name = "a_au"\n    asked = False\n')
    code = code.replace("from shop.names import", "from shop.terms import Task\nfrom shop.names import")
    auditor.write_text(code)
    (folder / "tests" / "test_audit.py").write_text(TRACED)
    return spec


@dataclass
class Shop:
    """The grown system's specification, its run folder and what roco said to each command."""

    spec: Path
    run_dir: Path
    said: dict[str, subprocess.CompletedProcess[str]]
    status: subprocess.CompletedProcess[str]
    down: subprocess.CompletedProcess[str]


LINES = ("fetch water", "break the cup")
"""Done; agreed, then failed (the planted fault)."""


@pytest.fixture(scope="module")
def shop(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Shop]:
    """The system grown in a folder of its own, its spec tools run, its fleet up (access control
    and TLS on, as by default), ``LINES`` sent, the auditor's conversation recorded, `roco
    status`, `roco down`."""
    folder = tmp_path_factory.mktemp("researcher") / "shop"
    spec = grow(folder)
    for tool in ("check", "deadlock", "verify-code"):
        ok(roco("spec", tool, "--spec", str(spec)))
    runs = folder / "runs"
    ok(roco("up", "--spec", str(spec), "--port", str(free_port()), "--runs-dir", str(runs)))
    try:
        said = {line: roco("send", line, "--runs-dir", str(runs)) for line in LINES}
        (run_dir,) = [p for p in runs.iterdir() if p.is_dir()]
        traffic = run_dir / "traffic.jsonl"
        wait_until(
            lambda: traffic.is_file() and '"channel":"C2"' in traffic.read_text(), 60, "the audit recorded"
        )
        status = roco("status", "--runs-dir", str(runs))
    finally:
        down = ok(roco("down", "--runs-dir", str(runs)))
    yield Shop(spec, run_dir, said, status, down)


def test_the_person_s_lines_are_done_and_the_broken_one_fails(shop: Shop) -> None:
    done = ok(shop.said["fetch water"])
    assert done.stdout.splitlines() == ["accepted: on it", "succeeded: done: fetch water"]
    broken = shop.said["break the cup"]
    assert broken.returncode == 1 and broken.stdout.splitlines()[-1] == "failed: it broke", broken.stdout


def test_status_names_the_agents_and_the_requirement_violated_live(shop: Shop) -> None:
    lines = ok(shop.status).stdout.splitlines()
    assert {line.split()[0] for line in lines if " alive" in line} >= {"a_wk", "a_au", "a_ui"}, lines
    (flag,) = [line for line in lines if line.startswith("violated")]
    assert flag.startswith("violated  R1 “a task agreed to is done") and "failure" in flag, flag


def test_the_run_conforms_and_the_system_s_own_tests_are_traced(shop: Shop) -> None:
    verified = ok(roco("spec", "verify", str(shop.run_dir)))  # the run remembers its specification
    assert "full conformance: yes" in verified.stdout, verified.stdout
    traced = roco("spec", "trace", str(shop.run_dir))
    assert traced.returncode == 1, traced.stdout + traced.stderr  # R1 violated
    assert "1 violated (R1)" in traced.stdout, traced.stdout
    assert "tests/test_audit.py" in traced.stdout and "tests/test_shop.py" in traced.stdout, traced.stdout


def test_the_report_is_the_system_s_without_kitchen_sections(shop: Shop) -> None:
    report = (shop.run_dir / "report.md").read_text()
    assert "| System | Shop |" in report
    assert "| C1 | a_ui–a_wk |" in report and "| C2 | a_au–a_wk |" in report, report
    for kitchen in ("Spheres", "ag_ex", "paper (§5.7)", "Planning phases", "Control loop", "a_co"):
        assert kitchen not in report, kitchen


def test_its_compose_file_carries_it_and_check_names_its_identities(shop: Shop) -> None:
    """`roco deploy compose --spec` writes the system's compose file in its folder; `--check`
    names its identities and the system's folder it mounts; with the auditor's service taken out
    of the file (the planted fault), `--check` exits 1."""
    compose = shop.spec.parent / "compose.yaml"
    ok(roco("deploy", "compose", "--spec", str(shop.spec), "--file", str(compose)))
    checked = ok(roco("deploy", "compose", "--spec", str(shop.spec), "--file", str(compose), "--check"))
    assert "(identities: a_ui, a_wk, a_au, recorder, operator, router;" in checked.stdout, checked.stdout
    assert "read-only at /system, ROCO_SPEC=/system/shop.toml" in checked.stdout, checked.stdout
    text = compose.read_text()
    assert "a_km" not in text and "\n  world:" not in text and "build:" not in text
    start = text.index("\n  a_au:\n")
    end = text.index("\n  a_", start + 1)
    compose.write_text(text[:start] + text[end:])
    broken = roco("deploy", "compose", "--spec", str(shop.spec), "--file", str(compose), "--check")
    assert broken.returncode == 1 and "a_au" in broken.stdout + broken.stderr, broken.stdout + broken.stderr
