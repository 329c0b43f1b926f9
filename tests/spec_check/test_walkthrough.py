"""The walk-through of docs/spec.md ("adding an agent"), stage by stage: its TOML and Python
snippets are read from the document itself and added to a copy of the shipped specification
and to the agent ``roco spec new-agent`` writes, and the tools say what the document says
they say; at the end the new agent and a_hi run on one bus."""

from __future__ import annotations

import re
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from services.runtime.memory_transport import MemoryBus
from services.spec.check import check_report
from services.spec.model import DEFAULT_SPEC, load
from services.spec_check.code_check import verify_code_report
from services.spec_check.new_agent import write_agent
from shared.fipa_codec.languages.l_hc import CommandOutcome

DOC = Path(__file__).resolve().parents[2] / "docs" / "spec.md"
MODULE = "services.agents.logbook.agent"
HI = 'implementation = "services.agents.human_interface.agent:HumanInterface"'


def snippet(n: int, kind: str = "toml") -> str:
    m = re.search(rf"```{kind} walkthrough-{n}\n(.*?)```", DOC.read_text(), re.S)
    assert m, f"docs/spec.md lost walk-through snippet {n}"
    return m.group(1)


def stage(tmp_path: Path, *parts: str, edits: dict[str, str] | None = None) -> Path:
    text = DEFAULT_SPEC.read_text()
    for old, new in (edits or {}).items():
        assert text.count(old) == 1, old
        text = text.replace(old, new)
    path = tmp_path / "spec.toml"
    # requirements and steps before the agents, as in the shipped file
    head, tail = text.split("\n[[agents]]", 1)
    decomposition = "\n".join(p for p in parts if "[[steps]]" in p or "[[requirements]]" in p)
    rest = "\n".join(p for p in parts if p not in decomposition)
    path.write_text(head + "\n" + decomposition + "\n[[agents]]" + tail + "\n" + rest)
    return path


def logbook_stage(tmp_path: Path, package: str, *, hi: str | None = None) -> Path:
    """Stages 1 and 2, with the logbook written under ``tmp_path`` as ``package.agent``
    (a package of its own per test: a module is imported once per process)."""
    edits = {'group = "hi"': 'group = "ui"'}
    if hi is not None:
        edits[HI] = f'implementation = "{hi}"'
    return stage(tmp_path, snippet(1), snippet(2).replace(MODULE, f"{package}.agent"), edits=edits)


def test_stage_1_a_new_step_makes_check_list_what_is_missing(tmp_path: Path) -> None:
    ok, text = check_report(stage(tmp_path, snippet(1)))
    assert not ok
    for line in (
        "stop condition: group 'ui' of the final fringe is substituted by no agent",
        "stop condition: group 'lb' of the final fringe is substituted by no agent",
        "agent a_hi substitutes group 'hi', which is not in the final fringe",
        "channel C2 joins <group ui> and a_co by the decomposition, but a_co and a_hi in [[channels]]",
        "channel C7 joins <group ui> and a_km by the decomposition, but a_hi and a_km in [[channels]]",
        "channel C8 joins <group ui> and x_fipa by the decomposition, but x_fipa and a_hi in [[channels]]",
        "channel C9 of the decomposition is not specified in [[channels]]",
        "7 problem(s)",
    ):
        assert line in text, text


def test_stage_2_new_agent_writes_the_agent_and_verify_code_says_what_is_missing(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = logbook_stage(tmp_path, "walk_lb2")
    assert check_report(path)[0]

    def new_agent() -> subprocess.CompletedProcess[str]:
        command = ["spec", "new-agent", "a_lb", "--spec", str(path), "--root", str(tmp_path)]
        return subprocess.run(
            [sys.executable, "-m", "services.cli", *command], capture_output=True, text=True
        )

    done = new_agent()
    assert done.returncode == 0, done.stderr
    assert f"roco: wrote {tmp_path / 'walk_lb2' / 'agent.py'}" in done.stdout
    assert "roco: fill in _on_request; then: roco spec verify-code" in done.stdout
    again = new_agent()
    assert again.returncode == 1 and again.stderr.startswith("roco: ") and "exists" in again.stderr
    monkeypatch.syspath_prepend(str(tmp_path))
    ok, text = verify_code_report(path)
    assert not ok
    assert (
        "- agent a_hi declares no initiator role for fipa-request on C9, which [[channels]] C9 gives it "
        "(in L_HC)"
    ) in text
    assert (
        "- agent a_lb has a handler not written yet: _on_request raises NotImplementedError (agent.py:"
        in text
    )
    assert "2 problem(s)" in text


def finished_logbook(tmp_path: Path, package: str) -> Path:
    path = logbook_stage(tmp_path, package, hi="tests.spec_check.walkthrough.hi_logbook:HumanInterface")
    module = write_agent(load(path), "a_lb", tmp_path).module
    text = module.read_text()
    written = re.search(
        r'    @handles\("fipa-request", PARTICIPANT, "request"\)\n.*?raise NotImplementedError\(.*?\)\n',
        text,
        re.S,
    )
    assert written, text
    text = text.replace(written.group(0), snippet(3, "python"))
    imports = "from shared.fipa_codec import Performative"
    text = text.replace(imports, f"from shared.fipa_codec.languages.l_hc import CommandOutcome\n{imports}")
    module.write_text(text)
    return path


def test_stage_3_the_finished_agent_conforms_and_a_hi_records_through_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = finished_logbook(tmp_path, "walk_lb3")
    monkeypatch.syspath_prepend(str(tmp_path))
    ok, text = verify_code_report(path)
    assert ok, text
    assert "a_lb: 2 files; 1 protocol roles agree with the specification:" in text
    assert "  C9 fipa-request participant with a_hi in L_HC: receives cancel, request" in text

    # both ends of C9 on one bus, started from the staged specification
    from services.runtime.main import agent_class

    spec = load(path)
    bus = MemoryBus()
    logbook = agent_class(spec, "a_lb")(bus.transport(), spec)
    hi = agent_class(spec, "a_hi")(bus.transport(), spec)
    for agent in (logbook, hi):
        agent.bind()
    thread = threading.Thread(target=logbook.run, daemon=True)
    thread.start()
    try:
        conv = hi.record(
            CommandOutcome(command_id="cmd-1", succeeded=True, detail="the bowl holds the content")
        )
        hi._dispatch()
        for _ in range(200):  # each acquire blocks until input arrives or 0.05 s pass
            hi._acquire(0.05)
            hi.handle_received()
            if hi.counters["logbook.recorded"]:
                break
        assert hi.counters["logbook.recorded"] == 1
        assert conv.finished and conv.content == CommandOutcome(
            command_id="cmd-1", succeeded=True, detail="the bowl holds the content"
        )
        assert logbook.counters["recorded"] == 1
    finally:
        logbook.stop()
        thread.join(timeout=5)
