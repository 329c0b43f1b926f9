"""The communication specification as data (paper §4 steps 3–4, §5.4) and the agent
interfaces derived from it.

Loaded from TOML (``robot_companion.toml`` beside this module) into typed Structs; msgspec
validates the shape, :func:`load` the cross references. An agent's interface is the set of
(channel, peer, performative, protocol, language) it may send or receive (paper §4 step 4:
the sets yV̂_j, xV̂_j, yL̂_j, xL̂_j).

A channel may end at an external role (``[[externals]]``, docs/gateway.md) instead of an agent: agents
of other platforms, which no process of roco runs; :meth:`SystemSpec.role_of` says which role a
concrete agent name plays (``da0@host:1099/JADE`` plays ``x_fipa``).
"""

from __future__ import annotations

import datetime
import importlib
import sys
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cache
from pathlib import Path

import msgspec

from shared.settings import Settings

DEFAULT_SPEC = Path(__file__).with_name("robot_companion.toml")
NOT_UNDERSTOOD = "not-understood"


class SpecError(ValueError):
    """A specification file that is malformed or inconsistent; the message names file and place."""


ROLES: dict[str, str] = {
    "person": "hears a person's lines and answers them: the keys roco/human/* "
    "(services/runtime/person.py); roco send, run and the scenarios talk to it",
    "robot": "the robot's executor: publishes its state, camera and the simulation's clock and "
    "hears disturbances of the simulated world (velma/, roco/sim/*)",
}
"""The roles an agent may play beyond its channels (``role = "person"``): what roco grants or
expects of that agent follows the role, never its name. Each role is played by one agent at most."""


class AgentSpec(msgspec.Struct, frozen=True, forbid_unknown_fields=True):
    """An agent: its ``name``, the decomposition ``group`` it substitutes, its ``job``, the
    ``implementation`` (``module:Class``) the launcher starts for it, ``waits``: the
    conversations it opens while serving another (validated by services/spec_check/deadlock.py),
    ``terms``: the module (``services.agents.x.terms``) declaring the agent's own content
    terms, which :func:`load` registers (services/spec/terms.py; empty: none), and ``role``:
    one of :data:`ROLES` (empty: none)."""

    name: str
    group: str
    implementation: str
    job: str = ""
    waits: tuple[dict[str, str | list[str]], ...] = ()
    terms: str = ""
    role: str = ""


class LanguageSpec(msgspec.Struct, frozen=True, forbid_unknown_fields=True):
    """A content language of the system (``[languages.NAME]``; paper §4 step 3 names one per
    kind of content): the ``ontology`` its terms come from and the ``terms`` that form its
    vocabulary, each a module that lists msgspec Structs in ``TERMS`` (``"cell.terms"``: all of
    them) or one Struct of such a module (``"cell.terms:Order"``). Several languages and agents
    may name the same module. A name roco's codec already has (``L_WM``) is extended by the
    terms; a new name needs an ``ontology`` and at least one term (services/spec/terms.py)."""

    ontology: str = ""
    terms: tuple[str, ...] = ()
    description: str = ""


class ExternalSpec(msgspec.Struct, frozen=True, forbid_unknown_fields=True):
    """A role played by agents outside the platform (docs/gateway.md): agents of another FIPA
    platform, reached through ``roco gateway`` (FIPA SC00084 HTTP transport, SC00085 envelope).
    ``name`` is the role's name in the channels (``x_fipa``), ``group`` the group outside the
    system that a decomposition step introduces (``outside``), ``job`` what such agents do here.
    No process of roco plays it: every agent name of the form ``local@platform`` (a FIPA
    SC00023 GUID, e.g. JADE's ``da0@host:1099/JADE``) that is not an agent of the
    specification plays it (:meth:`SystemSpec.role_of`); with a ``platform``, only the names
    ``local@<platform>`` play it (``x_ros2``: ``…@ros2``, the callers of ``roco ros2``)."""

    name: str
    group: str
    job: str = ""
    platform: str = ""


