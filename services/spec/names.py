"""The names of the specification RoCo: its channels, interaction protocols and content
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
    """Between a_co and a_ta (coordinate): plans to be executed, a_ta's supervised-worker states,
    plan cancellation."""
    C2 = "C2"
    """Between a_co and a_hi (fipa-request, fipa-subscribe, fipa-query): interpreted human
    commands, their progress and outcome, the robot's status."""
    C3 = "C3"
    """Between a_co and a_pl (fipa-request): plan requests (ground task networks) and generated
    plans."""
    C4 = "C4"
    """Between a_pl and a_km (fipa-query): knowledge needed by the planner."""
    C5 = "C5"
    """Between ag_ex and a_ta (fipa-request, fipa-subscribe): low-level commands for the hardware
    and sensor readings."""
    C6 = "C6"
    """Between a_ta and a_km (fipa-subscribe, fipa-query): knowledge needed by a_ta and updates
    of the environment model."""
    C7 = "C7"
    """Between a_hi and a_km (fipa-query, fipa-subscribe): the words for the kitchen's things and
    where they are (a_hi's vocabulary), and what a_km knows of them for a person's questions
    (contents, places, when a_ta last saw them)."""
    C8 = "C8"
    """Between x_fipa and a_hi (fipa-request, roco-notify): sentences from agents of other FIPA
    platforms (through roco gateway) and their outcome; their notices to the person."""
    C9 = "C9"
    """Between x_ros2 and a_hi (fipa-request): sentences from ROS 2 nodes (through roco ros2) and
    their outcome."""


class ProtocolName(enum.StrEnum):
    """The interaction protocols ``[protocols.*]`` names, as a communicate's ``protocol``
    parameter carries them (FIPA SC00061)."""

    FIPA_REQUEST = "fipa-request"
    """FIPA SC00026; on C2, C3, C5, C8, C9."""
    FIPA_QUERY = "fipa-query"
    """FIPA SC00027; on C2, C4, C6, C7."""
    FIPA_SUBSCRIBE = "fipa-subscribe"
    """FIPA SC00035; on C2, C5, C6, C7."""
    COORDINATE = "coordinate"
    """paper §5.4, Figure 8; on C1."""
    ROCO_NOTIFY = "roco-notify"
    """inform: FIPA SC00037; on C8."""


class Language(enum.StrEnum):
    """The content languages the channels carry, as a communicate's ``language`` parameter names
    them (FIPA SC00061; shared/fipa_codec/languages)."""

    L_EX = "L_EX"
    """On C5."""
    L_HC = "L_HC"
    """On C2, C8, C9."""
    L_HFSM = "L_HFSM"
    """On C1, C3."""
    L_SD = "L_SD"
    """On C5."""
    L_SW = "L_SW"
    """On C1."""
    L_WM = "L_WM"
    """On C4, C6, C7."""


C1 = Channel.C1
C2 = Channel.C2
C3 = Channel.C3
C4 = Channel.C4
C5 = Channel.C5
C6 = Channel.C6
C7 = Channel.C7
C8 = Channel.C8
C9 = Channel.C9

FIPA_REQUEST = ProtocolName.FIPA_REQUEST
FIPA_QUERY = ProtocolName.FIPA_QUERY
FIPA_SUBSCRIBE = ProtocolName.FIPA_SUBSCRIBE
COORDINATE = ProtocolName.COORDINATE
ROCO_NOTIFY = ProtocolName.ROCO_NOTIFY

L_EX = Language.L_EX
L_HC = Language.L_HC
L_HFSM = Language.L_HFSM
L_SD = Language.L_SD
L_SW = Language.L_SW
L_WM = Language.L_WM
