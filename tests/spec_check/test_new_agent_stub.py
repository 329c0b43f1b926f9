"""The module ``roco spec new-agent`` writes (services/spec_check/new_agent.py), for every agent
of the shipped specification and for the two agents of tests/support/role_agents.py, which
play both roles of every protocol roco knows on one channel: it imports; its handlers are
distinct methods and exactly what its roles need, each not written yet; every call its comments
hint at is a method of the roles' API, and every performative they name is one its role may
send; with the handlers written (here: ``return``) the agent starts; ruff finds nothing in it.
A stub names its channels, protocols and languages by services/spec/names.py; for the test
specification, whose protocols the shipped one lacks, that module is rendered from it
(tests/support/spec_names.py), as ``roco spec new-agent`` renders it where it writes."""

from __future__ import annotations

import importlib
import importlib.util
import re
import shutil
import subprocess
import sys
from pathlib import Path

import msgspec
import pytest

from services.runtime.memory_transport import MemoryBus
from services.runtime.roles import (
    INITIATOR,
    Conversation,
    Roles,
    agent_problems,
    handlers_of,
    incoming,
    optional,
    outgoing,
    spec_roles,
)
from services.spec.model import SystemSpec, default_spec
from services.spec.protocol_defs import machine_of
from services.spec.render_names import spellings
from services.spec_check.new_agent import TIMER_METHOD, agent_source
from shared.fipa_codec import Performative
from tests.support.role_agents import SPEC as EVERY_PROTOCOL
from tests.support.spec_names import use_names

ROOT = Path(__file__).resolve().parents[2]
SHIPPED = default_spec()
CASES = [(SHIPPED, a) for a in SHIPPED.agent_names] + [(EVERY_PROTOCOL, "a_i"), (EVERY_PROTOCOL, "a_p")]
_n = iter(range(1_000_000))


def write_stub(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, spec: SystemSpec, agent: str
) -> tuple[str, type]:
    """Write agent ``agent``'s stub as a module of a package of its own; its text and class."""
    package = f"stub_{agent}_{next(_n)}"
    (tmp_path / package).mkdir()
    (tmp_path / package / "__init__.py").write_text("")
    text, _ = agent_source(spec, agent, "Stub", f"{package}/agent.py")
    (tmp_path / package / "agent.py").write_text(text)
    monkeypatch.syspath_prepend(str(tmp_path))
    use_names(spec, monkeypatch)
    return text, importlib.import_module(f"{package}.agent").Stub


def hint_blocks(text: str) -> dict[str, str]:
    """Method name → the comment lines in it (the hints), joined."""
    out: dict[str, str] = {}
    for m in re.finditer(r"    def (\w+)\(self.*?\n((?:        .*\n|\n)*)", text):
        comments = [line.strip()[2:] for line in m.group(2).splitlines() if line.strip().startswith("# ")]
        out[m.group(1)] = " ".join(comments)
    return out


@pytest.mark.parametrize(("spec", "agent"), CASES, ids=[f"{s.system}-{a}" for s, a in CASES])
def test_the_stub_imports_and_has_exactly_the_handlers_its_roles_need(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, spec: SystemSpec, agent: str
) -> None:
    _, cls = write_stub(tmp_path, monkeypatch, spec, agent)
    handlers = handlers_of(cls)
    needed = sum(
        len(incoming(m, d.role) - optional(m, d.role))
        for d in spec_roles(spec, agent)
        for m in [machine_of(spec, d.protocol)]
    )
    assert len(handlers) == len(set(handlers.values())) == needed  # one method each, none overwritten
    problems = agent_problems(spec, agent, cls)
    assert len(problems) == needed
    assert all("has a handler not written yet" in p for p in problems), problems
    assert (TIMER_METHOD in vars(cls)) is any(d.role == INITIATOR for d in spec_roles(spec, agent))


