"""The live view's look: one :class:`~services.live.state.Progress` as a rich panel of
labelled rows (command, plan, step with a bar of its place in the plan, a_ta's state,
agents, time, loop, and the last notice to the person once there is one)."""

from __future__ import annotations

from rich.console import Group, RenderableType
from rich.panel import Panel
from rich.progress_bar import ProgressBar
from rich.table import Table
from rich.text import Text

from services.live.state import Progress


def _time(p: Progress) -> Text:
    wall = f"wall {p.wall_s:6.1f} s"
    if p.sim_s is None:
        return Text(f"{wall} · sim not started")
    rate = f"  ({p.sim_rate:.2f} × wall time)" if p.sim_rate is not None else ""
    return Text(f"{wall} · sim {p.sim_s:6.1f} s{rate}")


def _loop(p: Progress) -> Text:
    if p.overrun_share is None:
        return Text("no timing yet", style="dim")
    style = "green" if p.overrun_share <= 0.001 else "yellow" if p.overrun_share <= 0.01 else "red"
    return Text.assemble(
        (f"overruns {100 * p.overrun_share:.3f} %", style), f" ({p.overruns:,} of {p.cycles:,} cycles)"
    )


def _agents(p: Progress) -> Text:
    alive = [a for a in p.expected if a in p.alive]
    text = Text(
        f"{len(alive)} of {len(p.expected)} alive", style="green" if len(alive) == len(p.expected) else "red"
    )
    missing = [a for a in p.expected if a not in p.alive]
    if missing:
        text.append(f"  (not: {', '.join(missing)})", style="red")
    return text


def _step(p: Progress) -> RenderableType:
    if p.step is None:
        return Text("—", style="dim")
    if p.step_place is None:
        return Text(p.step)
    i, n = p.step_place
    grid = Table.grid(padding=(0, 1))
    grid.add_column(no_wrap=True)
    grid.add_column(width=20)
    grid.add_column(overflow="fold")
    grid.add_row(Text(f"{i:2d} of {n}"), ProgressBar(total=n, completed=i, width=20), Text(p.step))
    return grid


class LiveView:
    """The renderable of ``progress`` titled ``title`` (e.g. ``roco run``)."""

    def __init__(self, title: str, progress: Progress) -> None:
        self.title = title
        self.progress = progress

    def rows(self) -> list[tuple[str, RenderableType]]:
        """(label, value) per row, in the order shown."""
        p = self.progress
        if p.command is None:
            command: RenderableType = Text("waiting for the agents and a_km's knowledge", style="dim")
        else:
            command = Text(f"#{p.commands} “{p.command}”")
            if p.outcome:
                command.append(f"  → {p.outcome}", style="bold")
        plan: RenderableType = Text("—", style="dim")
        if p.plan is not None:
            kind = "complete" if p.plan.complete else "partial, ends with sensing"
            plan = Text(f"#{p.plan.index} of {p.plan.of} ({kind})")
        rows: list[tuple[str, RenderableType]] = [
            ("command", command),
            ("plan", plan),
            ("step", _step(p)),
            ("a_ta", Text(p.sw_state or "—")),
            ("agents", _agents(p)),
            ("time", _time(p)),
            ("loop", _loop(p)),
        ]
        if p.notice is not None:
            rows.append(("notice", Text(f"{p.notice}  ({p.notices} in all)" if p.notices > 1 else p.notice)))
        return rows

    def __rich__(self) -> RenderableType:
        grid = Table.grid(padding=(0, 2))
        grid.add_column(style="bold cyan", no_wrap=True)
        grid.add_column(overflow="fold")
        for label, value in self.rows():
            grid.add_row(label, value)
        return Panel(Group(grid), title=self.title, title_align="left", border_style="cyan")
