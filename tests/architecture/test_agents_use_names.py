"""Every agent names what the specification names by the names generated from it: its
channels, protocols and content languages by services/spec/names.py (``participant(C5,
FIPA_REQUEST, L_EX, L_SD)``), its performatives by ``Performative`` (``@handles(FIPA_REQUEST,
PARTICIPANT, Performative.REQUEST)``), its roles by ``INITIATOR``/``PARTICIPANT``; and it
writes each behaviour's name once (``FSM([Behaviour("idle", …), …])``, not a dict of states).

The agents' code is read (Python's ``ast``; nothing is run): no string literal is passed to
``participant``/``initiator``, ``@handles``/``@on_deadline`` or the roles' ``open``,
``restore``, ``conversations`` and ``role`` where a channel, protocol, language, role or
performative goes, no module keeps a constant of its own for such a name (``C2 = "C2"``,
``QUERY = "fipa-query"``), and no ``FSM(...)`` is given a dict. A failure names each place as
``file:line``. (Tests' own agents, on specifications of their own, may pass plain strings:
the runtime takes both.)"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from services.spec.model import default_spec
from services.spec.render_names import spellings
from services.spec_check.code_check import package_files

ROOT = Path(__file__).resolve().parents[2]

ROLE_MAKERS = ("channel", "protocol", "language")
"""What ``participant(...)``/``initiator(...)`` take, by position (languages repeat)."""
HANDLER_MARKS = {
    "handles": ("protocol", "role", "performative"),
    "on_deadline": ("protocol", "role"),
}
"""What each decorator takes, by position (the last repeats)."""
ROLES_METHODS = ("open", "restore", "conversations", "role")
"""Methods of the agent's roles that take (channel, protocol, …) first."""
SPELLINGS = frozenset(spellings(default_spec()).values())
"""The shipped specification's channels, protocols and languages as it spells them."""


def _name(func: ast.expr) -> str:
    return func.id if isinstance(func, ast.Name) else func.attr if isinstance(func, ast.Attribute) else ""


def _on_roles(func: ast.expr) -> bool:
    """``func`` is ``<something>.roles.<method>``."""
    return (
        isinstance(func, ast.Attribute)
        and func.attr in ROLES_METHODS
        and isinstance(func.value, ast.Attribute)
        and func.value.attr == "roles"
    )


def _string(node: ast.AST) -> str | None:
    return node.value if isinstance(node, ast.Constant) and isinstance(node.value, str) else None


def _positions(call: ast.Call) -> tuple[str, ...] | None:
    """What the positional arguments of ``call`` are, when it is a call this check reads."""
    name = _name(call.func)
    if _on_roles(call.func):
        return ("channel", "protocol")
    if name in ("participant", "initiator"):
        return ROLE_MAKERS
    return HANDLER_MARKS.get(name)


def strings_in(path: Path) -> list[str]:
    """Where module ``path`` writes a name of the specification or a performative as a string,
    or builds an FSM from a dict: ``file:line: what``, one per place."""
    tree = ast.parse(path.read_text(), str(path))
    shown = path.relative_to(ROOT) if path.is_relative_to(ROOT) else path
    out: list[tuple[int, int, str]] = []
    for node in ast.walk(tree):
        kept = _string(node.value) if isinstance(node, ast.Assign | ast.AnnAssign) and node.value else None
        if kept in SPELLINGS:
            text = f"keeps {kept!r} in a constant of its own: import it from services.spec.names"
            out.append((node.lineno, node.col_offset, f"{shown}:{node.lineno}: {text}"))
        if not isinstance(node, ast.Call):
            continue
        where = f"{shown}:{node.lineno}"
        place = (node.lineno, node.col_offset)
        func = ast.unparse(node.func)
        if _name(node.func) == "FSM":
            given = [*node.args, *(k.value for k in node.keywords)]
            if any(isinstance(a, ast.Dict | ast.DictComp) for a in given):
                out.append(
                    (*place, f"{where}: {func}(...) gets a dict of states: pass the behaviours, FSM([...])")
                )
            continue
        positions = _positions(node)
        if positions is None:
            continue
        for i, arg in enumerate(node.args):
            what = positions[min(i, len(positions) - 1)]
            if i >= len(positions) and what == "protocol":  # the roles' methods: content and more
                break
            text = _string(arg)
            if text is not None:
                out.append((*place, f"{where}: {func}(...) gets the {what} {text!r} as a string"))
        for keyword in node.keywords:
            text = _string(keyword.value)
            if keyword.arg in ("channel", "performative") and text is not None:
                out.append((*place, f"{where}: {func}(...) gets the {keyword.arg} {text!r} as a string"))
    return [text for *_, text in sorted(out, key=lambda found: found[:2])]


