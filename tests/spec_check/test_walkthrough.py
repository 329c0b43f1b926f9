"""The walk-through of docs/spec.md ("adding an agent"), stage by stage: its TOML and Python
snippets are read from the document itself and added to a copy of the shipped specification,
to the agent's folder (its terms module) and to the agent ``roco spec new-agent`` writes, and
the tools say what the document says they say; a_km and a_hi serve the new channels with no
edit of their code (a_hi: the new protocol is a notice protocol by its state machine); at the
end the new agent and a_km run on one bus and the watcher's warning, a term of its own that
says itself, goes to a_hi. The snippets' requirement, step and
channel are numbered the next free ones of the shipped specification (R4, 10 and C10 as the
document writes them, until the specification grows; walkthrough.NEXT). The agent names its
channel by services/spec/names.py, which new-agent renders again where it writes; in this process the
module rendered from the staged specification stands in for it (tests/support/spec_names.py)."""

from __future__ import annotations

import os
import queue
import shutil
import subprocess
import sys
import threading
import tomllib
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from services.deploy.compose import check, read
from services.runtime import keys
from services.runtime.memory_transport import MemoryBus
from services.spec.check import check_report
from services.spec.model import DEFAULT_SPEC, load
from services.spec.render_names import NAMES_FILE, render
from services.spec_check.code_check import verify_code_report
from services.spec_check.new_agent import write_agent
from shared.fipa_codec import Communicate, Performative, decode
from shared.fipa_codec.languages import decode_content
from shared.fipa_codec.languages.told import told
from tests.agents.knowledge.test_agent import Peer
from tests.agents.knowledge.test_scene_subscription import ON_ITS_SIDE, at, seen, settled
from tests.spec_check.walkthrough import (
    AS_WRITTEN,
    NEXT,
    ROOT,
    TERMS_PACKAGE,
    Numbers,
    entries,
    fill,
    free_numbers,
    group_edit,
    renumbered,
    shared_terms,
    snippet,
    staged,
    walkthrough_spec,
)
from tests.support.codec_registry import languages_restored
from tests.support.spec_names import use_names

HANDLERS = ("_on_failure", "_on_inform", "_on_refuse")
C = NEXT.channel_name
"""The walk-through's channel to a_km: C10 in the shipped specification."""
N = NEXT.notice_channel_name
"""The walk-through's channel to a_hi: C11 in the shipped specification."""


@pytest.fixture(autouse=True)
def _terms_leave_with_the_test() -> Iterator[None]:
    """Each test's watcher registers its own ``Tipped`` (a package of its own per test): the
    codec's registry is put back after it."""
    with languages_restored():
        yield


def stage(tmp_path: Path, *parts: str, edit: Callable[[str], str] | None = None) -> Path:
    path = tmp_path / "spec.toml"
    path.write_text(staged(DEFAULT_SPEC.read_text(), *parts, edit=edit))
    return path


def watch_stage(tmp_path: Path, package: str, monkeypatch: pytest.MonkeyPatch) -> Path:
    """Stages 1 and 2, with the watcher's agent module under ``tmp_path`` as ``package.agent``
    (a package of its own per test: a module is imported once per process; ``tmp_path`` on the
    import path) and its terms module the process's (walkthrough.shared_terms)."""
    monkeypatch.syspath_prepend(str(tmp_path))
    return stage(tmp_path, snippet(1), entries(agent=f"{package}.agent"), edit=group_edit)


@pytest.mark.walkthrough
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
        "channel C9 joins <group ui> and x_ros2 by the decomposition, but x_ros2 and a_hi in [[channels]]",
        f"channel {C} of the decomposition is not specified in [[channels]]",
        f"channel {N} of the decomposition is not specified in [[channels]]",
        # two groups without an agent, a_hi's old group, each channel of a_hi's (four in the
        # shipped specification, more where it has grown) and the two new channels
        f"{5 + len(NEXT.hi_channels)} problem(s)",
    ):
        assert line in text, text