class ProtocolRoles(msgspec.Struct, frozen=True, forbid_unknown_fields=True):
    """Performatives each role of an interaction protocol may send, and optionally its state
    machine (validated and built by services/spec/protocol_defs.py; ``crossing``: the
    transitions only a communicate that crossed the other party's latest may take).

    A ``[protocols.NAME]`` table may leave out ``initiator`` and ``participant``: :func:`load`
    fills them with what the protocol's state machine lets each role send
    (services/spec/protocol_defs.py ``role_lists``); a Struct built in Python gets what it is
    given (empty by default)."""

    initiator: tuple[str, ...] = ()
    participant: tuple[str, ...] = ()
    initial: str | None = None
    final: tuple[str, ...] = ()
    transitions: tuple[tuple[str, str, str, str], ...] = ()
    cancellable: tuple[str, ...] = ()
    terminal: tuple[tuple[str, str, str, str], ...] = ()
    description: str = ""
    spec: str = ""
    crossing: tuple[tuple[str, str, str, str], ...] = ()


class ChannelProtocol(msgspec.Struct, frozen=True, forbid_unknown_fields=True):
    """One protocol on a channel: who initiates; per performative the content language, the
    content schemas (``contents``: the names of the language's terms it may carry; absent:
    any term, or none) and the size estimate on the wire (``sizes``: [min, max] bytes of the
    encoded communicate; paper eq. 4 and §5.4 give them per language)."""

    protocol: str
    initiator: str
    languages: dict[str, str | tuple[str, ...]] = {}
    contents: dict[str, tuple[str, ...]] = {}
    sizes: dict[str, tuple[int, int]] = {}

    def content_types(self, performative: str) -> tuple[str, ...]:
        """The term names ``performative`` may carry (empty: not constrained)."""
        return self.contents.get(performative, ())


class ChannelSpec(msgspec.Struct, frozen=True, forbid_unknown_fields=True):
    """A communication channel C^k between two agents (paper §3.1) and its protocols."""

    name: str
    ends: tuple[str, str]
    transmits: str
    protocols: tuple[ChannelProtocol, ...]


class SystemSpec(msgspec.Struct, frozen=True, forbid_unknown_fields=True):
    """The whole specification file: the system's name, agents, protocols and channels; the
    requirement tree and the decomposition steps are read (and validated field by field) by
    services/spec/decomposition.py."""

    system: str
    agents: tuple[AgentSpec, ...]
    protocols: dict[str, ProtocolRoles]
    channels: tuple[ChannelSpec, ...]
    requirements: tuple[dict[str, object], ...] = ()
    steps: tuple[dict[str, object], ...] = ()
    start_order: tuple[str, ...] = ()
    """The order a launcher starts the agents in; agents it does not name start after those it
    names, in file order."""
    externals: tuple[ExternalSpec, ...] = ()
    """Roles of agents outside the platform (one per platform; see :class:`ExternalSpec`)."""
    languages: dict[str, LanguageSpec] = {}
    """The system's own content languages, or terms added to roco's (:class:`LanguageSpec`)."""
    names: str = ""
    """The module of the system's names (``cell.names``): ``roco spec names`` writes it, the
    agents ``roco spec new-agent`` writes import from it. Empty: :attr:`names_module`'s default."""

    @property
    def names_module(self) -> str:
        """:attr:`names`, else ``<package>.names`` where ``<package>`` is the top-level package
        of the first agent's ``implementation`` (``cell.operator:Operator`` → ``cell.names``)."""
        if self.names:
            return self.names
        first = self.agents[0].implementation.partition(":")[0] if self.agents else ""
        return f"{first.partition('.')[0] or 'system'}.names"

    @property
    def external_names(self) -> tuple[str, ...]:
        """The external roles' names (``x_fipa``), in file order."""
        return tuple(e.name for e in self.externals)

    def role_of(self, name: str) -> str:
        """The name agent ``name`` has in the channels: an agent of the specification is
        itself; a foreign agent (``local@platform``, not an agent of the specification) plays
        the external role of its platform, else the one without a platform
        (:class:`ExternalSpec`); any other
        name is itself (and ends no channel)."""
        if self.externals and is_foreign(name) and name not in self.agent_names:
            platform = name[name.find("@", 1) + 1 :]
            named = [e.name for e in self.externals if e.platform == platform]
            anyone = [e.name for e in self.externals if not e.platform]
            return (named or anyone or [name])[0]
        return name

    def playing(self, role: str) -> str | None:
        """The agent that plays ``role`` (one of :data:`ROLES`), or None when none does."""
        return next((a.name for a in self.agents if a.role == role), None)

    @property
    def agent_names(self) -> tuple[str, ...]:
        """The agents' names, in file order."""
        return tuple(a.name for a in self.agents)

    @property
    def launch_order(self) -> tuple[str, ...]:
        """The order a launcher starts the agents in: those ``start_order`` names, then the
        others in file order (a new agent needs no entry there to be started)."""
        return (*self.start_order, *(a for a in self.agent_names if a not in self.start_order))


