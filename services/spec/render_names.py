"""``services/spec/names.py`` rendered from the specification: its channels, interaction
protocols and content languages as string enums (``enum.StrEnum``), with a module-level alias
for each member, so that an agent declares a role as ``participant(C5, FIPA_REQUEST, L_EX,
L_SD)`` and a handler as ``@handles(FIPA_REQUEST, PARTICIPANT, Performative.REQUEST)``
(docs/spec.md, "Names from the specification").

A name of the specification becomes a Python name by :func:`python_name`: upper case, with
``-`` written ``_`` (``fipa-request`` → ``FIPA_REQUEST``; ``C5`` and ``L_EX`` stay as they
are). Each member's value is the specification's own spelling, and a ``StrEnum`` member is a
``str`` equal to it (``Channel.C5 == "C5"``, ``f"{Channel.C5}" == "C5"``), so the runtime's
tables keyed by strings, the key expressions and the wire see the specification's spellings.

``roco spec names`` writes the file, ``roco spec names --check`` compares it, and ``roco spec
new-agent`` brings it up to date after a decomposition step added channels — as
services/deploy/compose.py does for deploy/compose.yaml.
"""

from __future__ import annotations

import re
import textwrap
from dataclasses import dataclass
from pathlib import Path

from services.spec.generated import GeneratedFile
from services.spec.model import ProtocolRoles, SpecError, SystemSpec, system_root
from shared.fipa_codec.protocols import PROTOCOLS

NAMES_FILE = Path(__file__).with_name("names.py")
"""The project's generated names module."""


def names_file(spec_path: Path, spec: SystemSpec) -> Path:
    """The file of the names module of the system ``spec`` loaded from ``spec_path``
    (``SystemSpec.names_module`` under services/spec/model.py ``system_root``): services/spec/names.py for the
    shipped one, ``cell/names.py`` beside ``cell.toml`` for a system whose agents are ``cell.…``."""
    return system_root(spec_path).joinpath(*spec.names_module.split(".")).with_suffix(".py")


MAX_NAMES_BYTES = 1 << 20
"""Largest names module :func:`check` reads (1 MiB; the rendered file is ≈ 3 kB)."""

WIDTH = 100
"""Longest line of a rendered docstring (ruff's limit is 110)."""

_NAME = re.compile(r"[A-Z][A-Z0-9_]*")
_KINDS = ("channel", "protocol", "language")


class NamesError(SpecError):
    """A specification whose names cannot be rendered as Python names, or a names module that
    cannot be read or written; the message is one line naming the name or the file."""


@dataclass(frozen=True)
class Member:
    """One member of a rendered enum: its Python ``name``, the specification's ``value``, and
    the ``doc`` its docstring says."""

    name: str
    value: str
    doc: str


@dataclass(frozen=True)
class TypedNames:
    """The members of the three enums, in the order the module lists them: ``channels`` as
    ``[[channels]]`` lists them, ``protocols`` as ``[protocols.*]`` does, ``languages``
    sorted by name."""

    channels: tuple[Member, ...]
    protocols: tuple[Member, ...]
    languages: tuple[Member, ...]

    def aliases(self) -> dict[str, str]:
        """Every module-level alias → the specification's name it stands for
        (``FIPA_REQUEST`` → ``fipa-request``)."""
        return {m.name: m.value for m in (*self.channels, *self.protocols, *self.languages)}


def python_name(kind: str, value: str) -> str:
    """The Python name of the specification's ``kind`` (channel, protocol or language) named
    ``value``: upper case, ``-`` as ``_``. Raises NamesError when that is not an ASCII upper-case
    identifier starting with a letter (``C5``, ``FIPA_REQUEST``, ``L_EX``)."""
    name = value.upper().replace("-", "_")
    if not _NAME.fullmatch(name):
        raise NamesError(
            f"{kind} {value!r} has no Python name in services/spec/names.py: upper-cased with '-' "
            f"as '_' it must be a letter, then letters, digits and '_' (not {name!r})"
        )
    return name


def _languages(spec: SystemSpec) -> dict[str, list[str]]:
    """Each content language the channels name → the channels that carry it, in file order."""
    out: dict[str, list[str]] = {}
    for ch in spec.channels:
        for cp in ch.protocols:
            for value in cp.languages.values():
                for language in (value,) if isinstance(value, str) else value:
                    channels = out.setdefault(language, [])
                    if ch.name not in channels:
                        channels.append(ch.name)
    return out


def _protocol_member(spec: SystemSpec, name: str, roles: ProtocolRoles) -> Member:
    """Protocol ``name``'s member: its source (FIPA spec) and the channels that carry it."""
    where = [ch.name for ch in spec.channels if any(cp.protocol == name for cp in ch.protocols)]
    source = roles.spec or (PROTOCOLS[name].spec if name in PROTOCOLS else "")
    said = f"{source}; " if source else ""
    on = f"on {', '.join(where)}" if where else "on no channel"
    return Member(python_name("protocol", name), name, f"{said}{on}.")


def _check_unique(typed: TypedNames) -> None:
    """NamesError for two members that would be one Python name."""
    seen: dict[str, tuple[str, str]] = {}
    for kind, members in zip(_KINDS, (typed.channels, typed.protocols, typed.languages), strict=True):
        for m in members:
            if m.name in seen:
                other_kind, other = seen[m.name]
                raise NamesError(
                    f"{kind} {m.value!r} and {other_kind} {other!r} would both be {m.name} in "
                    f"services/spec/names.py: rename one in the specification"
                )
            seen[m.name] = (kind, m.value)


