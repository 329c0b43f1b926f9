"""The walk-through of docs/spec.md ("adding an agent"), stage by stage: its TOML and Python
snippets are read from the document itself and added to a copy of the shipped specification
and to the agent ``roco spec new-agent`` writes, and the tools say what the document says
they say; a_km serves the new channel with no edit of its code; at the end the new agent and
a_km run on one bus and the watcher's query is answered. The snippets' requirement, step and
channel are numbered the next free ones of the shipped specification (R4, 9 and C9 as the
document writes them, until the specification grows; walkthrough.NEXT). The agent names its
channel by services/spec/names.py, which new-agent renders again where it writes; in this process the
module rendered from the staged specification stands in for it (tests/support/spec_names.py)."""

from __future__ import annotations

import shutil
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from services.deploy.compose import check, read
from services.runtime.memory_transport import MemoryBus
from services.spec.check import check_report
from services.spec.model import DEFAULT_SPEC, load
from services.spec.render_names import NAMES_FILE, render
from services.spec_check.code_check import verify_code_report
from services.spec_check.new_agent import write_agent
from shared.fipa_codec.languages.common import Pose
from shared.fipa_codec.languages.l_wm import ObjectInfo
from tests.spec_check.walkthrough import (
    AS_WRITTEN,
    GROUP_EDIT,
    MODULE,
    NEXT,
    ROOT,
    Numbers,
    fill,
    free_numbers,
    renumbered,
    snippet,
    staged,
    walkthrough_spec,
)
from tests.support.spec_names import use_names

HANDLERS = ("_on_failure", "_on_inform", "_on_inform_ref", "_on_refuse")
C = NEXT.channel_name
"""The walk-through's channel: C9 in the shipped specification."""


def stage(tmp_path: Path, *parts: str, edits: dict[str, str] | None = None) -> Path:
    path = tmp_path / "spec.toml"
    path.write_text(staged(DEFAULT_SPEC.read_text(), *parts, edits=edits))
    return path


def watch_stage(tmp_path: Path, package: str) -> Path:
    """Stages 1 and 2, with the watcher written under ``tmp_path`` as ``package.agent`` (a
    package of its own per test: a module is imported once per process)."""
    return stage(tmp_path, snippet(1), snippet(2).replace(MODULE, f"{package}.agent"), edits=GROUP_EDIT)


def test_stage_1_a_new_step_makes_check_list_what_is_missing(tmp_path: Path) -> None:
    ok, text = check_report(stage(tmp_path, snippet(1)))
    assert not ok
    for line in (
        "stop condition: group 'ui' of the final fringe is substituted by no agent",
        "stop condition: group 'wt' of the final fringe is substituted by no agent",
        "agent a_hi substitutes group 'hi', which is not in the final fringe",
        "channel C2 joins <group ui> and a_co by the decomposition, but a_co and a_hi in [[channels]]",
        "channel C7 joins <group ui> and a_km by the decomposition, but a_hi and a_km in [[channels]]",
        "channel C8 joins <group ui> and x_fipa by the decomposition, but x_fipa and a_hi in [[channels]]",
        f"channel {C} of the decomposition is not specified in [[channels]]",
        "7 problem(s)",
    ):
        assert line in text, text