@dataclass(frozen=True)
class MessageKind:
    """One kind of communicate an agent may send or receive."""

    channel: str
    sender: str
    receiver: str
    performative: str
    protocol: str
    languages: tuple[str, ...]
    contents: tuple[str, ...] = ()
    """the names of the language terms it may carry (empty: any)"""


@dataclass(frozen=True)
class Interface:
    """An agent's interface: the kinds of communicates it sends and receives."""

    agent: str
    sends: tuple[MessageKind, ...]
    receives: tuple[MessageKind, ...]

    def accepts(self, sender: str, performative: str, protocol: str | None) -> MessageKind | None:
        """The received kind matching a communicate, or None when it is outside the interface."""
        for kind in self.receives:
            if kind.sender == sender and kind.performative == performative and kind.protocol == protocol:
                return kind
        return None


def is_foreign(name: str) -> bool:
    """Whether ``name`` is the name of an agent of another platform: a FIPA SC00023 GUID
    ``local@platform`` (an ``@`` after its first character and before its last), as JADE
    names its agents (``da0@host:1099/JADE``). roco's own agents have short names without one."""
    at = name.find("@", 1)
    return 0 < at < len(name) - 1


def read_text(path: Path, what: str = "specification file", error: type[ValueError] = SpecError) -> str:
    """The text of an input file (UTF-8). Raises ``error`` (one line naming the file) when it
    does not exist, is a directory, cannot be read, or is not UTF-8 (with the line and
    column of the first bad byte)."""
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise error(f"{path}: no such {what}") from None
    except IsADirectoryError:
        raise error(f"{path}: is a directory, not a {what}") from None
    except OSError as exc:
        raise error(f"{path}: cannot read the {what}: {exc.strerror or exc}") from None
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        column = exc.start - (data.rfind(b"\n", 0, exc.start) + 1) + 1
        bad = f"byte 0x{data[exc.start]:02x} at line {line}, column {column}"
        raise error(f"{path}: not UTF-8 text ({bad})") from None


def one_line(exc: Exception) -> str:
    """The first line of an exception's message (msgspec and tomllib messages name the
    place: ``at line L, column C`` or the key path ``$.channels[0].ends``)."""
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def _check_externals(spec: SystemSpec, names: set[str], path: Path) -> None:
    """External roles named as no agent (``names``) and no GUID, each once
    (:func:`_check_platforms`)."""
    _check_platforms(spec, path)
    if len({e.name for e in spec.externals}) != len(spec.externals):
        raise SpecError(f"{path}: an external role is named twice")
    for e in spec.externals:
        if e.name in names or is_foreign(e.name):
            raise SpecError(f"{path}: external role {e.name!r} must be no agent's name and no GUID")


def _check_platforms(spec: SystemSpec, path: Path) -> None:
    """At most one external role without a platform, each platform once and a word (letters,
    digits, ``_``, ``-``: a key chunk's end of an agent's name)."""
    platforms = [e.platform for e in spec.externals]
    if len(set(platforms)) != len(platforms):
        raise SpecError(f"{path}: at most one external role per platform (and one without)")
    for p in platforms:
        if p and not p.replace("_", "").replace("-", "").isalnum():
            raise SpecError(f"{path}: platform {p!r} of an external role is no word")


def _check_roles(spec: SystemSpec, path: Path) -> None:
    """Each agent's role is one of :data:`ROLES`, each played by one agent at most."""
    for a in spec.agents:
        if a.role and a.role not in ROLES:
            raise SpecError(f"{path}: agent {a.name}: unknown role {a.role!r} (roles: {', '.join(ROLES)})")
    for role in ROLES:
        playing = [a.name for a in spec.agents if a.role == role]
        if len(playing) > 1:
            raise SpecError(f"{path}: role {role!r} is played by {' and '.join(playing)}: one agent at most")


