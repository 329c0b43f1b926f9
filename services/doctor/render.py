"""``roco doctor``'s output: the checks grouped by what they serve and the settings, each as
plain lines (a pipe, a log) or a rich table (a terminal), and the verdict line."""

from __future__ import annotations

from collections.abc import Sequence

from rich.console import Console
from rich.table import Table
from rich.text import Text

from services.doctor.model import Check, Use, camera_ready, run_ready
from services.doctor.settings import Reading

WORD = {True: "found", False: "not found"}


def _status(check: Check) -> str:
    return "—" if check.informative else WORD[check.found]


def lines(checks: Sequence[Check]) -> list[str]:
    """One line per check (``use``, status, name, detail), and below a missing one its
    ``how to get it:`` line."""
    out: list[str] = []
    width = max((len(c.name) for c in checks), default=0)
    for use in Use:
        group = [c for c in checks if c.use is use]
        if not group:
            continue
        out.append(f"{use.value}:")
        for c in group:
            out.append(f"  {_status(c):9s}  {c.name:{width}s}  {c.detail}")
            if c.missing and c.how:
                out.append(f"  {'':9s}  {'':{width}s}  how to get it: {c.how}")
    return out


def table(checks: Sequence[Check]) -> Table:
    """The same as :func:`lines`, as a rich table (colour: green found, red missing for
    ``roco run``, yellow missing otherwise)."""
    t = Table(show_header=True, header_style="bold", expand=False, pad_edge=False, box=None)
    t.add_column("for", style="dim", no_wrap=True)
    t.add_column("", no_wrap=True)
    t.add_column("item", no_wrap=True)
    t.add_column("found / how to get it")
    for use in Use:
        for i, c in enumerate(c for c in checks if c.use is use):
            t.add_row(use.value if i == 0 else "", Text(_status(c), style=_colour(c)), c.name, _found_text(c))
    return t


def _colour(c: Check) -> str:
    """A row's colour: dim informative, green found, red missing for ``roco run``, yellow
    missing otherwise."""
    if c.informative:
        return "dim"
    if c.found:
        return "green"
    return "red" if c.use is Use.RUN else "yellow"


def _found_text(c: Check) -> Text:
    """A row's last cell: the detail, and how to get a missing item."""
    text = Text(c.detail)
    if c.missing and c.how:
        text.append(f"\nhow to get it: {c.how}", style="bold")
    return text


CAMERA_NEED = "a GL context for the head camera (EGL or OSMesa; ROCO_PERCEPTION=truth runs without)"


TRUTH_BY_DEFAULT = " (perceiving with the ground truth: no GL library for the head camera)"


def verdict(checks: Sequence[Check], camera: bool = True, truth_by_default: bool = False) -> str:
    """The last line: whether ``roco run`` has what it needs (with ``camera``, a GL context
    for the head camera too: ``run_ready``), and which other uses lack something.
    ``truth_by_default``: the robot will perceive with the ground truth because no GL library
    is installed (velma/executor/capture.py ``perception_mode``), which the line says."""
    others = _others(checks, camera)
    if run_ready(checks, camera):
        how = TRUTH_BY_DEFAULT if truth_by_default else ""
        return f"roco: roco run has everything it needs{how}{others}"
    needed = [c.name for c in checks if c.missing and c.use is Use.RUN]
    needed += [CAMERA_NEED] if camera and not camera_ready(checks) else []
    return f"roco: roco run lacks {', '.join(needed)}{others}"


def compose_verdict(checks: Sequence[Check]) -> str:
    """The last line of ``roco doctor --compose``: that the compose fleet has what it needs, or
    each missing prerequisite (``Use.COMPOSE``) by name."""
    missing = [c.name for c in checks if c.missing and c.use is Use.COMPOSE]
    if not missing:
        return "roco: the compose fleet has everything it needs"
    return f"roco: the compose fleet lacks {', '.join(missing)} (how to get each: above)"


def _lacking(c: Check, camera: bool) -> bool:
    """Whether ``c`` is a missing item of a use other than ``roco run`` (and, with ``camera``,
    other than the head camera's)."""
    return c.missing and c.use is not Use.RUN and not (camera and c.use is Use.CAMERA)


def _others(checks: Sequence[Check], camera: bool) -> str:
    """The verdict's tail: the other uses that lack something, or that none does."""
    lacking = sorted({c.use.value for c in checks if _lacking(c, camera)})
    return f"; not ready: {', '.join(lacking)}" if lacking else "; everything else is here too"


SETTINGS_TITLE = "settings (docs/settings.md):"
UNSET = "default"
"""What the value column says of a setting that is unset (or empty) here."""


def settings_lines(readings: Sequence[Reading]) -> list[str]:
    """A title, then one line per setting: its name, its value here (:data:`UNSET` when
    unset), its default and what it sets; below a value that does not parse, the reason."""
    name_w = max((len(r.name) for r in readings), default=0)
    value_w = max((len(r.value or UNSET) for r in readings), default=0)
    default_w = max((len(r.default or "—") for r in readings), default=0)
    out = [SETTINGS_TITLE]
    for r in readings:
        out.append(
            f"  {r.name:{name_w}s}  {r.value or UNSET:{value_w}s}  {r.default or '—':{default_w}s}  {r.doc}"
        )
        if r.error is not None:
            out.append(f"  {'':{name_w}s}  not valid: {r.error}")
    return out


def settings_table(readings: Sequence[Reading]) -> Table:
    """The same as :func:`settings_lines`, as a rich table (a value that does not parse in red)."""
    t = Table(title=SETTINGS_TITLE, title_justify="left", header_style="bold", box=None, pad_edge=False)
    t.add_column("setting", no_wrap=True)
    t.add_column("here", no_wrap=True)
    t.add_column("default", no_wrap=True)
    t.add_column("what it sets")
    for r in readings:
        here = Text(r.value or UNSET, style="red" if r.error else "" if r.value else "dim")
        doc = Text(r.doc)
        if r.error is not None:
            doc.append(f"\nnot valid: {r.error}", style="bold red")
        t.add_row(r.name, here, r.default or "—", doc)
    return t


def show(checks: Sequence[Check], console: Console, readings: Sequence[Reading] = ()) -> None:
    """Print the checks, then the settings ``readings``, on ``console``: tables on a terminal,
    plain lines otherwise."""
    if console.is_terminal:
        console.print(table(checks))
        if readings:
            console.print(settings_table(readings))
        return
    for line in [*lines(checks), *(settings_lines(readings) if readings else [])]:
        console.print(line, markup=False, highlight=False, soft_wrap=True)
