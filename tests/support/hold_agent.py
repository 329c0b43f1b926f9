"""A test's entry module for an agent process of a fleet with the ``Hold`` primitive
(tests/agents/test_new_primitive.py; tests/support/hold.py), not a product feature:
``python -m tests.support.hold_agent AGENT`` registers Hold's rows in the process, then runs
the agent as ``python -m services.runtime.main AGENT`` does (its environment: ``ROCO_ROUTER``,
``ROCO_SPEC`` — a specification with Hold among C5's contents — and the rest).

The rows are registered when the module is imported, not only when it runs as ``__main__``: a
process the agent starts with multiprocessing's spawn (ag_ex's loop, velma/executor/process.py)
imports the main module again as its ``__mp_main__``, and so has the rows too.
``HOLD_ROWS_LEFT_OUT`` (tests/support/hold.py ``LEFT_OUT``) leaves rows out: a test's planted
fault. A test imports tests/support/hold.py, never this module (it registers for good)."""

from __future__ import annotations

import os
import sys

from services.runtime.main import main
from tests.support.hold import LEFT_OUT, register

register([name for name in os.environ.get(LEFT_OUT, "").split(",") if name])

if __name__ == "__main__":
    sys.exit(main())
