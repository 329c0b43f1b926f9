"""L_SW: the supervised-worker states a_ta reports to a_co on C1 (paper §5.4, protocol coordinate)."""

from __future__ import annotations

import enum

import msgspec

from shared.fipa_codec.languages.base import Language, register


class SWState(enum.StrEnum):
    """States of a supervised worker (paper §5.4)."""

    IDLE = "Idle"
    RUNNING = "Running"
    ERROR = "Error"
    TERMINATING = "Terminating"
    SUCCEEDED = "Succeeded"
    PREEMPTED = "Preempted"
    REPLAN = "Replan"


TERMINAL_SW_STATES = frozenset({SWState.ERROR, SWState.SUCCEEDED, SWState.PREEMPTED, SWState.REPLAN})


class SWStatus(msgspec.Struct, frozen=True, tag="sw", kw_only=True):
    """a_ta's state ``state`` while running plan ``plan_id``; ``step`` is the HFSM state path
    being executed (e.g. ``fetch_jar/grasp``), ``reason`` explains Error or Replan."""

    state: SWState
    plan_id: str = ""
    step: str | None = None
    reason: str | None = None


L_SW = register(Language("L_SW", "O_RoCo", (SWStatus,)))
