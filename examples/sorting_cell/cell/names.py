"""The names of the specification SortingCell: its channels, interaction protocols and content
languages, as string enums (``enum.StrEnum``) and module-level aliases.

GENERATED from the specification by services/spec/render_names.py: do not edit. ``roco spec
names`` writes it again, ``roco spec names --check`` says whether it is what the specification
gives, and ``roco spec new-agent`` brings it up to date.

An agent names its roles with these: ``participant(C5, FIPA_REQUEST, L_EX, L_SD)``. Each member
is a ``str`` equal to the specification's own spelling (``FIPA_REQUEST == "fipa-request"``).
"""

from __future__ import annotations

import enum


class Channel(enum.StrEnum):
    """The channels C^k (paper §3.1; created by the decomposition steps, §5.2), as
    ``[[channels]]`` names them."""

    C1 = "C1"
    """Between a_op and a_so (fipa-request): orders and their outcome."""
    C2 = "C2"
    """Between a_so and a_cv (fipa-request): moves of items to a bin and their result."""


class ProtocolName(enum.StrEnum):
    """The interaction protocols ``[protocols.*]`` names, as a communicate's ``protocol``
    parameter carries them (FIPA SC00061)."""

    FIPA_REQUEST = "fipa-request"
    """FIPA SC00026; on C1, C2."""


class Language(enum.StrEnum):
    """The content languages the channels carry, as a communicate's ``language`` parameter names
    them (FIPA SC00061; shared/fipa_codec/languages)."""

    L_BELT = "L_BELT"
    """On C2."""
    L_ORD = "L_ORD"
    """On C1."""


C1 = Channel.C1
C2 = Channel.C2

FIPA_REQUEST = ProtocolName.FIPA_REQUEST

L_BELT = Language.L_BELT
L_ORD = Language.L_ORD