@pytest.mark.parametrize(("spec", "agent"), CASES, ids=[f"{s.system}-{a}" for s, a in CASES])
def test_every_hint_names_a_call_of_the_roles_api_and_a_performative_the_role_may_send(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, spec: SystemSpec, agent: str
) -> None:
    text, cls = write_stub(tmp_path, monkeypatch, spec, agent)
    keys = {name: key for key, name in handlers_of(cls).items()}
    blocks = hint_blocks(text)
    for method, hints in blocks.items():
        if not hints:
            continue
        for name in re.findall(r"\bconv\.(\w+)", hints):
            assert hasattr(Conversation, name), (method, name)
        for name in re.findall(r"\bself\.roles\.(\w+)", hints):
            assert hasattr(Roles, name), (method, name)
        named = [Performative[p] for p in re.findall(r"\bPerformative\.(\w+)", hints)]
        if method in keys:  # a handler: what its role may send in that protocol
            key = keys[method]
            assert set(named) <= outgoing(machine_of(spec, key.protocol), key.role), (method, named)
            assert "Performative.CANCEL" not in hints  # the initiator cancels with conv.cancel()
        else:  # the periodic opening: each open names a role of the agent and its opening
            assert method == TIMER_METHOD
            opens = re.findall(r"self\.roles\.open\((\w+), (\w+), [^)]*?(?:Performative\.(\w+))?\)", hints)
            spelt = spellings(spec)  # the names of services/spec/names.py → the specification's
            initiators = {(d.channel, d.protocol) for d in spec_roles(spec, agent) if d.role == INITIATOR}
            assert {(spelt[c], spelt[p]) for c, p, _ in opens} == initiators
            for _, protocol, perf in opens:
                machine = machine_of(spec, spelt[protocol])
                if perf:
                    assert machine.next_state(machine.initial, INITIATOR, Performative[perf]) is not None
    assert set(keys) <= set(blocks)