def typed_names(spec: SystemSpec) -> TypedNames:
    """The members of ``spec``'s names module. Raises NamesError for a name with no Python
    name (:func:`python_name`) and for two names of the module that would be one Python name
    (``C1`` and ``c1``; a channel and a language both ``L_X``)."""
    channels = tuple(
        Member(
            python_name("channel", ch.name),
            ch.name,
            f"Between {ch.ends[0]} and {ch.ends[1]} "
            f"({', '.join(cp.protocol for cp in ch.protocols)}): {ch.transmits}.",
        )
        for ch in spec.channels
    )
    protocols = tuple(_protocol_member(spec, name, roles) for name, roles in spec.protocols.items())
    languages = tuple(
        Member(python_name("language", name), name, f"On {', '.join(where)}.")
        for name, where in sorted(_languages(spec).items())
    )
    typed = TypedNames(channels, protocols, languages)
    _check_unique(typed)
    return typed


def spellings(spec: SystemSpec) -> dict[str, str]:
    """Every Python name of ``spec``'s channels, protocols and languages → the specification's
    spelling (``FIPA_REQUEST`` → ``fipa-request``), as :func:`typed_names` gives them, but
    leaving out a name that has none or that another already has, instead of raising: what
    services/runtime/code_scan.py reads an agent's code by."""
    out: dict[str, str] = {}
    named = [
        *(("channel", ch.name) for ch in spec.channels),
        *(("protocol", name) for name in spec.protocols),
        *(("language", name) for name in sorted(_languages(spec))),
    ]
    for kind, value in named:
        try:
            out.setdefault(python_name(kind, value), value)
        except NamesError:
            continue
    return out


def _docstring(text: str, indent: str) -> str:
    """``text`` as a docstring at ``indent``, wrapped at :data:`WIDTH`."""
    text = text.replace("\\", "\\\\").replace('"', '\\"')
    lines = textwrap.wrap(text, WIDTH - len(indent) - 6, break_long_words=False, break_on_hyphens=False) or [
        ""
    ]
    return indent + '"""' + f"\n{indent}".join(lines) + '"""\n'


_HEAD = '''"""The names of the specification {system}: its channels, interaction protocols and content
languages, as string enums (``enum.StrEnum``) and module-level aliases.

GENERATED from the specification by services/spec/render_names.py: do not edit. ``roco spec
names`` writes it again, ``roco spec names --check`` says whether it is what the specification
gives, and ``roco spec new-agent`` brings it up to date.

An agent names its roles with these: ``participant(C5, FIPA_REQUEST, L_EX, L_SD)``. Each member
is a ``str`` equal to the specification's own spelling (``FIPA_REQUEST == "fipa-request"``).
"""

from __future__ import annotations

import enum

'''

_CLASSES = (
    (
        "Channel",
        "The channels C^k (paper §3.1; created by the decomposition steps, §5.2), as "
        "``[[channels]]`` names them.",
    ),
    (
        "ProtocolName",
        "The interaction protocols ``[protocols.*]`` names, as a communicate's ``protocol`` "
        "parameter carries them (FIPA SC00061).",
    ),
    (
        "Language",
        "The content languages the channels carry, as a communicate's ``language`` parameter "
        "names them (FIPA SC00061; shared/fipa_codec/languages).",
    ),
)


def render(spec: SystemSpec) -> str:
    """The names module ``spec`` gives (see the module docstring). Raises NamesError as
    :func:`typed_names`."""
    typed = typed_names(spec)
    groups = (typed.channels, typed.protocols, typed.languages)
    system = spec.system.replace("\\", "\\\\").replace('"', '\\"')
    parts = [_HEAD.format(system=system)]
    for (cls, doc), members in zip(_CLASSES, groups, strict=True):
        body = (
            "".join(f'    {m.name} = "{m.value}"\n' + _docstring(m.doc, "    ") for m in members)
            or "    pass\n"
        )
        parts.append(f"\nclass {cls}(enum.StrEnum):\n{_docstring(doc, '    ')}\n{body}\n")
    for (cls, _), members in zip(_CLASSES, groups, strict=True):
        parts.append("\n" + "".join(f"{m.name} = {cls}.{m.name}\n" for m in members))
    return "".join(parts).rstrip("\n") + "\n"


def _named_difference(text: str, spec: SystemSpec) -> str | None:
    """The names names module ``text`` lacks, or has beyond the specification's."""
    typed = typed_names(spec)
    names = set(typed.aliases())
    found = set(re.findall(r"^([A-Z][A-Z0-9_]*) = [A-Za-z]+\.", text, re.M))
    if missing := sorted(names - found, key=list(typed.aliases()).index):
        return f"no name {', '.join(missing)}"
    if extra := sorted(found - names):
        return f"names {', '.join(extra)}, which the specification does not have"
    return None


NAMES = GeneratedFile(
    what="names module",
    relative=Path("services", "spec", "names.py"),
    command="roco spec names",
    max_bytes=MAX_NAMES_BYTES,
    error=NamesError,
    render=render,
    named_difference=_named_difference,
    wrote=lambda spec: f"the names of channels {', '.join(ch.name for ch in spec.channels)}",
)
"""``services/spec/names.py`` (services/spec/generated.py): ``read``, ``difference``,
``check``, ``write``, ``bring_up_to_date``."""
read = NAMES.read
difference = NAMES.difference
check = NAMES.check
write = NAMES.write
bring_up_to_date = NAMES.bring_up_to_date