@pytest.mark.walkthrough
def test_stage_2_new_agent_writes_the_agent_and_its_service_and_verify_code_lists_its_handlers(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = watch_stage(tmp_path, "walk_wt2", monkeypatch)
    assert check_report(path)[0]
    compose = tmp_path / "deploy" / "compose.yaml"
    compose.parent.mkdir()
    shutil.copy(ROOT / "deploy" / "compose.yaml", compose)
    names = tmp_path / "services" / "spec" / "names.py"
    names.parent.mkdir(parents=True)
    shutil.copy(NAMES_FILE, names)

    def new_agent() -> subprocess.CompletedProcess[str]:
        command = ["spec", "new-agent", "a_wt", "--spec", str(path), "--root", str(tmp_path)]
        env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), str(shared_terms())])}
        return subprocess.run(
            [sys.executable, "-m", "services.cli", *command],
            capture_output=True,
            text=True,
            cwd=ROOT,
            env=env,
        )

    done = new_agent()
    assert done.returncode == 0, done.stderr
    assert f"roco: wrote {tmp_path / 'walk_wt2' / 'agent.py'}" in done.stdout
    channels = ", ".join(c.name for c in load(path).channels)
    assert f"roco: wrote {names}: the names of channels {channels}" in done.stdout and channels.endswith(
        f"{C}, {N}"
    )
    assert f"roco: wrote {compose}: one service per agent (" in done.stdout
    assert (
        f"roco: fill in {', '.join(HANDLERS)} and what _periodically opens; then: roco spec verify-code"
        in done.stdout
    )
    # the names module now names the new channel, and the compose file runs the new agent too,
    # as the specification gives them
    assert names.read_text() == render(load(path)) and f"\n{N} = Channel.{N}\n" in names.read_text()
    written = (tmp_path / "walk_wt2" / "agent.py").read_text()
    assert (
        f"initiator({C}, FIPA_SUBSCRIBE, L_WM)" in written
        and f"initiator({N}, KITCHEN_WARNING, L_HC)" in written
    )
    assert f"self.roles.open({N}, KITCHEN_WARNING, Tipped(…))" in written
    assert check(compose, load(path)) is None
    assert '    command: ["python", "-m", "services.runtime.main", "a_wt"]' in read(compose)
    again = new_agent()
    last = again.stderr.splitlines()[-1]
    assert (
        again.returncode == 1
        and last.startswith("roco: ")
        and last.endswith("new-agent writes only new files")
    )

    use_names(load(path), monkeypatch)
    ok, text = verify_code_report(path)
    assert not ok
    for handler in HANDLERS:
        assert f"- agent a_wt has a handler not written yet: {handler} raises NotImplementedError" in text
    assert "3 problem(s)" in text
    # the other ends of the new channels are served by a_km's and a_hi's code as it is: a role
    # for every channel
    assert "agent a_km" not in text and "agent a_hi" not in text
    assert (
        f"  {C} fipa-subscribe participant with a_wt in L_WM (declared for every channel): receives "
        "cancel, subscribe; sends agree, failure, inform, refuse"
    ) in text
    assert (
        f"  {N} kitchen-warning participant with a_wt in L_HC (declared for every channel): receives "
        "inform; sends nothing"
    ) in text


def finished_watch(tmp_path: Path, package: str, monkeypatch: pytest.MonkeyPatch) -> Path:
    path = watch_stage(tmp_path, package, monkeypatch)
    module = write_agent(load(path), "a_wt", tmp_path).module
    fill(module)
    return path