def _check_agents(spec: SystemSpec, path: Path) -> None:
    """Agents named once, each role of :data:`ROLES` played once at most; the external roles
    (:func:`_check_externals`); ``start_order`` names known agents, each once."""
    names = {a.name for a in spec.agents}
    if len(names) != len(spec.agents):
        raise SpecError(f"{path}: an agent is named twice")
    _check_roles(spec, path)
    _check_externals(spec, names, path)
    unknown = [a for a in spec.start_order if a not in names]
    if unknown or len(set(spec.start_order)) != len(spec.start_order):
        what = f"unknown agent {unknown[0]!r}" if unknown else "an agent twice"
        raise SpecError(f"{path}: start_order names {what}")


def _check_channel(spec: SystemSpec, ch: ChannelSpec, path: Path) -> None:
    """The channel's ends are agents or the external role (not two external roles); its
    protocols are the specification's, each initiated by an end."""
    names = {a.name for a in spec.agents}
    outside = set(spec.external_names)
    for end in ch.ends:
        if end not in names and end not in outside:
            raise SpecError(f"{path}: channel {ch.name} names unknown agent {end!r}")
    if set(ch.ends) <= outside:
        raise SpecError(f"{path}: channel {ch.name} joins two external roles")
    for cp in ch.protocols:
        if cp.protocol not in spec.protocols:
            raise SpecError(f"{path}: channel {ch.name} uses unknown protocol {cp.protocol!r}")
        if cp.initiator not in ch.ends:
            raise SpecError(f"{path}: channel {ch.name}: initiator {cp.initiator!r} is not an end")


def load(path: Path = DEFAULT_SPEC) -> SystemSpec:
    """Load and cross-check a specification, fill in the role lists a ``[protocols.NAME]``
    table leaves out (:func:`_with_role_lists`) and register its content languages
    (``[languages.NAME]``) and its agents' own content terms (``terms``: services/spec/terms.py),
    so that every process that loads it decodes them.
    Raises SpecError, one line naming the file and the place: line and column for TOML syntax,
    the key path (``$.channels[0].ends``) for a wrong type or unknown field, the channel for an
    unknown agent or protocol, the protocol whose role lists cannot be derived (its declared
    state machine breaks a rule, or it has none), the language or agent whose terms cannot be
    registered."""
    text = read_text(path)
    try:
        raw = msgspec.toml.decode(text)
        # as msgspec.toml.decode(text, type=SystemSpec) converts, keeping the plain tables
        spec = msgspec.convert(
            raw, SystemSpec, str_keys=True, builtin_types=(datetime.datetime, datetime.date, datetime.time)
        )
    except (msgspec.DecodeError, msgspec.ValidationError) as exc:
        raise SpecError(f"{path}: {one_line(exc)}") from None
    _check_agents(spec, path)
    for ch in spec.channels:
        _check_channel(spec, ch, path)
    spec = _with_role_lists(spec, raw.get("protocols", {}), path)
    from services.spec.terms import register_languages, register_terms  # they read this module's types

    system_package_importable(path)
    register_languages(spec, path)
    register_terms(spec, path)
    return spec


def system_root(path: Path) -> Path:
    """The folder the packages of the system specified by ``path`` start in: roco's checkout
    for the shipped specification, else the specification's own folder (a system is a
    specification plus a package beside it: ``cell.toml`` and ``cell/``)."""
    shipped = path.resolve() == DEFAULT_SPEC.resolve()
    return DEFAULT_SPEC.resolve().parents[2] if shipped else path.resolve().parent


def system_package_importable(path: Path) -> None:
    """Make the system's package beside the specification ``path`` importable: its folder is
    appended to ``sys.path`` (after roco's own packages: a package there never replaces one of
    roco's), unless it is the shipped specification. A system is a specification plus a package
    beside it (``cell.toml`` and ``cell/``: examples/sorting_cell/), so its agents
    (``implementation``) and terms modules import in every process that loads it."""
    if path.resolve() == DEFAULT_SPEC.resolve():
        return
    folder = str(system_root(path))
    if folder not in sys.path:
        sys.path.append(folder)
        importlib.invalidate_caches()


