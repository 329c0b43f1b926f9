"""A new agent, end to end, as a user adds one (docs/spec.md, "Walk-through: adding an agent"): in
a copy of this checkout, the watcher's terms module (``Tipped``) is written in its folder, the
walk-through's specification entries are added (the agent, its channels, and its own protocol
``kitchen-warning`` in the table), ``roco spec new-agent a_wt`` writes the agent and renders
deploy/compose.yaml, the handlers are written as the document writes them, and then the tools
agree (spec check, verify-code, deadlock, the compose file, the access control), and ``roco
scenario`` has Velma bring the bowl with the new agent in the fleet, access control on, and
knocks the bowl over as it is set down: the watcher, which asks to be told of changes within
0.5 s (``SceneSubscription.within_s``: the robot watches with its head camera while it is
subscribed), warns the person through a_hi (a ``Tipped`` in ``kitchen-warning``, which a_hi
tells as the term says itself) within 1 s of robot time of the knock (:func:`knock_to_warning`),
``roco scenario``'s output and the report show the warning with its sender, and ``roco spec
verify`` passes on the run. In the same copy, with a second agent added besides (the scratch
agent a_sc, which asks a_km and tells the person through a_hi: tests/support/checkout.py), the
tools and the fast part of roco's tests pass (:data:`FAST_PART`). No other agent's code is
edited.

Every command runs in the copy, by the copy's code (tests/support/checkout.py)."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from services.recorder.record import read_records
from services.report.load import load_run
from services.report.robot_clock import robot_clock
from tests.spec_check.walkthrough import NEXT
from tests.spec_check.walkthrough.scratch import SCRATCH
from tests.support.checkout import ROOT, Checkout, copy_checkout

pytestmark = [pytest.mark.slow]

C = NEXT.channel_name
"""The new agent's channel to a_km (C10 in the shipped specification; the copy's is this
checkout's)."""
N = NEXT.notice_channel_name
"""The new agent's channel to a_hi (C11 in the shipped specification)."""
WARNING = "the bowl has tipped over"
SESSION = """name = "the watcher warns of a knocked-over bowl"
timeout_s = 900
[[steps]]
say = "bring me the bowl"
expect = "failed"
expect_text = "the bowl is not upright"
[[steps]]
disturb = { object = "bowl", dz = 0.07, tilt = 3.1416 }
after = { step = "place_bowl/park" }
[[steps]]
say = "what is in the bowl?"
after = { ended = 1 }
expect = "answer"
"""
"""The session (the library's ``knocked_bowl``, then a question): the bowl brought to the table
and knocked upside down while the arm parks; the robot's watch sees it, so a_km learns it and
the watcher warns the person (and the set-down's last look sees it: the command fails); the
question keeps the fleet running while the warning goes out."""


@dataclass(frozen=True)
class Grown:
    """The copy of the checkout with the watcher and the scratch agent added, and what
    ``roco spec new-agent`` did for each."""

    copy: Checkout
    new_agent: subprocess.CompletedProcess[str]
    scratch: subprocess.CompletedProcess[str]

    @property
    def root(self) -> Path:
        return self.copy.root

    @property
    def env(self) -> dict[str, str]:
        return self.copy.env

    def roco(self, *args: str, timeout: float = 300) -> subprocess.CompletedProcess[str]:
        """``roco ARGS`` run in the copy, by the copy's code."""
        return self.copy.roco(*args, timeout=timeout)

    def python(self, code: str) -> str:
        """What Python ``code`` prints, run in the copy by the copy's code (its specification
        imports the watcher's terms, which only the copy has)."""
        done = self.copy.run("-c", code, timeout=120)
        done.check_returncode()
        return done.stdout.strip()


@pytest.fixture(scope="module")
def checkout(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Grown]:
    if shutil.which("git") is None or not (ROOT / ".git").exists():
        pytest.skip("needs this checkout's git repository and git (apt-get install git)")
    root = tmp_path_factory.mktemp("checkout")
    copy_checkout(root)
    copy = Checkout(root)
    new_agent = copy.add_watcher()
    scratch = copy.add_scratch() if new_agent.returncode == 0 else subprocess.CompletedProcess([], 1, "", "")
    yield Grown(copy, new_agent, scratch)


