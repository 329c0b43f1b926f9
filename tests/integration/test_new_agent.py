"""A new agent, end to end, as a user adds one (docs/spec.md, "Walk-through: adding an agent"):
in a copy of this checkout, the walk-through's specification entries are added, ``roco spec
new-agent a_wt`` writes the agent and renders deploy/compose.yaml, the handlers are written as
the document writes them, and then the tools agree (spec check, verify-code, the compose file,
the access control), and ``roco run`` pours with the new agent in the fleet, access control on:
the traffic record holds its conversations with a_km, the report names it, and ``roco spec
verify`` passes on the run. No other agent's code is edited.

Every command runs in the copy (its working folder, first on PYTHONPATH), so that the copy's
code runs, not this checkout's (which the virtual environment installs editable)."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from services.recorder.record import read_records
from services.spec.model import load
from tests.spec_check.walkthrough import AGENT, NEXT, fill, walkthrough_spec

pytestmark = [pytest.mark.slow, pytest.mark.fleet]

ROOT = Path(__file__).resolve().parents[2]
SENTENCE = "pour the jar into the bowl"
C = NEXT.channel_name
"""The new agent's channel (C9 in the shipped specification; the copy's is this checkout's)."""
BUILT = ("services/**/*.so", "velma/**/*.so", "shared/**/*.so", "services/runtime/_compiled.json")
"""What ``pip install -e .`` built beside the sources (not tracked): the compiled control law
and runtime, copied so that the copy runs as fast as this checkout."""


@dataclass(frozen=True)
class Checkout:
    root: Path
    env: dict[str, str]
    new_agent: subprocess.CompletedProcess[str]

    def roco(self, *args: str, timeout: float = 300) -> subprocess.CompletedProcess[str]:
        """``roco ARGS`` run in the copy, by the copy's code."""
        return subprocess.run(
            [sys.executable, "-m", "services.cli", *args],
            cwd=self.root,
            env=self.env,
            capture_output=True,
            text=True,
            timeout=timeout,
        )


