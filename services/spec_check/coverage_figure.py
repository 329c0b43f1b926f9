"""The figure of ``roco spec coverage``: the agent graph with each channel coloured by the share
of its items exercised, each interaction protocol's state machine and each agent's FSM with
each edge coloured by how often it was taken (red, dashed: never), drawn with matplotlib's
object-oriented API (no pyplot, no Graphviz) as SVG or PNG.

A protocol's panel adds up its transitions over every channel that speaks it (the text output
gives them per channel); not-understood and time-outs, which leave every state, are counted in
its title rather than drawn. :func:`panels` returns exactly the data drawn (tested);
:func:`write_figure` draws it.
"""

from __future__ import annotations

import math
import re
from collections import Counter, defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from services.report.model import CoverageSummary
from services.spec_check.coverage import Coverage, Item

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

NEVER = "#d62728"
PARTLY = "#ff9f1c"
_EDGE = re.compile(r"^(?P<source>\S+) -(?P<label>[IP]: [^>]+?)-> (?P<target>\S+)$")
_ARC = re.compile(r"^(?P<source>\S+) -> (?P<target>\S+)(?: \((?P<label>.*)\))?$")


@dataclass
class Panel:
    """One graph to draw: ``title``, ``nodes`` in layout order with their (x, y), and
    ``edges`` (source, target) → [(label, count)]; ``initial`` the initial node (None: no
    initial arrow, as the agent graph); ``undirected`` for the agent graph."""

    title: str
    nodes: dict[str, tuple[float, float]] = field(default_factory=dict)
    edges: dict[tuple[str, str], list[tuple[str, int]]] = field(default_factory=lambda: defaultdict(list))
    initial: str | None = None
    undirected: bool = False


def _layered(initial: str, edges: list[tuple[str, str]], nodes: list[str]) -> dict[str, tuple[float, float]]:
    """Nodes placed by their distance (in edges) from ``initial``: x the distance, y spread
    within it; a node not reached goes one layer past the last."""
    depth = {initial: 0}
    todo = [initial]
    while todo:
        node = todo.pop(0)
        for source, target in edges:
            if source == node and target not in depth:
                depth[target] = depth[node] + 1
                todo.append(target)
    last = max(depth.values(), default=0) + 1
    layers: dict[int, list[str]] = defaultdict(list)
    for n in nodes:
        layers[depth.get(n, last)].append(n)
    out = {}
    for x, members in layers.items():
        for i, n in enumerate(members):
            out[n] = (float(x), (len(members) - 1) / 2 - i)
    return out


def _protocol_panel(cov: Coverage, protocol: str, items: list[Item]) -> Panel:
    counts: Counter[tuple[str, str, str]] = Counter()
    side: Counter[str] = Counter()
    for item in items:
        m = _EDGE.match(item.name)
        if item.kind == "transition" and m:
            counts[(m["source"], m["target"], m["label"])] += cov.counts[item]
        elif item.kind in ("not-understood", "time-out"):
            side[item.kind] += cov.counts[item]
    channels = sorted({i.group.split()[0] for i in items})
    title = (
        f"{protocol} ({', '.join(channels)}): not-understood ×{side['not-understood']}, "
        f"time-outs ×{side['time-out']}"
    )
    panel = Panel(title, initial="start")
    for (source, target, label), n in counts.items():
        panel.edges[(source, target)].append((label, n))
    nodes = list(dict.fromkeys(n for pair in panel.edges for n in pair))
    panel.nodes = _layered("start", list(panel.edges), nodes)
    return panel


def _fsm_panel(cov: Coverage, agent: str, items: list[Item]) -> Panel:
    declared = cov.fsm_of[agent]
    panel = Panel(f"{agent} FSM", initial=declared.initial)
    for item in items:
        m = _ARC.match(item.name)
        if item.kind == "arc" and m:
            panel.edges[(m["source"], m["target"])].append((m["label"] or "", cov.counts[item]))
    visits = {i.name.removeprefix("state "): cov.counts[i] for i in items if i.kind == "state"}
    panel.nodes = _layered(declared.initial, list(panel.edges), list(declared.states))
    panel.title += " (entered: " + ", ".join(f"{s} ×{n}" for s, n in visits.items()) + ")"
    return panel


def _agent_panel(cov: Coverage) -> Panel:
    panel = Panel("agents and channels: items exercised per channel", undirected=True)
    ends = cov.channel_ends
    names = list(dict.fromkeys(n for pair in ends.values() for n in pair))
    for i, name in enumerate(names):
        angle = 2 * math.pi * i / max(len(names), 1) + math.pi / 2
        panel.nodes[name] = (math.cos(angle), math.sin(angle))
    for channel, pair in ends.items():
        mine = [i for i in cov.items if i.group.split()[0] == channel]
        done = sum(1 for i in mine if cov.counts[i])
        panel.edges[pair].append((f"{channel} {done}/{len(mine)}", done if done == len(mine) else -done))
    return panel


def panels(cov: Coverage) -> list[Panel]:
    """The agent graph, one panel per interaction protocol, one per agent whose FSM is known."""
    by_protocol: dict[str, list[Item]] = defaultdict(list)
    out = [_agent_panel(cov)]
    fsms = []
    for group, items in cov.groups().items():
        if group in cov.fsm_of:
            fsms.append(_fsm_panel(cov, group, items))
        else:
            by_protocol[group.split(" ", 1)[1]].extend(items)
    out += [_protocol_panel(cov, p, items) for p, items in by_protocol.items()]
    return out + fsms


# ---------------------------------------------------------------------------------------------
# drawing