def test_new_agent_writes_the_agent_and_the_compose_service_in_the_copy(checkout: Grown) -> None:
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


def test_spec_check_and_verify_code_pass_with_no_edit_of_another_agent(checkout: Grown) -> None:
    done = checkout.roco("spec", "check")
    assert done.returncode == 0, done.stdout + done.stderr
    done = checkout.roco("spec", "verify-code")
    assert done.returncode == 0, done.stdout + done.stderr
    assert "a_wt: 3 files; 2 protocol roles agree with the specification:" in done.stdout
    assert f"  {C} fipa-subscribe participant with a_wt in L_WM (declared for every channel)" in done.stdout
    assert f"  {N} kitchen-warning participant with a_wt in L_HC (declared for every channel)" in done.stdout
    for agent in ("knowledge", "human_interface"):  # a_km and a_hi serve the new channels as they are
        copied = checkout.root / "services" / "agents" / agent / "agent.py"
        assert copied.read_text() == (ROOT / "services" / "agents" / agent / "agent.py").read_text()


def test_the_access_control_lets_it_send_on_its_channels_and_nowhere_else(checkout: Grown) -> None:
    done = checkout.roco("deploy", "acl")
    assert done.returncode == 0, done.stderr
    rules = {r["id"]: r for r in json.loads(done.stdout)["rules"]}
    sends = [k for k in rules["a_wt/ingress/put"]["key_exprs"] if k.startswith("roco/fipa/")]
    assert sorted(sends) == sorted(
        [
            f"roco/fipa/{ch}/a_wt/{peer}{tail}"
            for ch, peer in ((C, "a_km"), (N, "a_hi"))
            for tail in ("", "/@adv/**")
        ]
    )
    assert f"roco/fipa/{N}/a_wt/a_hi" in rules["a_hi/egress/put"]["key_exprs"]
    assert f"roco/fipa/{C}/a_km/a_wt" in rules["a_wt/egress/put"]["key_exprs"]
    assert f"roco/fipa/{C}/a_km/a_wt" in rules["a_km/ingress/put"]["key_exprs"]
    assert f"roco/fipa/{C}/a_wt/a_km" in rules["a_km/egress/put"]["key_exprs"]


LANGUAGE_TESTS = "tests/fipa_codec/test_fipa_languages.py"
"""The round trip of a sample of every content term (in :data:`FAST_PART`)."""


FAST_PART = (
    "tests/spec",
    "tests/spec_check/test_declared_protocol.py",
    "tests/architecture/test_agents_keep_no_protocol_books.py",
    "tests/architecture/test_agents_read_their_sources.py",
    "tests/architecture/test_agents_use_names.py",
    "tests/architecture/test_agents_use_roles.py",
    "tests/architecture/test_complexity.py",
    "tests/architecture/test_imports_resolve.py",
    LANGUAGE_TESTS,
)
"""The fast part of roco's own tests: those a new agent could break, run in the copy after it
is added, within about 30 s of test time — the specification's model, names, content terms,
protocols and deadlock search (tests/spec), the declared protocols (tests/spec_check), the
architecture rules an agent's module keeps (tests/architecture: no protocol machinery by hand,
its sources, the names module, its roles, no state machine hidden in branches, imports that
resolve), and the round trip of a sample of every content term
(tests/fipa_codec/test_fipa_languages.py). Left out: the tests marked ``walkthrough`` (they add
the watcher again); tests/spec_check/test_trace.py, whose rule that each leaf requirement has a
test marked with it a new requirement keeps only once a test in tests/ names it; and the
slower architecture tests of the whole package (import graph, lean processes, settings)."""