def _with_role_lists(spec: SystemSpec, tables: Mapping[str, Mapping[str, object]], path: Path) -> SystemSpec:
    """``spec`` with the ``initiator``/``participant`` lists its ``[protocols.NAME]``
    ``tables`` leave out filled in: what the protocol's state machine (declared in the table,
    else built in) lets each role send (services/spec/protocol_defs.py ``role_lists``). Raises
    SpecError naming ``path`` and the protocol when its declared machine breaks a rule or it
    has none."""
    missing = [
        name for name, table in tables.items() if "initiator" not in table or "participant" not in table
    ]
    if not missing:
        return spec
    from services.spec.protocol_defs import role_lists  # it reads this module's types

    protocols = dict(spec.protocols)
    for name in missing:
        table, roles = tables[name], protocols[name]
        initiator, participant = role_lists(name, table, source=path)
        protocols[name] = msgspec.structs.replace(
            roles,
            initiator=roles.initiator if "initiator" in table else initiator,
            participant=roles.participant if "participant" in table else participant,
        )
    return msgspec.structs.replace(spec, protocols=protocols)


def spec_path(*environs: Mapping[str, str]) -> Path:
    """The specification file ``ROCO_SPEC`` names in the first of ``environs`` that sets it
    (none given: ``os.environ``, read now), else :data:`DEFAULT_SPEC`."""
    for env in environs or (None,):
        named = Settings.from_env(env, only=("spec",)).spec
        if named is not None:
            return named
    return DEFAULT_SPEC


@cache
def default_spec() -> SystemSpec:
    """The Robot Companion's specification, loaded once per process."""
    return load()


def channel_between(spec: SystemSpec, a: str, b: str) -> ChannelSpec | None:
    """The channel joining agents ``a`` and ``b`` (in either order), or None."""
    for ch in spec.channels:
        if set(ch.ends) == {a, b}:
            return ch
    return None


def interface(spec: SystemSpec, agent: str) -> Interface:
    """Derive ``agent``'s interface from the channels it ends (paper §4 step 4)."""
    sends: list[MessageKind] = []
    receives: list[MessageKind] = []
    for ch in spec.channels:
        if agent not in ch.ends:
            continue
        peer = ch.ends[1] if ch.ends[0] == agent else ch.ends[0]
        for cp in ch.protocols:
            roles = spec.protocols[cp.protocol]
            mine = roles.initiator if cp.initiator == agent else roles.participant
            theirs = roles.participant if cp.initiator == agent else roles.initiator
            for perf in (*mine, NOT_UNDERSTOOD):
                sends.append(
                    MessageKind(
                        ch.name, agent, peer, perf, cp.protocol, _langs(cp, perf), cp.content_types(perf)
                    )
                )
            for perf in (*theirs, NOT_UNDERSTOOD):
                receives.append(
                    MessageKind(
                        ch.name, peer, agent, perf, cp.protocol, _langs(cp, perf), cp.content_types(perf)
                    )
                )
    return Interface(agent, tuple(sends), tuple(receives))


def asked(spec: SystemSpec, agent: str) -> tuple[str, ...]:
    """The agents ``agent`` asks: the other end of each channel on which it initiates a protocol,
    each once, in the channels' order; an external role (``x_fipa``) is not an agent of the
    platform and is left out. An agent is ready once it has seen these (services/runtime/engine.py
    ``Engine.ready``)."""
    found: list[str] = []
    for ch in spec.channels:
        if agent not in ch.ends or not any(cp.initiator == agent for cp in ch.protocols):
            continue
        peer = ch.ends[1] if ch.ends[0] == agent else ch.ends[0]
        if peer != agent and peer in spec.agent_names and peer not in found:
            found.append(peer)
    return tuple(found)


def _langs(cp: ChannelProtocol, performative: str) -> tuple[str, ...]:
    lang = cp.languages.get(performative)
    if lang is None:
        return ()
    return (lang,) if isinstance(lang, str) else tuple(lang)
