"""The executor of ag_ex (paper §5.3): the 1 kHz control loop that runs L_EX commands on the
simulated Velma. ``Executor`` hosts it in a thread (tests, scripts), ``ExecutorProcess`` in a
process of its own with lock-free hand-offs (ag_ex).

Names are imported lazily, so that light modules (``velma.executor.timing``,
``velma.executor.handoff``) can be used without loading MuJoCo and Pinocchio."""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from velma.executor.core import Executor
    from velma.executor.process import ExecutorProcess
    from velma.executor.state import RobotSnapshot
    from velma.executor.timing import TimingStats

__all__ = ["Executor", "ExecutorProcess", "RobotSnapshot", "TimingStats"]

_WHERE = {
    "Executor": "velma.executor.core",
    "ExecutorProcess": "velma.executor.process",
    "RobotSnapshot": "velma.executor.state",
    "TimingStats": "velma.executor.timing",
}


def __getattr__(name: str) -> Any:
    if name in _WHERE:
        return getattr(importlib.import_module(_WHERE[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