def test_the_tools_and_the_fast_part_of_the_tests_pass_in_the_copy(checkout: Grown) -> None:
    """With the watcher and the scratch agent added (the specification edited, their folders
    written), ``roco spec check``, ``verify-code`` and ``deadlock`` pass in the copy, and so does
    :data:`FAST_PART` (``-x -q -n 0 -p no:cacheprovider -m "not walkthrough"``), run by the
    copy's code on the copy's specification; the watcher's ``Tipped`` is among the terms whose
    sample is built from their declaration there. (scripts/check_growth.py runs all of roco's
    fast tests so.)"""
    assert checkout.new_agent.returncode == 0, checkout.new_agent.stderr
    assert checkout.scratch.returncode == 0, checkout.scratch.stdout + checkout.scratch.stderr
    assert (
        f"roco: wrote {checkout.root / 'services' / 'agents' / 'scratch' / 'agent.py'}"
        in checkout.scratch.stdout
    )
    assert SCRATCH in checkout.python(
        "from services.spec.model import default_spec; print(default_spec().agent_names)"
    )
    for tool in ("check", "verify-code", "deadlock"):
        done = checkout.roco("spec", tool)
        assert done.returncode == 0, f"roco spec {tool}: " + done.stdout[-3000:] + done.stderr[-2000:]
    options = ["-x", "-q", "-n", "0", "-p", "no:cacheprovider", "-m", "not walkthrough"]
    done = subprocess.run(
        [sys.executable, "-m", "pytest", *options, *FAST_PART],
        cwd=checkout.root,
        env=checkout.env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stdout[-4000:] + done.stderr[-2000:]
    assert " passed" in done.stdout.splitlines()[-1], done.stdout[-2000:]
    # the watcher's own term is among those whose sample is built from the declaration
    listed = subprocess.run(
        [sys.executable, "-m", "pytest", "--collect-only", "-q", "-p", "no:cacheprovider", LANGUAGE_TESTS],
        cwd=checkout.root,
        env=checkout.env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert f"{LANGUAGE_TESTS}::test_a_sample_built_from_the_declaration_round_trips[Tipped]" in listed.stdout


def disturbed_at(run_dir: Path) -> float:
    """When ag_ex applied the run's disturbance: the wall time (POSIX s) of its log line "the
    world: … moved by …" (services/agents/executor/agent.py ``_disturb``; the runtime's log
    format, services/runtime/log_format.py: local time to the millisecond)."""
    line = next(x for x in (run_dir / "logs" / "ag_ex.log").read_text().splitlines() if "the world: " in x)
    return _log_wall(line)


def _log_wall(line: str) -> float:
    """The wall time (POSIX s) of a log line (the runtime's log format,
    services/runtime/log_format.py: local time to the millisecond)."""
    stamp, ms = line[:23].split(",")
    return time.mktime(time.strptime(stamp, "%Y-%m-%d %H:%M:%S")) + int(ms) / 1000


def knocked_at_robot_time(run_dir: Path) -> float:
    """The robot time (s) of the run's disturbance: ag_ex's log line "the world: … at robot time
    T s" (services/agents/executor/agent.py ``_disturb``: the latest robot state's time when it
    passed the knock to the loop, at most ``STATE_MARGIN_S`` before the loop applied it)."""
    line = next(x for x in (run_dir / "logs" / "ag_ex.log").read_text().splitlines() if "the world: " in x)
    return float(line.rsplit("at robot time ", 1)[1].split()[0])


STATE_MARGIN_S = 0.02
"""Robot s a robot state may be old when read (velma/executor/loop_wire.py ``STATE_PERIOD``: 20
cycles of 1 ms)."""


def watched_throughout(run_dir: Path, start: float, end: float) -> bool:
    """Whether ag_ex's watch was on from wall time ``start`` to ``end`` (POSIX s): its log says
    "watch on" before ``start`` and no "watch off" between (velma/executor/process.py)."""
    lines = (run_dir / "logs" / "ag_ex.log").read_text().splitlines()
    on = [_log_wall(x) for x in lines if "watch on: " in x]
    off = [_log_wall(x) for x in lines if "watch off: " in x]
    return any(t <= start for t in on) and not any(start <= t <= end for t in off)


def knock_to_warning(run_dir: Path, told: float) -> tuple[float, float]:
    """Robot s from the knock to the warning, bounded each way, as measured in the run folder:

    - at least: the robot time of the frame that saw the bowl tipped (a_wt's log: "told the
      person: … (seen at robot time S s)", a_km's ``SceneChange.stamp``) less the knock's
      (:func:`knocked_at_robot_time`): the warning cannot precede what it tells;
    - at most: the robot time of ag_ex's first answer on C5 recorded after the warning (its
      ``CommandResult.sim_time`` or ``Observation.stamp``: services/report/robot_clock.py) less
      the knock's: the robot's clock had not passed it when the warning was heard (``told``,
      POSIX s, when the recorder heard it). While the robot watches, ag_ex answers a frame every
      0.25 s of robot time, so the bound is that tight. AssertionError when no answer follows."""
    wt_log = (run_dir / "logs" / "a_wt.log").read_text().splitlines()
    seen = next(x for x in wt_log if f"told the person: {WARNING}" in x)
    seen_robot = float(seen.rsplit("seen at robot time ", 1)[1].split()[0])
    knocked = knocked_at_robot_time(run_dir)
    run = load_run(run_dir)
    after = [robot for t, robot in robot_clock(run.messages).marks if t >= told - run.t0]
    assert after, "ag_ex answered nothing on C5 after the warning: no robot time bounds it"
    return seen_robot - knocked, after[0] - knocked


@pytest.fixture(scope="module")
def pour(checkout: Grown) -> tuple[subprocess.CompletedProcess[str], Path]:
    if checkout.new_agent.returncode != 0:
        pytest.fail("roco spec new-agent failed: " + checkout.new_agent.stderr)
    runs = checkout.root / "runs"
    session = checkout.root / "watcher.toml"
    session.write_text(SESSION)
    done = checkout.roco("scenario", str(session), "--runs-dir", str(runs), timeout=1200)
    (run_dir,) = [p for p in runs.iterdir() if p.is_dir()]
    return done, run_dir


@pytest.mark.fleet  # the only test here that runs a fleet: the others need no place in its group
def test_it_runs_in_the_fleet_with_access_control_and_the_run_conforms(
    checkout: Grown, pour: tuple[subprocess.CompletedProcess[str], Path]
) -> None:
    done, run_dir = pour
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-2000:]
    alive = next(line for line in done.stdout.splitlines() if "all agents alive" in line)
    order = checkout.python(
        "from services.spec.model import default_spec; print(*default_spec().launch_order)"
    )
    names = order.split()  # the watcher right after a_hi (the scratch agent after it)
    assert alive.endswith(", ".join(names)) and names[names.index("a_hi") + 1] == "a_wt", alive
    assert (run_dir / "security" / "acl.json").is_file()  # access control was on
    # the traffic record: a_wt's subscription on C, a_km's changes, and one warning on N
    records = [r for r in read_records(run_dir) if r.channel in (C, N)]
    sent = [(r.channel, r.sender, r.performative) for r in records]
    for one in ((C, "a_wt", "subscribe"), (C, "a_km", "agree"), (C, "a_km", "inform")):
        assert one in sent, sent
    warnings = [r for r in records if r.channel == N]
    assert [(r.sender, r.receivers, r.performative, r.protocol) for r in warnings] == [
        ("a_wt", ("a_hi",), "inform", "kitchen-warning")
    ], sent
    # the warning within 1 s of robot time of the knock: the robot watched (a_wt subscribed with
    # within_s), so it saw the knock within a camera frame or two (knock_to_warning)
    told = warnings[0].t
    at_least, at_most = knock_to_warning(run_dir, told)
    print(f"robot s from the knock to the warning: at least {at_least:.3f}, at most {at_most:.3f}")
    assert 0 <= at_least <= 1.0, (at_least, at_most)
    assert watched_throughout(run_dir, disturbed_at(run_dir), told)
    assert at_most <= 1.0, (at_least, at_most)
    # what it did with the changes: its log and counters
    log = (run_dir / "logs" / "a_wt.log").read_text()
    assert "started (pid" in log and "stopped by an error" not in log
    assert f"told the person: {WARNING}" in log
    stopping = [line for line in log.splitlines() if "stopping; counters" in line]
    assert stopping and "'warnings': 1" in stopping[-1], stopping  # its counters when it stopped
    # the person saw it, with its sender: in roco scenario's output and in the report
    assert any("a_wt" in line and WARNING in line for line in done.stdout.splitlines()), done.stdout[-3000:]
    # the report names it, and the run conforms to the specification
    report = (run_dir / "report.md").read_text()
    assert "a_wt" in report and C in report
    assert any("a_wt" in line and WARNING in line for line in report.splitlines())
    verified = checkout.roco("spec", "verify", str(run_dir))
    assert verified.returncode == 0, verified.stdout[-3000:]
    assert "full conformance: yes" in verified.stdout