def copy_checkout(to: Path) -> None:
    """The checkout's files as git sees them (tracked, and new files not ignored) and what the
    install built, copied to ``to``."""
    listed = subprocess.run(
        ["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
        cwd=ROOT,
        capture_output=True,
        check=True,
    ).stdout.decode()
    files = [ROOT / name for name in listed.split("\0") if name]
    files += [p for pattern in BUILT for p in ROOT.glob(pattern)]
    for source in files:
        if source.is_file() and ".venv" not in source.relative_to(ROOT).parts:
            target = to / source.relative_to(ROOT)
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(source, target)


@pytest.fixture(scope="module")
def checkout(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Checkout]:
    if shutil.which("git") is None or not (ROOT / ".git").exists():
        pytest.skip("needs this checkout's git repository and git (apt-get install git)")
    root = tmp_path_factory.mktemp("checkout")
    copy_checkout(root)
    spec = root / "services" / "spec" / "robot_companion.toml"
    doc = root / "docs" / "spec.md"
    walkthrough_spec(spec, base=spec, doc=doc)
    env = {k: v for k, v in os.environ.items() if k not in ("ROCO_ACL", "ROCO_SPEC", "ROCO_RUN_DIR")}
    env["PYTHONPATH"] = str(root)
    made = Checkout(root, env, subprocess.CompletedProcess([], 0))
    new_agent = made.roco("spec", "new-agent", AGENT)
    made = Checkout(root, env, new_agent)
    if new_agent.returncode == 0:
        fill(root / "services" / "agents" / "watch" / "agent.py", doc)
    yield made


def test_new_agent_writes_the_agent_and_the_compose_service_in_the_copy(checkout: Checkout) -> None:
    done = checkout.new_agent
    assert done.returncode == 0, done.stdout + done.stderr
    module = checkout.root / "services" / "agents" / "watch" / "agent.py"
    assert f"roco: wrote {module}" in done.stdout  # the copy's code, writing into the copy
    assert f"roco: wrote {checkout.root / 'deploy' / 'compose.yaml'}: one service per agent" in done.stdout
    where = subprocess.run(
        [sys.executable, "-c", "import services; print(services.__file__)"],
        cwd=checkout.root,
        env=checkout.env,
        capture_output=True,
        text=True,
        check=True,
    )
    assert Path(where.stdout.strip()).is_relative_to(checkout.root), where.stdout
    assert not (ROOT / "services" / "agents" / "watch").exists()
    compose = (checkout.root / "deploy" / "compose.yaml").read_text()
    assert '    command: ["python", "-m", "services.runtime.main", "a_wt"]' in compose
    done = checkout.roco("deploy", "compose", "--check")
    assert done.returncode == 0, done.stdout + done.stderr
    assert "roco: deploy/compose.yaml is what the specification gives" in done.stdout


def test_spec_check_and_verify_code_pass_with_no_edit_of_another_agent(checkout: Checkout) -> None:
    done = checkout.roco("spec", "check")
    assert done.returncode == 0, done.stdout + done.stderr
    done = checkout.roco("spec", "verify-code")
    assert done.returncode == 0, done.stdout + done.stderr
    assert "a_wt: 2 files; 1 protocol roles agree with the specification:" in done.stdout
    assert f"  {C} fipa-query participant with a_wt in L_WM (declared for every channel)" in done.stdout
    for agent in ("knowledge", "human_interface"):  # a_km serves C as it is; a_hi only changed group
        copied = checkout.root / "services" / "agents" / agent / "agent.py"
        assert copied.read_text() == (ROOT / "services" / "agents" / agent / "agent.py").read_text()


def test_the_access_control_lets_it_send_on_its_channel_and_nowhere_else(checkout: Checkout) -> None:
    done = checkout.roco("deploy", "acl")
    assert done.returncode == 0, done.stderr
    rules = {r["id"]: r for r in json.loads(done.stdout)["rules"]}
    sends = [k for k in rules["a_wt/ingress/put"]["key_exprs"] if k.startswith("roco/fipa/")]
    assert sends == [f"roco/fipa/{C}/a_wt/a_km", f"roco/fipa/{C}/a_wt/a_km/@adv/**"]
    assert f"roco/fipa/{C}/a_km/a_wt" in rules["a_wt/egress/put"]["key_exprs"]
    assert f"roco/fipa/{C}/a_km/a_wt" in rules["a_km/ingress/put"]["key_exprs"]
    assert f"roco/fipa/{C}/a_wt/a_km" in rules["a_km/egress/put"]["key_exprs"]


@pytest.fixture(scope="module")
def pour(checkout: Checkout) -> tuple[subprocess.CompletedProcess[str], Path]:
    if checkout.new_agent.returncode != 0:
        pytest.fail("roco spec new-agent failed: " + checkout.new_agent.stderr)
    runs = checkout.root / "runs"
    done = checkout.roco("run", SENTENCE, "--runs-dir", str(runs), "--timeout", "900", timeout=1200)
    (run_dir,) = [p for p in runs.iterdir() if p.is_dir()]
    return done, run_dir


def test_it_runs_in_the_fleet_with_access_control_and_the_run_conforms(
    checkout: Checkout, pour: tuple[subprocess.CompletedProcess[str], Path]
) -> None:
    done, run_dir = pour
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-2000:]
    alive = next(line for line in done.stdout.splitlines() if "all agents alive" in line)
    order = load(checkout.root / "services" / "spec" / "robot_companion.toml").launch_order
    assert alive.endswith(", ".join(order)) and order[-1] == "a_wt", alive
    assert (run_dir / "security" / "acl.json").is_file()  # access control was on
    # the traffic record: a_wt's queries on its channel and a_km's answers
    records = [r for r in read_records(run_dir) if r.channel == C]
    asked = [r for r in records if r.sender == "a_wt" and r.performative == "query-ref"]
    answered = [r for r in records if r.sender == "a_km" and r.performative == "inform-ref"]
    assert asked and answered, [(r.sender, r.performative) for r in records]
    assert {r.receivers for r in asked} == {("a_km",)} and {r.receivers for r in answered} == {("a_wt",)}
    # what it did with the answers: its log and counters
    log = (run_dir / "logs" / "a_wt.log").read_text()
    assert "started (pid" in log and "stopped by an error" not in log
    stopping = [line for line in log.splitlines() if "stopping; counters" in line]
    assert stopping and "'scenes': " in stopping[-1], stopping  # its counters when it stopped
    # the report names it, and the run conforms to the specification
    report = (run_dir / "report.md").read_text()
    assert "a_wt" in report and C in report
    verified = checkout.roco("spec", "verify", str(run_dir))
    assert verified.returncode == 0, verified.stdout[-3000:]
    assert "full conformance: yes" in verified.stdout