def _colour(counts: list[int], scale: float) -> str:
    from matplotlib import colormaps

    if all(n == 0 for n in counts):
        return NEVER
    if any(n <= 0 for n in counts):
        return PARTLY
    level = 0.35 + 0.65 * math.log1p(min(counts)) / scale
    r, g, b, _ = colormaps["Blues"](min(level, 1.0))
    return f"#{int(r * 255):02x}{int(g * 255):02x}{int(b * 255):02x}"


def _draw_edge(
    ax: Axes, panel: Panel, ends: tuple[str, str], labels: list[tuple[str, int]], scale: float
) -> None:
    """One edge of ``panel`` (a self-loop as a note above its node), coloured by its counts."""
    from matplotlib.patches import FancyArrowPatch

    colour = _colour([n for _, n in labels], scale)
    text = "\n".join(label if panel.undirected else f"{label} ×{max(n, 0)}" for label, n in labels)
    (x1, y1), (x2, y2) = panel.nodes[ends[0]], panel.nodes[ends[1]]
    if ends[0] == ends[1]:
        ax.annotate(
            f"↻ {text}",
            (x1, y1),
            xytext=(0, 14),
            textcoords="offset points",
            ha="center",
            fontsize=6,
            color=colour,
        )
        return
    ax.add_patch(
        FancyArrowPatch(
            (x1, y1),
            (x2, y2),
            arrowstyle="-" if panel.undirected else "-|>",
            mutation_scale=8,
            connectionstyle="arc3,rad=0.0" if panel.undirected else "arc3,rad=0.15",
            color=colour,
            linestyle="--" if colour == NEVER else "-",
            linewidth=1.2,
            shrinkA=14,
            shrinkB=14,
        )
    )
    ax.text((x1 + x2) / 2, (y1 + y2) / 2 + 0.08, text, fontsize=5.5, ha="center", va="bottom", color=colour)


def _draw(ax: Axes, panel: Panel, scale: float) -> None:
    ax.set_title(panel.title, fontsize=8, wrap=True)
    ax.set_axis_off()
    for ends, labels in panel.edges.items():
        _draw_edge(ax, panel, ends, labels, scale)
    for name, (x, y) in panel.nodes.items():
        ax.text(
            x,
            y,
            name,
            fontsize=7,
            ha="center",
            va="center",
            bbox={"boxstyle": "round", "fc": "#eef4ff", "ec": "#124", "lw": 0.8},
        )
    xs = [p[0] for p in panel.nodes.values()] or [0.0]
    ys = [p[1] for p in panel.nodes.values()] or [0.0]
    ax.set_xlim(min(xs) - 0.6, max(xs) + 0.6)
    ax.set_ylim(min(ys) - 0.6, max(ys) + 0.6)


def draw(cov: Coverage) -> Figure:
    """The figure of ``cov``: :func:`panels` in a grid, three wide."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    drawn = panels(cov)
    cols = 3
    rows = math.ceil(len(drawn) / cols)
    fig = Figure(figsize=(6.0 * cols, 4.2 * rows), layout="constrained")
    FigureCanvasAgg(fig)
    fig.suptitle(
        f"Coverage of the {cov.spec} specification: {cov.exercised} of {len(cov.items)} items "
        f"({100 * cov.share:.1f} %); edge colour: times taken (blue, log), some never (orange), never (red)",
        fontsize=10,
    )
    scale = math.log1p(max([n for n in cov.counts.values()] or [1]))
    for i, panel in enumerate(drawn):
        _draw(fig.add_subplot(rows, cols, i + 1), panel, max(scale, 1.0))
    return fig


def write_figure(cov: Coverage, path: Path) -> None:
    """Draw ``cov`` to ``path``, SVG or PNG by its suffix (SVG for any other). Raises OSError
    when it cannot be written."""
    fig = draw(cov)
    fig.savefig(path, format="png" if path.suffix.lower() == ".png" else "svg", dpi=110)


FIGURE = "coverage.png"
"""The figure's file in the run folder's ``figures/`` (services/report/figures.py's folder)."""
NEVER_SHOWN = 12
"""Items never taken that the report names."""


def report_summary(run_dir: Path) -> CoverageSummary:
    """The coverage of run folder ``run_dir`` alone, for its report: counted
    (:func:`~services.spec_check.coverage.coverage_of`), its figure drawn to
    ``figures/coverage.png`` unless the report draws no figures (services/report/figures.py
    ``figures_wanted``). Raises what :func:`coverage_of` and :func:`write_figure` raise."""
    from services.report.figures import FIGURES_DIR, figures_wanted
    from services.runtime.run_folder import spec_for_run
    from services.spec_check.coverage import KINDS, coverage_of

    cov = coverage_of([run_dir], spec_path=spec_for_run(run_dir))
    drawn = figures_wanted()
    if drawn:
        (run_dir / FIGURES_DIR).mkdir(exist_ok=True)
        write_figure(cov, run_dir / FIGURES_DIR / FIGURE)
    never = [i.key for i in cov.items if not cov.counts[i] and i.kind != "term"]
    notes = [_sentence(n.removeprefix(f"{run_dir}: ")) for n in cov.evidence.notes if "FSM record" in n]
    return CoverageSummary(
        exercised=cov.exercised,
        items=len(cov.items),
        kinds=[(KINDS[k], done, n) for k, (done, n) in cov.by_kind().items()],
        figure=f"{FIGURES_DIR}/{FIGURE}" if drawn else "",
        never=never[:NEVER_SHOWN],
        notes=notes,
    )


def _sentence(text: str) -> str:
    return text[:1].upper() + text[1:] + ("" if text.endswith(".") else ".")
