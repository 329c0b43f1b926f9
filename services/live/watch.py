"""The live view on a terminal: Zenoh subscribers that feed a :class:`LiveState`, and rich's
``Live`` display that draws it under the event lines (two refreshes a second)."""

from __future__ import annotations

import time
from collections.abc import Callable, Collection, Sequence
from types import TracebackType
from typing import Any

import zenoh
from rich.console import Console
from rich.live import Live

from services.live.state import LiveState
from services.live.view import LiveView
from services.runtime import keys

REFRESH_PER_SECOND = 2.0


class LiveWatch:
    """``with LiveWatch("roco run", agents) as watch:`` shows the view until the block ends;
    ``watch.attach(session)`` subscribes to the run's traffic, ag_ex's state and the white
    pages; ``watch.line(text)`` prints an event line above the view. ``console`` defaults to
    a new rich Console on stdout; ``clock`` (s) to ``time.monotonic``; ``notice_protocols``: the
    specification's notice protocols (services/spec/notices.py), whose informs the view shows as
    notices to the person."""

    def __init__(
        self,
        title: str,
        expected: Sequence[str],
        *,
        console: Console | None = None,
        clock: Callable[[], float] = time.monotonic,
        notice_protocols: Collection[str] = (),
    ) -> None:
        self.title = title
        self.clock = clock
        self.state = LiveState(tuple(expected), clock(), notice_protocols)
        self.console = console or Console(highlight=False)
        self._subscribers: list[Any] = []
        self._live = Live(
            get_renderable=self.view,
            console=self.console,
            refresh_per_second=REFRESH_PER_SECOND,
            redirect_stdout=False,
            redirect_stderr=False,
        )

    def view(self) -> LiveView:
        """The view of the state now."""
        return LiveView(self.title, self.state.progress(self.clock()))

    def attach(self, session: zenoh.Session) -> None:
        """Subscribe on ``session`` (the run's own; the subscribers end with it)."""
        self._subscribers += [
            session.declare_subscriber(
                keys.FIPA_ALL, lambda s: self.state.communicates(str(s.key_expr), s.payload.to_bytes())
            ),
            session.declare_subscriber(
                keys.state_key("ag_ex"), lambda s: self.state.robot_state(s.payload.to_bytes(), self.clock())
            ),
            session.liveliness().declare_subscriber(keys.ALIVE_ALL, self._on_alive, history=True),
        ]

    def _on_alive(self, sample: zenoh.Sample) -> None:
        agent = keys.alive_agent(str(sample.key_expr))
        if agent is not None:
            self.state.alive(agent, sample.kind == zenoh.SampleKind.PUT)

    def line(self, text: str) -> None:
        """Print ``text`` above the view, as it is (no rich markup); the view below is drawn
        anew with it, so that it is never older than the last line."""
        if self._live.is_started:
            self._live.refresh()
        self.console.print(text, markup=False, highlight=False, soft_wrap=True)

    def __enter__(self) -> LiveWatch:
        self.state.started = self.clock()  # the run's clock starts with the view
        self._live.start()
        return self

    def __exit__(
        self, kind: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self._live.refresh()
        self._live.stop()
