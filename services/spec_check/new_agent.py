"""``roco spec new-agent NAME``: the folder of an agent a decomposition step introduced, written
from the specification (issue 17; paper §4 step 4: an agent's interface follows from its
channels).

The agent's ``[[agents]]`` entry names its implementation (``services.agents.logbook.agent:Logbook``):
the command writes that module, with ``__init__.py`` in every folder on the way, under a root
folder (the project by default). The module holds

- the agent class with its ``ROLES``: one per (channel, protocol) the specification gives it,
  initiator or participant, with the channel's content languages
  (:func:`services.runtime.roles.spec_roles`);
- one handler per performative the other role may send by the protocol's state machine
  (what :func:`services.runtime.roles.role_problems` requires), each raising
  NotImplementedError with a line saying what to decide, until written; ``roco spec
  verify-code`` lists the handlers not yet written;
- an FSM of one behaviour that routes the input buffer to the handlers.

It refuses to overwrite an existing file (FileExistsError).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from services.runtime.roles import RoleDecl, incoming, optional, spec_roles
from services.spec.model import SpecError, SystemSpec
from services.spec.protocol_defs import machine_of

PROJECT = Path(__file__).resolve().parents[2]
"""The project's root folder (where ``services/`` is)."""


@dataclass(frozen=True)
class Scaffold:
    """What :func:`write_agent` wrote: the module's path and the handlers to fill in."""

    module: Path
    handlers: tuple[str, ...]


def _peer(spec: SystemSpec, agent: str, channel: str) -> str:
    for ch in spec.channels:
        if ch.name == channel:
            return ch.ends[1] if ch.ends[0] == agent else ch.ends[0]
    raise SpecError(f"no channel {channel}")


def _constant(name: str) -> str:
    return name.upper().replace("-", "_")


def _method(decl: RoleDecl, performative: str, many: bool) -> str:
    where = f"{decl.channel.lower()}_" if many else ""
    return f"_on_{where}{performative.replace('-', '_')}"


def agent_source(spec: SystemSpec, agent: str, class_name: str, where: str) -> tuple[str, tuple[str, ...]]:
    """The module text of agent ``agent`` (class ``class_name``, written to ``where``) and
    the names of its handlers. Raises SpecError when the spec gives the agent no channel."""
    entry = next(a for a in spec.agents if a.name == agent)
    roles = spec_roles(spec, agent)
    if not roles:
        raise SpecError(f"agent {agent} ends no channel in the specification: it would have nothing to do")
    perfs: dict[str, int] = {}
    for decl in roles:
        machine = machine_of(spec, decl.protocol)
        for p in incoming(machine, decl.role) - optional(machine, decl.role):
            key = f"{decl.role}/{decl.protocol}/{p.value}"
            perfs[key] = perfs.get(key, 0) + 1
    declared = []
    for decl in roles:
        langs = ", ".join(f'"{lang}"' for lang in decl.languages)
        declared.append(f'        {decl.role}("{decl.channel}", "{decl.protocol}", {langs}),')
    handlers: list[str] = []
    blocks: list[str] = []
    for decl in roles:
        machine = machine_of(spec, decl.protocol)
        peer = _peer(spec, agent, decl.channel)
        needed = sorted(p.value for p in incoming(machine, decl.role) - optional(machine, decl.role))
        if decl.role == "initiator":
            opening = f'self.roles.open("{decl.channel}", "{decl.protocol}", content)'
            blocks.append(
                f"    # {decl.channel} {decl.protocol}, initiator towards {peer}: open a conversation with\n"
                f"    # {opening}; {peer}'s answers come here"
            )
        for perf in needed:
            name = _method(decl, perf, perfs[f"{decl.role}/{decl.protocol}/{perf}"] > 1)
            handlers.append(name)
            answer = (
                "answer with conv.reply(Performative.X, content) or conv.refuse_with(Performative.X, reason)"
                if decl.role == "participant"
                else "act on it (conv.content holds its content; conv.timed_out, conv.reason)"
            )
            todo = (
                f"{agent}: {perf} from {peer} on {decl.channel} ({decl.protocol}) is not handled yet: "
                f"write {class_name}.{name} in {where}"
            )
            blocks.append(
                f'    @handles("{decl.protocol}", {_constant(decl.role)}, "{perf}"'
                + (f', channel="{decl.channel}"' if perfs[f"{decl.role}/{decl.protocol}/{perf}"] > 1 else "")
                + ")\n"
                f"    def {name}(self, conv: Conversation) -> None:\n"
                f'        """{peer} sent {perf} ({decl.protocol} on {decl.channel}): {answer}."""\n'
                f'        raise NotImplementedError("{todo}")\n'
            )
    role_names = sorted({_constant(d.role) for d in roles})
    makers = sorted({d.role for d in roles})
    imports = ", ".join([*role_names, "Conversation", "handles", *makers])
    job = entry.job or f"the agent that substitutes group {entry.group}"
    text = f'''"""{agent} — {job}.

Written by ``roco spec new-agent {agent}`` from the specification: its protocol roles (one per
channel and protocol the specification gives it) and one handler per performative its peers
may send. Each handler raises NotImplementedError until it is written; ``roco spec
verify-code`` lists those not yet written. The runtime's roles answer not-understood, cancels
without a handler, and passed reply-by deadlines (services/runtime/roles.py).
"""

from __future__ import annotations

from services.runtime.agent import Agent
from services.runtime.behaviour import FSM, Behaviour
from services.runtime.roles import {imports}
from shared.fipa_codec import Performative  # noqa: F401  (the performatives handlers answer with)


class {class_name}(Agent):
    name = "{agent}"
    ROLES = (
{chr(10).join(declared)}
    )

    def build_fsm(self) -> FSM:
        return FSM(
            initial="serve",
            states={{
                "serve": Behaviour(
                    "serve", self.handle_received, terminal=lambda: False, doc="answer what arrives"
                )
            }},
        )

{chr(10).join(blocks)}'''
    return text.rstrip() + "\n", tuple(handlers)


def write_agent(spec: SystemSpec, agent: str, root: Path = PROJECT) -> Scaffold:
    """Write agent ``agent``'s module (see the module docstring) under ``root``. Raises
    SpecError for an agent the specification does not name or an implementation that is not
    ``package.module:Class``, FileExistsError when the module exists."""
    entry = next((a for a in spec.agents if a.name == agent), None)
    if entry is None:
        names = ", ".join(a.name for a in spec.agents)
        raise SpecError(f"the specification has no agent {agent!r} (it has {names})")
    module, _, class_name = entry.implementation.partition(":")
    parts = module.split(".")
    if not class_name.isidentifier() or len(parts) < 2 or not all(p.isidentifier() for p in parts):
        raise SpecError(f"agent {agent}: implementation {entry.implementation!r} is not package.module:Class")
    path = root.joinpath(*parts).with_suffix(".py")
    if path.exists():
        raise FileExistsError(f"{path} exists; new-agent writes only new files")
    shown = path.relative_to(root) if path.is_relative_to(root) else path
    text, handlers = agent_source(spec, agent, class_name, str(shown))
    folder = root
    for part in parts[:-1]:
        folder = folder / part
        folder.mkdir(exist_ok=True)
        init = folder / "__init__.py"
        if not init.exists():
            init.write_text("")
    path.write_text(text)
    return Scaffold(path, handlers)
