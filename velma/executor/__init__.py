"""The executor core of ag_ex: ``Executor`` runs L_EX commands on the simulated Velma."""

from __future__ import annotations

from velma.executor.core import Executor, RobotSnapshot

__all__ = ["Executor", "RobotSnapshot"]