def test_the_hints_say_how_each_protocol_is_answered(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    text, cls = write_stub(tmp_path, monkeypatch, EVERY_PROTOCOL, "a_p")
    hints = hint_blocks(text)
    by_key = {
        (k.protocol, k.performative.value if k.performative else ""): n for k, n in handlers_of(cls).items()
    }
    query = hints[by_key[("fipa-query", "query-ref")]]
    assert (
        "conv.reply(Performative.INFORM_REF)" in query
        and "conv.refuse_with(Performative.REFUSE, reason)" in query
    )
    assert "After conv.reply(Performative.AGREE), later (keep conv):" in query
    request = hints[by_key[("fipa-request", "request")]]
    assert (
        "conv.reply(Performative.INFORM)" in request
        and "conv.refuse_with(Performative.FAILURE, reason)" in request
    )
    assert (
        "Answer with conv.reply(Performative.AGREE); or conv.refuse_with(Performative.REFUSE, reason)"
        in (hints[by_key[("fipa-subscribe", "subscribe")]])
    )
    assert "conv.reply(Performative.PROPOSE)" in hints[by_key[("fipa-contract-net", "cfp")]]
    assert "conv.reply(Performative.INFORM)" in hints[by_key[("coordinate", "confirm")]]

    text, cls = write_stub(tmp_path, monkeypatch, EVERY_PROTOCOL, "a_i")
    hints = hint_blocks(text)
    by_key = {
        (k.protocol, k.performative.value if k.performative else ""): n for k, n in handlers_of(cls).items()
    }
    assert "May send: conv.cancel()" in hints[by_key[("fipa-subscribe", "inform")]]
    assert (
        "May send: conv.reply(Performative.CONFIRM); or conv.cancel()"
        in hints[by_key[("coordinate", "inform")]]
    )
    assert "conv.reply(Performative.ACCEPT_PROPOSAL)" in hints[by_key[("fipa-contract-net", "propose")]]
    assert "conv.timed_out" in hints[by_key[("fipa-request", "failure")]]
    assert "It ends the conversation" in hints[by_key[("fipa-query", "inform-ref")]]
    opening = hints[TIMER_METHOD]
    assert "self.roles.open(C1, FIPA_QUERY, content, performative=Performative.QUERY_IF)" in opening
    assert "self.roles.open(C1, FIPA_CONTRACT_NET, content)" in opening


def test_with_its_handlers_written_the_stub_starts(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    for agent in ("a_i", "a_p"):
        text, _ = agent_source(EVERY_PROTOCOL, agent, "Stub", "x.py")
        written = re.sub(r"raise NotImplementedError\(\n.*?\n.*?\n        \)", "return", text)
        assert "raise NotImplementedError" not in written
        package = f"written_{agent}"
        (tmp_path / package).mkdir()
        (tmp_path / package / "__init__.py").write_text("")
        (tmp_path / package / "agent.py").write_text(written)
        monkeypatch.syspath_prepend(str(tmp_path))
        use_names(EVERY_PROTOCOL, monkeypatch)
        cls = importlib.import_module(f"{package}.agent").Stub
        assert agent_problems(EVERY_PROTOCOL, agent, cls) == []
        started = cls(MemoryBus().transport(), EVERY_PROTOCOL)
        assert len(started.roles.declared) == len(spec_roles(EVERY_PROTOCOL, agent))


def test_ruff_finds_nothing_in_a_stub(tmp_path: Path) -> None:
    ruff = shutil.which("ruff", path=str(Path(sys.executable).parent)) or shutil.which("ruff")
    if ruff is None:
        pytest.skip("ruff is not installed (pip install -e '.[dev]')")
    for n, (spec, agent) in enumerate(CASES):
        (tmp_path / f"stub_{n}.py").write_text(agent_source(spec, agent, "Stub", "x.py")[0])
    done = subprocess.run(
        [ruff, "check", "--no-cache", "--config", str(ROOT / "pyproject.toml"), str(tmp_path)],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stdout + done.stderr


def test_a_long_job_wraps_and_the_written_module_passes_ruff_and_mypy(tmp_path: Path) -> None:
    """The job is the module docstring's first line; at 200 characters (with quotes and a
    backslash, as a person may write) it wraps, and ruff and mypy accept what ``roco spec
    new-agent`` wrote."""
    bin_dir = str(Path(sys.executable).parent)
    ruff, mypy = (shutil.which(t, path=bin_dir) or shutil.which(t) for t in ("ruff", "mypy"))
    if ruff is None or mypy is None:
        pytest.skip("ruff and mypy are not installed (pip install -e '.[dev]')")
    job = ('plans """what to do""" \\ next: ' + "turns a ground task network into a plan, " * 5)[:200].strip()
    assert len(job) == 200
    agents = tuple(msgspec.structs.replace(a, job=job) if a.name == "a_pl" else a for a in SHIPPED.agents)
    module = tmp_path / "stub_long_job.py"
    module.write_text(
        agent_source(msgspec.structs.replace(SHIPPED, agents=agents), "a_pl", "Stub", "x.py")[0]
    )
    config = str(ROOT / "pyproject.toml")
    for command in (
        [ruff, "check", "--no-cache", "--config", config, str(module)],
        [mypy, "--config-file", config, str(module)],
    ):
        done = subprocess.run(command, capture_output=True, text=True, cwd=ROOT)
        assert done.returncode == 0, f"{Path(command[0]).name}: {done.stdout}{done.stderr}"
    # the docstring says the job as written
    module_doc = importlib.util.spec_from_file_location("stub_long_job", module)
    assert module_doc is not None and module_doc.loader is not None
    loaded = importlib.util.module_from_spec(module_doc)
    module_doc.loader.exec_module(loaded)
    assert " ".join((loaded.__doc__ or "").split("\n\n")[0].split()) == f"a_pl — {job}."
