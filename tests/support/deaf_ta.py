"""A planted a_ta for tests: the first time in a run that a communicate from a_co on C1 (the
plan) reaches it, its receiving thread ends (an exception no handler catches, raised where the
transport calls it back): the fault the transport must not let pass silently
(services/runtime/transport.py; the agent's process ends with ``EXIT_LOST``,
services/runtime/main.py). Once per run folder (a marker file in it), so that the a_ta started
again is the real one. A test names it as a_ta's implementation in a copy of the specification
(``ROCO_SPEC``); roco itself never starts it."""

from __future__ import annotations

from typing import Any

from services.agents.task_executor.agent import TaskExecutor
from services.runtime import keys
from shared.settings import Settings

MARKER = "deaf_ta.planted"
"""In the run folder: the planted fault has happened."""


class ThreadKiller(BaseException):
    """Not an Exception: the transport's guard around its callback lets it through."""


class DeafTaskExecutor(TaskExecutor):
    """:class:`TaskExecutor` whose receiving thread ends at a_co's first C1 communicate of the run."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        engine = self.engine
        heard = engine._on_payload  # the engine subscribes what it finds here when it binds

        def on_payload(key: str, payload: bytes) -> None:
            if key == keys.fipa_key("C1", "a_co", self.name) and _first_time():
                raise ThreadKiller("planted: a_ta's receiving thread ends")
            heard(key, payload)

        engine._on_payload = on_payload  # type: ignore[method-assign]


def _first_time() -> bool:
    """True once per run folder (none: never)."""
    run_dir = Settings.from_env(only=("run_dir",)).run_dir
    if run_dir is None:
        return False
    try:
        with open(run_dir / MARKER, "x"):
            return True
    except FileExistsError:
        return False
