"""A planted a_ta for tests: the first time in a run that a communicate from a_co on C1 (the
plan) reaches it, its receiving thread ends (an exception no handler catches, raised where the
transport calls it back): the fault the transport must not let pass silently
(services/runtime/transport.py; the agent's process ends with ``EXIT_LOST``,
services/runtime/main.py). Once per run folder (a marker file in it), so that the a_ta started
again is the real one. A test names it as a_ta's implementation in a copy of the specification
(``ROCO_SPEC``); roco itself never starts it."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from services.agents.task_executor.agent import TaskExecutor
from services.runtime import keys
from shared.settings import Settings

MARKER = "deaf_ta.planted"
"""In the run folder: the planted fault has happened."""


class ThreadKiller(BaseException):
    """Not an Exception: the transport's guard around its callback lets it through."""


class Deafening:
    """The agent's transport, but for a subscription to its inbox: its callback raises
    :class:`ThreadKiller` at a_co's first C1 communicate of the run (every other attribute is
    the transport's own)."""

    def __init__(self, inner: Any, name: str) -> None:
        self.inner = inner
        self.plan_key = keys.fipa_key("C1", "a_co", name)

    def subscribe(self, key_expr: str, callback: Callable[[str, bytes], None]) -> None:
        def on_payload(key: str, payload: bytes) -> None:
            if key == self.plan_key and _first_time():
                raise ThreadKiller("planted: a_ta's receiving thread ends")
            callback(key, payload)

        self.inner.subscribe(key_expr, on_payload)

    def __getattr__(self, name: str) -> Any:
        return getattr(self.inner, name)


class DeafTaskExecutor(TaskExecutor):
    """:class:`TaskExecutor` whose receiving thread ends at a_co's first C1 communicate of the run."""

    def __init__(self, transport: Any, spec: Any = None) -> None:
        super().__init__(Deafening(transport, self.name), spec)


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
