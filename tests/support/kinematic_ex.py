"""ag_ex with the kinematic robot double (tests/support/fake_executor.py) in place of the MuJoCo
loop, for the fleet tests whose subject is the agents, the transport or the command line and not
the robot: a pour takes about 10 s and a tenth of the CPU of a simulated one (the
double moves the objects where each step says, counts the content it pours, and perceives the
ground truth). A test names it as ag_ex's implementation in a copy of the specification
(:func:`kinematic_spec`, then ``ROCO_SPEC`` or ``Fleet(spec=...)``); roco itself never starts
it. The world process still starts (the specification's robot role), idle: nothing attaches to
it, so its final scene is the kitchen as it started."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from services.agents.executor.agent import ExecutorAgent
from services.spec.model import DEFAULT_SPEC
from tests.support.fake_executor import FakeExecutor

DOUBLE = "the kinematic robot double serves ag_ex"
"""What :class:`KinematicExecutor` logs (ag_ex.log) as it makes its executor: a test that asked for
the double checks the run had it (:func:`ran_kinematic`)."""
REAL = 'implementation = "services.agents.executor.agent:ExecutorAgent"'
KINEMATIC = 'implementation = "tests.support.kinematic_ex:KinematicExecutor"'


class KinematicExecutor(ExecutorAgent):
    """:class:`ExecutorAgent` serving the kinematic double instead of velma's loop."""

    def make_executor(self) -> Any:
        self.log.info(DOUBLE)
        return FakeExecutor()


def ran_kinematic(run_dir: Path) -> bool:
    """Whether run ``run_dir``'s ag_ex served the kinematic double (its log says so)."""
    log = run_dir / "logs" / "ag_ex.log"
    return log.is_file() and DOUBLE in log.read_text(errors="replace")


def kinematic_spec(path: Path, base: Path = DEFAULT_SPEC) -> Path:
    """Write to ``path`` the specification ``base`` with ag_ex's implementation
    :class:`KinematicExecutor`; returns ``path``. A process that loads it imports this module:
    this checkout's root must be on its PYTHONPATH (or its working folder)."""
    text = base.read_text(encoding="utf-8")
    assert text.count(REAL) == 1, f"{base} does not name ag_ex's implementation once"
    path.write_text(text.replace(REAL, KINEMATIC), encoding="utf-8")
    return path
