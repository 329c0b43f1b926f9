"""Agent identifiers (FIPA SC00023 §4: agent-identifier with name and transport addresses)."""

from __future__ import annotations

import re

import msgspec

_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_.\-@]{0,127}$")


class AgentIdentifier(msgspec.Struct, frozen=True, array_like=True):
    """A FIPA agent-identifier: a globally unique ``name`` and optional transport ``addresses``.

    In roco the name is the agent's name from the specification (``a_co``, ``ag_ex``…); an
    address is a Zenoh locator (``tcp/127.0.0.1:7447``). Encoded as a two-element array on the
    wire to keep communicates small.
    """

    name: str
    addresses: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if not _NAME.match(self.name):
            raise ValueError(f"invalid agent name {self.name!r}: letters, digits, _ . - @ only")

    def __str__(self) -> str:
        return self.name


def aid(name: str) -> AgentIdentifier:
    """Shorthand for an :class:`AgentIdentifier` without addresses. Raises ValueError on a bad name."""
    return AgentIdentifier(name)