@pytest.mark.walkthrough
def test_stage_3_the_finished_agent_conforms_and_warns_the_person_of_a_tipped_bowl(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = finished_watch(tmp_path, "walk_wt3", monkeypatch)
    use_names(load(path), monkeypatch)
    ok, text = verify_code_report(path)
    assert ok, text
    # its folder: agent.py and __init__.py (its terms module is the process's: shared_terms)
    assert "a_wt: 2 files; 2 protocol roles agree with the specification:" in text
    assert (
        f"initiator({C}, FIPA_SUBSCRIBE, L_WM, reply_by_s=2.0, resubscribes=True)"
        in (tmp_path / "walk_wt3" / "agent.py").read_text()
    )
    assert (
        f"  {C} fipa-subscribe initiator with a_km in L_WM: receives agree, failure, inform, refuse; "
        "sends cancel, subscribe"
    ) in text
    assert f"  {N} kitchen-warning initiator with a_hi in L_HC: receives nothing; sends inform" in text
    assert f"  {N} kitchen-warning participant with a_wt in L_HC (declared for every channel)" in text

    # a_km and the watcher on one bus, started from the staged specification (a_km keeps its
    # knowledge in memory); the test plays a_ta and reads what the watcher tells a_hi
    for name in ("ROCO_KM_STORE", "ROCO_RUN_DIR", "ROCO_STATE_DIR"):
        monkeypatch.delenv(name, raising=False)
    from services.runtime.main import agent_class

    spec = load(path)
    bus = MemoryBus()
    warned: queue.SimpleQueue[Communicate] = queue.SimpleQueue()
    bus.subscribe(keys.fipa_key(N, "a_wt", "a_hi"), lambda _k, p: warned.put(decode(p)))
    km = agent_class(spec, "a_km")(bus.transport(), spec)
    watch = agent_class(spec, "a_wt")(bus.transport(), spec)
    for agent in (km, watch):
        agent.engine.bind()
    thread = threading.Thread(target=km.engine.run, daemon=True)
    thread.start()

    def until(counter: str) -> None:
        for _ in range(400):  # each acquire blocks until input arrives or 0.05 s pass
            watch.engine.acquire(0.05)
            watch.handle_received()
            watch.engine.dispatch()  # what the agent's loop publishes after each step
            if watch.counters[counter]:
                break
        assert watch.counters[counter] == 1, dict(watch.counters)

    try:
        peer = Peer(bus)
        peer.update(seen(1.0, at("bowl", 0.5), at("jar", 0.8), at("cup", 0.3)))
        settled(peer)
        watch.setup()  # its role subscribes once a_km's token is seen
        until("subscribed")
        # the jar moved 10 cm: logged, nobody told; the bowl knocked onto its side: the person told
        peer.update(seen(2.0, at("jar", 0.9)))
        peer.update(seen(3.0, at("bowl", 0.5, ON_ITS_SIDE)))
        until("warnings")
        notice = warned.get(timeout=5)
        assert notice.performative is Performative.INFORM and notice.protocol == "kitchen-warning"
        warning = decode_content(notice.language or "", notice.content)
        assert type(warning).__module__ == f"{TERMS_PACKAGE}.terms" and type(warning).__name__ == "Tipped"
        assert told(warning) == "the bowl has tipped over"  # what a_hi tells the person
        assert watch.counters["changes"] == 2 and warned.empty()
    finally:
        km.engine.stop()
        thread.join(timeout=5)
        km.close()  # type: ignore[attr-defined]


@pytest.mark.walkthrough
def test_the_walkthrough_takes_the_next_free_numbers_of_what_it_grows(tmp_path: Path) -> None:
    """Grown by the walk-through, a specification's next free numbers are one past its own."""
    grown = walkthrough_spec(tmp_path / "spec.toml").read_text()
    assert f'id = "{NEXT.requirement}"' in grown and f'name = "{C}"' in grown and f'name = "{N}"' in grown
    after = free_numbers(grown)
    assert after == Numbers(
        f"R{int(NEXT.requirement[1:]) + 1}",
        NEXT.step + 1,
        NEXT.channel + 2,
        NEXT.km_group,
        "ui",  # a_hi's group after the split, with the watcher's channel to it besides its own
        tuple(sorted((*NEXT.hi_channels, NEXT.channel + 1))),
    )
    moved = renumbered(snippet(1, numbers=AS_WRITTEN), Numbers("R7", 12, 11, "kx"))
    assert 'id = "R7"' in moved and 'requirements = ["R7"]' in moved and "\nnumber = 12\n" in moved
    assert "{ number = 11, ends" in moved and "{ number = 12, ends" in moved
    assert '{ number = 11, ends = ["wt", "kx"]' in moved
    assert '{ number = 2, from = "hi", to = "ui" }' in moved  # the reallocations keep their numbers
    # a specification whose a_hi substitutes another group, with other channels: the split and
    # its reallocations follow it
    regrown = renumbered(snippet(1, numbers=AS_WRITTEN), Numbers("R7", 12, 11, "kx", "hx", (3, 5)))
    assert 'split = "hx"' in regrown and 'split = "hi"' not in regrown
    assert regrown.count("from =") == 2 and '{ number = 3, from = "hx", to = "ui" }' in regrown
    assert '{ number = 5, from = "hx", to = "ui" }' in regrown


@pytest.mark.walkthrough
def test_stage_2_s_edits_find_the_entries_through_the_data_wherever_the_file_has_them() -> None:
    """a_hi's ``group`` line is changed in its own ``[[agents]]`` table only (another agent's
    ``group = "hi"`` is left), and the watcher is started right after a_hi whatever the order
    holds (an agent added after a_hi, the list on several lines)."""
    text = DEFAULT_SPEC.read_text()
    grown = text.replace(
        'start_order = ["a_km", "a_pl", "a_co", "ag_ex", "a_ta", "a_hi"]',
        'start_order = [\n  "a_km", "a_pl", "a_co", "ag_ex", "a_ta", "a_hi", "a_sc",\n]',
    )
    first = grown.index("\n[[agents]]\n")  # another agent of group "hi" before a_hi's table
    zz = '\n[[agents]]\nname = "a_zz"\ngroup = "hi"\nimplementation = "x:Y"\njob = "x"\n'
    grown = grown[:first] + zz + grown[first:]
    edited = group_edit(grown)
    data = tomllib.loads(edited)
    assert data["start_order"] == ["a_km", "a_pl", "a_co", "ag_ex", "a_ta", "a_hi", "a_wt", "a_sc"]
    groups = {a["name"]: a["group"] for a in data["agents"]}
    assert groups["a_hi"] == "ui" and groups["a_zz"] == "hi"
    assert {k: v for k, v in groups.items() if k != "a_hi"} == {
        a["name"]: a["group"] for a in tomllib.loads(grown)["agents"] if a["name"] != "a_hi"
    }
