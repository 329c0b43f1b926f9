"""A planted a_ta for tests: it reports Preempted as soon as a_co's cancel has halted the robot,
without making the robot safe first (no safe stop: what it holds stays in its hands), against
paper §3.2. A test names it as a_ta's implementation in a copy of the specification
(``ROCO_SPEC``); roco itself never starts it."""

from __future__ import annotations

from services.agents.task_executor.agent import TaskExecutor
from shared.fipa_codec.languages.l_hfsm import PlanNode


class HastyTaskExecutor(TaskExecutor):
    """:class:`TaskExecutor` whose safe stop is empty: Preempted follows the halt at once."""

    def _begin_safe_stop(
        self, key: str | None = None, first: list[tuple[str, PlanNode]] | None = None
    ) -> None:
        super()._begin_safe_stop(key, first)
        self.leaves, self.atomic_spans, self.index = [], [], 0
