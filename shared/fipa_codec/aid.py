"""Agent identifiers (FIPA SC00023 §4; their string form: SC00070 §2.2 ``AgentIdentifier``).

An agent-identifier (AID) holds a globally unique ``name``, optionally the ``addresses`` (a
sequence of URLs) at which the agent can be reached, the ``resolvers`` (a sequence of agent
identifiers, typically directory facilitators or AMSs, that can resolve the name to addresses;
recursive) and user-defined parameters, written ``:X-name value`` in the string form (SC00070
§2.2: ``( UserDefinedParameter Expression )*`` after ``:resolvers``).
"""

from __future__ import annotations

import re
from typing import Annotated

import msgspec

from shared.fipa_codec.names import KNOWN_NAMES, MAX_NAME_LENGTH, check_agent_name, check_word

__all__ = ["MAX_AID_DEPTH", "AgentIdentifier", "aid"]

MAX_AID_DEPTH = 32
"""Deepest nesting of agent identifiers through ``resolvers``, counting the outer one: an
identifier without resolvers has depth 1. The same cap as the string-form parser's."""

# a SC00070 Word (see shared.fipa_codec.names; the schema's pattern leaves out its number and
# date-time exclusions)
_NAME_PATTERN = r'[^\x00-\x20()#0-9\-@"][^\x00-\x20()]{0,' + f"{MAX_NAME_LENGTH - 1}}}"
# a SC00070 Word that starts with X- or x-: no white space (U+0000-U+0020), no parenthesis
_USER_NAME_PATTERN = r"[Xx]-[^\x00-\x20()]+"
_USER_NAME = re.compile(_USER_NAME_PATTERN)

# The field types, with their JSON Schema documentation (msgspec.json.schema). The patterns go
# to the schema only (extra_json_schema), anchored; __post_init__ checks them, with fullmatch
# (in Python "$" also matches before a final newline) and once per identifier (a msgspec
# ``pattern`` constraint would double the cost of decoding an agent identifier).
_Name = Annotated[
    str,
    msgspec.Meta(
        description=(
            f"name: a FIPA SC00070 word (no white space or parenthesis, not starting with # - @ or "
            f"a digit), at most {MAX_NAME_LENGTH} characters; roco's agents: a_co, ag_ex…"
        ),
        extra_json_schema={"pattern": f"^{_NAME_PATTERN}$"},
    ),
]
_Addresses = Annotated[
    tuple[str, ...],
    msgspec.Meta(
        description="addresses: transport addresses (URLs, each a FIPA SC00070 word), in order of preference"
    ),
]
_Resolvers = Annotated[
    tuple["AgentIdentifier", ...],
    msgspec.Meta(
        description=(
            f"resolvers: agent identifiers of name resolution services, in order (at most "
            f"{MAX_AID_DEPTH} identifiers deep, counting the outer one)"
        )
    ),
]
_UserParameter = Annotated[
    tuple[
        Annotated[
            str,
            msgspec.Meta(
                description="parameter name, X- included (a SC00070 Word starting with X- or x-)",
                extra_json_schema={"pattern": f"^{_USER_NAME_PATTERN}$"},
            ),
        ],
        Annotated[str, msgspec.Meta(description="parameter value, as text")],
    ],
    msgspec.Meta(description="a user-defined parameter: [name, value]"),
]
_User = Annotated[
    tuple[_UserParameter, ...],
    msgspec.Meta(description="user: user-defined parameters, in order, each name at most once"),
]


def _depth(agent: AgentIdentifier) -> int:
    """How many agent identifiers deep ``agent`` is through its resolvers (1 without any)."""
    return 1 + max((_depth(r) for r in agent.resolvers), default=0)


class AgentIdentifier(msgspec.Struct, frozen=True, array_like=True, gc=False):
    """A FIPA agent-identifier (SC00023 §4, SC00070 §2.2).

    ``name``: the globally unique name, a FIPA SC00070 word of at most
    :data:`~shared.fipa_codec.names.MAX_NAME_LENGTH` characters (``shared.fipa_codec.names``):
    roco's agents' names from the specification (``a_co``, ``ag_ex``…) as well as JADE's
    ``da0@host:1099/JADE``. In Zenoh key expressions a name travels as the key chunk
    :func:`~shared.fipa_codec.names.key_chunk` maps it to (roco's names as themselves).
    ``addresses``: transport addresses (URLs) in order of preference, each a SC00070 word
    (SC00070 §2.2 ``URLSequence``); in roco Zenoh locators (``tcp/127.0.0.1:7447``).
    ``resolvers``: agent identifiers of name resolution services (SC00023 §4), in order;
    each may have resolvers of its own, up to :data:`MAX_AID_DEPTH` identifiers deep.
    ``user``: user-defined parameters as ``(name, value)`` pairs in order; the name includes
    its ``X-`` prefix (``("X-JADE-agent-classname", "examples.PingAgent")``) and is a SC00070
    Word starting with ``X-`` or ``x-`` (no white space U+0000–U+0020, no parenthesis), at
    most once per identifier (spelling matters: ``X-a`` and ``x-a`` are two); the value is
    text. The string form writes them ``:X-name value``.

    Equality and hashing compare all four fields, the sequences in order. Not tracked by
    the garbage collector (``gc=False``: it holds no object that could refer back to it).

    On the wire (msgpack and JSON) an array ``[name, addresses, resolvers, user]``; a reader
    takes missing trailing items as empty, so the two-element arrays ``[name, addresses]``
    written before resolvers and user parameters existed still decode (and ignores extra
    trailing items, so older readers read newer identifiers without their new fields).
    msgspec writes all four items even when empty (``omit_defaults`` has no effect on
    ``array_like`` structs, msgspec issue #720), two bytes more than before in msgpack.

    Raises ValueError on construction (and msgspec.ValidationError on decoding) for a name or
    an address that is no SC00070 word, a name that is too long, a bad or repeated user
    parameter name, or resolvers nested deeper than :data:`MAX_AID_DEPTH`.
    """

    name: _Name
    addresses: _Addresses = ()
    resolvers: _Resolvers = ()
    user: _User = ()

    def __post_init__(self) -> None:
        name = self.name  # run on every identifier decoded: one test for a known name alone
        if type(name) is not str or name not in KNOWN_NAMES or self.addresses or self.user or self.resolvers:
            self._check()

    def _check(self) -> None:
        """The checks of the class docstring (ValueError)."""
        check_agent_name(self.name)
        for address in self.addresses:
            check_word(address, f"address of agent {self.name}")
        if self.user:
            seen: set[str] = set()
            for key, _value in self.user:
                if not isinstance(key, str) or not _USER_NAME.fullmatch(key):
                    raise ValueError(
                        f"invalid user parameter name {key!r} of agent {self.name}: 'X-' or 'x-' "
                        "then a name without white space or parenthesis"
                    )
                if key in seen:
                    raise ValueError(f"user parameter {key!r} of agent {self.name} repeated")
                seen.add(key)
        if self.resolvers and _depth(self) > MAX_AID_DEPTH:
            raise ValueError(
                f"resolvers of agent {self.name} nested deeper than {MAX_AID_DEPTH} agent identifiers"
            )

    def __str__(self) -> str:
        return self.name


def aid(name: str) -> AgentIdentifier:
    """Shorthand for an :class:`AgentIdentifier` without addresses. Raises ValueError when
    ``name`` is no agent name (a SC00070 word of at most 255 characters)."""
    return AgentIdentifier(name)