def agent_files() -> list[Path]:
    """Every module of every agent of the shipped specification (its implementation's package)."""
    files: list[Path] = []
    for agent in default_spec().agents:
        files += [f for f in package_files(agent.implementation) if f not in files]
    return files


def test_every_agent_is_read() -> None:
    names = {f.relative_to(ROOT).as_posix() for f in agent_files()}
    for folder in ("coordinator", "human_interface", "knowledge", "planner", "task_executor", "executor"):
        assert f"services/agents/{folder}/agent.py" in names


@pytest.mark.parametrize("path", agent_files(), ids=lambda p: p.relative_to(ROOT).as_posix())
def test_no_agent_writes_a_specification_name_or_performative_as_a_string(path: Path) -> None:
    assert strings_in(path) == []


BAD = """
from services.runtime.behaviour import FSM, Behaviour
from services.runtime.roles import PARTICIPANT, handles, initiator, on_deadline, participant
from shared.fipa_codec import Performative

C2 = "C2"
QUERY: str = "fipa-query"
ROLES = (participant("C5", FIPA_REQUEST, L_EX, "L_SD"), initiator(C3, "fipa-request", L_HFSM))


class A:
    @handles(FIPA_REQUEST, PARTICIPANT, Performative.REQUEST, "cancel", channel="C8")
    def h(self, conv): ...

    @on_deadline("coordinate", "participant")
    def d(self, conv): ...

    def build_fsm(self):
        self.roles.open("C3", FIPA_REQUEST, content, performative="request", data="a string is fine here")
        self.roles.restore(C1, COORDINATE, "running", kept=b"")
        return FSM(initial="a", states={"a": Behaviour("a", self.h, terminal=lambda: True)})
"""


def test_the_check_names_every_kind_of_string_and_a_dict_of_states(tmp_path: Path) -> None:
    """The check can fail: each planted string is named, with its line; nothing else is."""
    path = tmp_path / "bad.py"
    path.write_text(BAD)
    found = strings_in(path)
    assert found == [
        f"{path}:6: keeps 'C2' in a constant of its own: import it from services.spec.names",
        f"{path}:7: keeps 'fipa-query' in a constant of its own: import it from services.spec.names",
        f"{path}:8: participant(...) gets the channel 'C5' as a string",
        f"{path}:8: participant(...) gets the language 'L_SD' as a string",
        f"{path}:8: initiator(...) gets the protocol 'fipa-request' as a string",
        f"{path}:12: handles(...) gets the performative 'cancel' as a string",
        f"{path}:12: handles(...) gets the channel 'C8' as a string",
        f"{path}:15: on_deadline(...) gets the protocol 'coordinate' as a string",
        f"{path}:15: on_deadline(...) gets the role 'participant' as a string",
        f"{path}:19: self.roles.open(...) gets the channel 'C3' as a string",
        f"{path}:19: self.roles.open(...) gets the performative 'request' as a string",
        f"{path}:21: FSM(...) gets a dict of states: pass the behaviours, FSM([...])",
    ], found