def test_stage_2_new_agent_writes_the_agent_and_its_service_and_verify_code_lists_its_handlers(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = watch_stage(tmp_path, "walk_wt2")
    assert check_report(path)[0]
    compose = tmp_path / "deploy" / "compose.yaml"
    compose.parent.mkdir()
    shutil.copy(ROOT / "deploy" / "compose.yaml", compose)
    names = tmp_path / "services" / "spec" / "names.py"
    names.parent.mkdir(parents=True)
    shutil.copy(NAMES_FILE, names)

    def new_agent() -> subprocess.CompletedProcess[str]:
        command = ["spec", "new-agent", "a_wt", "--spec", str(path), "--root", str(tmp_path)]
        return subprocess.run(
            [sys.executable, "-m", "services.cli", *command], capture_output=True, text=True, cwd=ROOT
        )

    done = new_agent()
    assert done.returncode == 0, done.stderr
    assert f"roco: wrote {tmp_path / 'walk_wt2' / 'agent.py'}" in done.stdout
    channels = ", ".join(c.name for c in load(path).channels)
    assert f"roco: wrote {names}: the names of channels {channels}" in done.stdout and channels.endswith(C)
    assert f"roco: wrote {compose}: one service per agent (" in done.stdout
    assert (
        f"roco: fill in {', '.join(HANDLERS)} and what _periodically opens; then: roco spec verify-code"
        in done.stdout
    )
    # the names module now names the new channel, and the compose file runs the new agent too,
    # as the specification gives them
    assert names.read_text() == render(load(path)) and f"\n{C} = Channel.{C}\n" in names.read_text()
    assert f"initiator({C}, FIPA_QUERY, L_WM)" in (tmp_path / "walk_wt2" / "agent.py").read_text()
    assert check(compose, load(path)) is None
    assert '    command: ["python", "-m", "services.runtime.main", "a_wt"]' in read(compose)
    again = new_agent()
    last = again.stderr.splitlines()[-1]
    assert (
        again.returncode == 1
        and last.startswith("roco: ")
        and last.endswith("new-agent writes only new files")
    )

    monkeypatch.syspath_prepend(str(tmp_path))
    use_names(load(path), monkeypatch)
    ok, text = verify_code_report(path)
    assert not ok
    for handler in HANDLERS:
        assert f"- agent a_wt has a handler not written yet: {handler} raises NotImplementedError" in text
    assert "4 problem(s)" in text
    # the other end of the new channel is served by a_km's code as it is: a role for every channel
    assert "agent a_km" not in text
    assert (
        f"  {C} fipa-query participant with a_wt in L_WM (declared for every channel): receives cancel, "
        "query-if, query-ref; sends agree, failure, inform, inform-ref, refuse"
    ) in text


def finished_watch(tmp_path: Path, package: str) -> Path:
    path = watch_stage(tmp_path, package)
    module = write_agent(load(path), "a_wt", tmp_path).module
    fill(module)
    return path


def test_stage_3_the_finished_agent_conforms_and_a_km_answers_it_as_it_is(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = finished_watch(tmp_path, "walk_wt3")
    monkeypatch.syspath_prepend(str(tmp_path))
    use_names(load(path), monkeypatch)
    ok, text = verify_code_report(path)
    assert ok, text
    assert "a_wt: 2 files; 1 protocol roles agree with the specification:" in text
    assert (
        f"  {C} fipa-query initiator with a_km in L_WM: receives agree, failure, inform, inform-ref, refuse; "
        "sends cancel, query-if, query-ref"
    ) in text

    # both ends of the new channel on one bus, started from the staged specification; a_km keeps its
    # knowledge in memory
    for name in ("ROCO_KM_STORE", "ROCO_RUN_DIR", "ROCO_STATE_DIR"):
        monkeypatch.delenv(name, raising=False)
    from services.runtime.main import agent_class

    spec = load(path)
    bus = MemoryBus()
    km = agent_class(spec, "a_km")(bus.transport(), spec)
    watch = agent_class(spec, "a_wt")(bus.transport(), spec)
    for agent in (km, watch):
        agent.bind()
    thread = threading.Thread(target=km.run, daemon=True)
    thread.start()
    try:
        watch.setup()
        watch._periodically()  # type: ignore[attr-defined]  # what the periodic behaviour runs
        watch._dispatch()
        for _ in range(400):  # each acquire blocks until input arrives or 0.05 s pass
            watch._acquire(0.05)
            watch.handle_received()
            if watch.counters["scenes"] or watch.counters["unanswered"]:
                break
        assert watch.counters["scenes"] == 1, dict(watch.counters)
        assert {"jar", "bowl"} <= set(watch.seen)  # type: ignore[attr-defined]
        assert km.counters["queries"] == 1
    finally:
        km.stop()
        thread.join(timeout=5)
        km.close()  # type: ignore[attr-defined]

    moved = sys.modules["walk_wt3.agent"].moved
    here = ObjectInfo(name="jar", type="Jar", pose=Pose((0.5, 0.0, 0.9)), location="cabinet")
    assert not moved(
        here, ObjectInfo(name="jar", type="Jar", pose=Pose((0.505, 0.0, 0.9)), location="cabinet")
    )
    assert moved(here, ObjectInfo(name="jar", type="Jar", pose=Pose((0.52, 0.0, 0.9)), location="cabinet"))
    assert moved(here, ObjectInfo(name="jar", type="Jar", pose=Pose((0.5, 0.0, 0.9)), held_by="left_hand"))


def test_the_walkthrough_takes_the_next_free_numbers_of_what_it_grows(tmp_path: Path) -> None:
    """Grown by the walk-through, a specification's next free numbers are one past its own."""
    grown = walkthrough_spec(tmp_path / "spec.toml").read_text()
    assert f'id = "{NEXT.requirement}"' in grown and f'name = "{C}"' in grown
    after = free_numbers(grown)
    assert after == Numbers(
        f"R{int(NEXT.requirement[1:]) + 1}", NEXT.step + 1, NEXT.channel + 1, NEXT.km_group
    )
    moved = renumbered(snippet(1, numbers=AS_WRITTEN), Numbers("R7", 12, 11, "kx"))
    assert 'id = "R7"' in moved and 'requirements = ["R7"]' in moved and "\nnumber = 12\n" in moved
    assert '{ number = 11, ends = ["wt", "kx"]' in moved
    assert '{ number = 2, from = "hi", to = "ui" }' in moved  # the reallocations keep their numbers
