"""The report's figures: PNGs in ``<run>/figures/`` drawn with matplotlib's Agg renderer.

Five figures, after paper §5.7 (the paper's own figures are images this project does not
have, so its published numbers from :mod:`services.report.paper` are drawn as reference lines,
annotations or a second panel, and each caption says so):

============================  =====================================================  ==========
file                          what                                                   paper
============================  =====================================================  ==========
``sizes_over_time.png``       each communicate as a point, size vs arrival time,     Figure 12
                              coloured by channel; planning phases shaded
``bandwidth.png``             kbit/s per channel in 1 s bins from the run start      Figure 13
``size_histogram.png``        distribution of sizes (log bins), the 0.5 kB mark      §5.7 text
``matrix.png``                communicates per receiver (rows) and sender (columns)  Table 8
``timeline.png``              the event timeline as a Gantt chart                    Table 7
============================  =====================================================  ==========

Units: times in s since the run start (arrival at the traffic recorder, see
:mod:`services.report.model`), sizes in bytes of the msgpack communicate on the wire,
bandwidth in kbit/s (1000 bit/s). The functions ``*_series``/``*_points``/``*_rows``/
``*_grid`` return exactly the data a figure draws (tested against the traffic record);
``draw_*`` draw it; :func:`write_figures` writes them all, turning a failure to draw one
figure into a note. matplotlib is imported only when a figure is drawn, and only its
object-oriented API is used (``matplotlib.figure.Figure`` on a ``FigureCanvasAgg``): no
pyplot, no global backend switch.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from services.report import paper
from services.report.load import Message, RunData
from services.report.model import AgentMatrix, Event, PlanPhase, Report
from services.report.stats import SMALL_BYTES
from shared.settings import Settings

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.axis import Axis
    from matplotlib.figure import Figure

FIGURES_DIR = "figures"
"""Folder of the PNGs inside the run folder; report.md links them relatively."""

BIN_S = 1.0
"""Bin width (s) of the bandwidth figure, as the paper's Figure 13."""

HIST_BINS_PER_DECADE = 8
"""Logarithmic size bins of the histogram: this many per factor of ten."""

DPI = 110

CHANNEL_COLOURS: dict[str, str] = {
    "C1": "#1f77b4",
    "C2": "#ff7f0e",
    "C3": "#2ca02c",
    "C4": "#d62728",
    "C5": "#9467bd",
    "C6": "#8c564b",
}
"""One colour per channel, the same in every figure; other channel names are grey."""

OTHER_COLOUR = "#7f7f7f"
PAPER_COLOUR = "#444444"


def channel_colour(channel: str) -> str:
    return CHANNEL_COLOURS.get(channel, OTHER_COLOUR)


def channel_label(channel: str) -> str:
    """``C4 a_pl–a_km`` for a channel of the specification, else the name."""
    ends = paper.CHANNEL_ENDS.get(channel)
    return f"{channel} {ends[0]}–{ends[1]}" if ends else channel


@dataclass(frozen=True)
class FigureFile:
    """One figure written: ``name`` (the file's stem), ``path`` relative to the run folder
    (``figures/<name>.png``, as report.md links it), ``title`` (the image's alt text) and
    ``caption`` (what it shows, how measured, which of the paper's numbers it draws)."""

    name: str
    path: str
    title: str
    caption: str


# ---------------------------------------------------------------------------------------------
# The data behind each figure


def _channel_order(channels: set[str]) -> list[str]:
    known = [c for c in paper.CHANNEL_ENDS if c in channels]
    return known + sorted(channels - set(paper.CHANNEL_ENDS))


def size_points(messages: Sequence[Message]) -> dict[str, tuple[list[float], list[int]]]:
    """Figure 12's points: per channel (C1..C6 in order, then others; only channels with
    traffic) the arrival times (s since run start) and sizes (bytes) of its communicates, in
    arrival order."""
    out: dict[str, tuple[list[float], list[int]]] = {}
    for m in messages:
        times, sizes = out.setdefault(m.channel or "?", ([], []))
        times.append(m.t)
        sizes.append(m.rec.size)
    return {c: out[c] for c in _channel_order(set(out))}


@dataclass(frozen=True)
class Bandwidth:
    """Figure 13's lines: ``starts`` the start of each bin (s since run start; bin ``k`` is
    ``[k·bin_s, (k+1)·bin_s)``), ``kbps[channel][k]`` the bytes of that channel's
    communicates arriving in bin ``k``, times 8 / 1000 / ``bin_s`` (kbit/s)."""

    bin_s: float
    starts: list[float]
    kbps: dict[str, list[float]]

    def peak(self, channel: str) -> tuple[float, float] | None:
        """(bin start, kbit/s) of ``channel``'s busiest bin (the first of equals), or None."""
        series = self.kbps.get(channel)
        if not series:
            return None
        k = max(range(len(series)), key=lambda i: (series[i], -i))
        return self.starts[k], series[k]


def bandwidth_series(messages: Sequence[Message], bin_s: float = BIN_S) -> Bandwidth:
    """Bandwidth per channel in bins of ``bin_s`` seconds from the run start to the last
    communicate (only channels with traffic; a communicate before the run start counts in bin
    0)."""
    if not messages:
        return Bandwidth(bin_s, [], {})
    n = int(max(m.t for m in messages) // bin_s) + 1
    totals: dict[str, list[int]] = {}
    for m in messages:
        k = max(0, int(m.t // bin_s))
        totals.setdefault(m.channel or "?", [0] * n)[k] += m.rec.size
    kbps = {c: [b * 8 / 1000 / bin_s for b in totals[c]] for c in _channel_order(set(totals))}
    return Bandwidth(bin_s, [k * bin_s for k in range(n)], kbps)


@dataclass(frozen=True)
class SizeHistogram:
    """The size distribution: ``edges`` (bytes, logarithmic, ``HIST_BINS_PER_DECADE`` a
    decade, aligned so that 500 B is an edge: ``500 · 10^(k / HIST_BINS_PER_DECADE)``; bin ``i``
    is ``[edges[i], edges[i+1])``), ``counts`` per bin;
    ``count`` communicates of which ``under`` are below ``threshold`` bytes (500: the paper's
    0.5 kB)."""

    edges: list[float]
    counts: list[int]
    count: int
    under: int
    threshold: int = SMALL_BYTES

    @property
    def share_under(self) -> float | None:
        return self.under / self.count if self.count else None


def _bin(size: int, guess: int, edges: Sequence[float]) -> int:
    """The bin of ``size``, from the ``guess`` its logarithm gives: a size equal to an edge
    belongs to the bin it opens (the float edge guarded)."""
    i = guess
    while i > 0 and size < edges[i]:
        i -= 1
    while i < len(edges) - 2 and size >= edges[i + 1]:
        i += 1
    return i


def size_histogram(messages: Sequence[Message]) -> SizeHistogram:
    """The histogram of the communicates' sizes (empty edges when there are none)."""
    sizes = [m.rec.size for m in messages]
    under = sum(1 for s in sizes if s < SMALL_BYTES)
    if not sizes:
        return SizeHistogram([], [], 0, 0)
    per = HIST_BINS_PER_DECADE

    def level(size: int) -> int:
        return math.floor(math.log10(max(size, 1) / SMALL_BYTES) * per)

    lo, hi = level(min(sizes)), level(max(sizes)) + 1
    edges = [SMALL_BYTES * 10 ** (k / per) for k in range(lo, hi + 1)]
    counts = [0] * (len(edges) - 1)
    for s in sizes:
        counts[_bin(s, level(s) - lo, edges)] += 1
    return SizeHistogram(edges, counts, len(sizes), under)


@dataclass(frozen=True)
class MatrixGrid:
    """A Table 8 grid: ``rows`` receivers, ``cols`` senders, ``cells[i][j]`` communicates
    from ``cols[j]`` to ``rows[i]``; ``received``/``sent`` the row and column sums."""

    rows: list[str]
    cols: list[str]
    cells: list[list[int]]
    received: list[int]
    sent: list[int]

    @property
    def total(self) -> int:
        return sum(self.received)


def _grid(agents: list[str], table: dict[str, dict[str, int]]) -> MatrixGrid:
    cells = [[table.get(r, {}).get(s, 0) for s in agents] for r in agents]
    return MatrixGrid(
        agents,
        agents,
        cells,
        [sum(row) for row in cells],
        [sum(cells[i][j] for i in range(len(agents))) for j in range(len(agents))],
    )


def matrix_grid(matrix: AgentMatrix) -> MatrixGrid:
    """This run's Table 8 as a grid (rows and columns in ``matrix.agents`` order)."""
    return _grid(list(matrix.agents), matrix.cells)


def paper_matrix_grid() -> MatrixGrid:
    """The paper's Table 8 as a grid on the same agents (its missing a_hi row as zeros)."""
    return _grid(list(paper.AGENTS), paper.TABLE8)


@dataclass(frozen=True)
class GanttRow:
    """One Table 7 row as drawn: ``label``, its ``spans`` ((start, end) in s; start == end
    for an instant) and the ``channels`` used (the first one gives the colour)."""

    label: str
    spans: list[tuple[float, float]]
    channels: list[str] = field(default_factory=list)


LABEL_CHARS = 72
"""Gantt labels longer than this are cut (the full text is in the Table 7 section)."""

_STEP = re.compile(r" \(step .*\)$")


def _label(text: str) -> str:
    text = _STEP.sub("", text)
    return text if len(text) <= LABEL_CHARS else text[: LABEL_CHARS - 1] + "…"


def gantt_rows(events: Sequence[Event]) -> list[GanttRow]:
    """This run's timeline rows, in the order of the Table 7 section (sorted by start). The
    plan step in parentheses is left out of the label, long labels are cut."""
    return [
        GanttRow(_label(e.text), [(e.start, e.end if e.end is not None else e.start)], list(e.channels))
        for e in events
    ]


def _paper_span(text: str) -> tuple[float, float]:
    a, _, b = text.strip().partition("–")
    return float(a), float(b or a)


def paper_gantt_rows() -> list[GanttRow]:
    """The paper's Table 7 as rows: ``"293–315, 674–680"`` gives two spans; ``"—"`` channels
    none."""
    rows = []
    for when, text, channels in paper.TABLE7:
        spans = [_paper_span(part) for part in when.split(",")]
        chans = [c.strip() for c in channels.split(",") if c.strip().startswith("C")]
        rows.append(GanttRow(_label(text), spans, chans))
    return rows


# ---------------------------------------------------------------------------------------------
# Drawing


def _figure(width: float, height: float) -> Figure:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), dpi=DPI, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def byte_tick(x: float, pos: int | None = None) -> str:
    """A size axis tick: ``200 B``, ``1 kB``, ``20 kB`` (1 kB = 1000 B, as the paper)."""
    return f"{x / 1000:g} kB" if x >= 1000 else f"{x:g} B"


def _bytes_axis(axis: Axis) -> None:
    """Log-scale size axis with ticks at 1, 2 and 5 times the powers of ten, in B or kB."""
    from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

    axis.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
    axis.set_major_formatter(FuncFormatter(byte_tick))
    axis.set_minor_formatter(NullFormatter())


def _planning_spans(ax: Axes, plans: Sequence[PlanPhase], x_max: float) -> None:
    """Shade each planning phase (C3 request → answer), at least 0.4 % of the axis wide."""
    for i, p in enumerate(plans):
        end = p.received_t if p.received_t is not None else p.c4_last_t
        if end is None:
            end = p.requested_t
        width = max(end - p.requested_t, 0.004 * x_max)
        ax.axvspan(
            p.requested_t,
            p.requested_t + width,
            color="#ffd54f",
            alpha=0.35,
            lw=0,
            label="planning (C3 request → plan)" if i == 0 else None,
        )
        ax.annotate(
            f"plan #{p.index}",
            (p.requested_t, 1.0),
            xycoords=("data", "axes fraction"),
            xytext=(2, -12),
            textcoords="offset points",
            fontsize=8,
            color="#8d6e00",
        )


def draw_sizes_over_time(
    points: dict[str, tuple[list[float], list[int]]], plans: Sequence[PlanPhase], share_under: float | None
) -> Figure:
    """Figure 12 of this run: size [B] (log scale) of each communicate against its arrival
    time, one colour per channel, the 0.5 kB line, planning phases shaded."""
    fig = _figure(10.0, 4.8)
    ax = fig.add_subplot()
    x_max = max((max(t) for t, _ in points.values() if t), default=1.0) or 1.0
    _planning_spans(ax, plans, x_max)
    for channel, (times, sizes) in points.items():
        ax.scatter(
            times,
            sizes,
            s=14,
            alpha=0.75,
            color=channel_colour(channel),
            edgecolors="none",
            label=f"{channel_label(channel)} ({len(times)})",
        )
    ours = "—" if share_under is None else f"{100 * share_under:.1f} %"
    ax.axhline(
        SMALL_BYTES,
        color=PAPER_COLOUR,
        ls="--",
        lw=1,
        label=f"0.5 kB: below it {ours} here, {100 * paper.SHARE_UNDER_500:.0f} % in the paper",
    )
    ax.set_yscale("log")
    _bytes_axis(ax.yaxis)
    x_min = min((min(t) for t, _ in points.values() if t), default=0.0)
    ax.set_xlim(left=min(x_min, 0.0) - 0.01 * x_max)  # points at t = 0 drawn whole
    ax.set_xlabel("arrival time since the run start [s]")
    ax.set_ylabel("size on the wire (log scale)")
    ax.set_title("Size of each communicate over time (cf. paper Figure 12)")
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0)
    return fig


def draw_bandwidth(bw: Bandwidth, plans: Sequence[PlanPhase]) -> Figure:
    """Figure 13 of this run: kbit/s per channel in ``bw.bin_s`` bins (steps), with the paper's
    C4 numbers (peak 150 kbit/s at the end of planning #1, mean 32 kbit/s) as lines."""
    fig = _figure(10.0, 4.8)
    ax = fig.add_subplot()
    x_max = (bw.starts[-1] + bw.bin_s) if bw.starts else 1.0
    _planning_spans(ax, plans, x_max)
    edges = [*bw.starts, x_max]
    for channel, series in bw.kbps.items():
        peak = bw.peak(channel)
        peak_text = f" (peak {peak[1]:.1f})" if peak else ""
        ax.stairs(
            series,
            edges,
            color=channel_colour(channel),
            lw=1.4,
            label=f"{channel_label(channel)}{peak_text}",
        )
    p1 = paper.PLANS[0]
    if p1.peak_kbps is not None:
        ax.axhline(
            p1.peak_kbps,
            color=channel_colour("C4"),
            ls="--",
            lw=1,
            alpha=0.7,
            label=f"paper: C4 peak {p1.peak_kbps:.0f} kbit/s (end of planning #1, Fig. 13)",
        )
    ax.axhline(
        p1.mean_kbps,
        color=channel_colour("C4"),
        ls=":",
        lw=1.2,
        alpha=0.7,
        label=f"paper: C4 mean {p1.mean_kbps:.0f} kbit/s over planning #1 and #2",
    )
    ax.set_xlim(0, x_max)
    ax.set_ylim(bottom=0)
    ax.set_xlabel("time since the run start [s]")
    ax.set_ylabel(f"bandwidth [kbit/s], {bw.bin_s:g} s bins")
    ax.set_title(f"Bandwidth per channel, {bw.bin_s:g} s bins (cf. paper Figure 13)")
    ax.grid(True, alpha=0.3)
    ax.legend(
        fontsize=8,
        loc="upper left",
        bbox_to_anchor=(1.01, 1.0),
        borderaxespad=0,
        title="channel (peak kbit/s)",
    )
    return fig


def draw_size_histogram(h: SizeHistogram, mean_bytes: float | None) -> Figure:
    """The size distribution on logarithmic bins, the 0.5 kB mark and the shares below it
    (this run and the paper's 86 %), the means (this run and the paper's 654 B)."""
    fig = _figure(8.0, 4.5)
    ax = fig.add_subplot()
    ax.stairs(h.counts, h.edges, fill=True, color="#4c72b0", alpha=0.85, label="this run")
    ax.set_xscale("log")
    _bytes_axis(ax.xaxis)
    ax.axvline(h.threshold, color=PAPER_COLOUR, ls="--", lw=1.2, label="0.5 kB")
    if mean_bytes is not None:
        ax.axvline(mean_bytes, color="#4c72b0", ls=":", lw=1.2, label=f"mean here: {mean_bytes:.0f} B")
    ax.axvline(paper.MEAN_SIZE_B, color="#c44e52", ls=":", lw=1.2, label=f"paper mean: {paper.MEAN_SIZE_B} B")
    share = h.share_under
    text = (
        f"below 0.5 kB:\nthis run {100 * share:.1f} % ({h.under} of {h.count})\n"
        f"paper {100 * paper.SHARE_UNDER_500:.0f} % (of {paper.COMMUNICATES})"
        if share is not None
        else "no communicates"
    )
    ax.text(
        0.98,
        0.97,
        text,
        transform=ax.transAxes,
        ha="right",
        va="top",
        fontsize=9,
        bbox={"boxstyle": "round", "fc": "white", "ec": "#bbbbbb"},
    )
    ax.set_xlabel("size on the wire (log scale)")
    ax.set_ylabel("communicates")
    ax.set_title(f"Distribution of communicate sizes ({HIST_BINS_PER_DECADE} bins per decade)")
    ax.grid(True, axis="y", alpha=0.3)
    ax.legend(fontsize=8, loc="center right")
    return fig


def _draw_grid(ax: Axes, grid: MatrixGrid, title: str, vmax: int) -> None:
    import numpy as np
    from matplotlib.colors import LogNorm

    data = np.ma.masked_equal(np.array(grid.cells, dtype=float), 0)
    ax.imshow(data, cmap="Blues", norm=LogNorm(vmin=1, vmax=max(vmax, 2)), aspect="equal")
    for i, row in enumerate(grid.cells):
        for j, n in enumerate(row):
            if n:
                dark = math.log(n) > 0.6 * math.log(max(vmax, 2))
                ax.text(
                    j, i, str(n), ha="center", va="center", fontsize=9, color="white" if dark else "black"
                )
    ax.set_xticks(range(len(grid.cols)), [f"{c}\n{s}" for c, s in zip(grid.cols, grid.sent, strict=True)])
    ax.set_yticks(
        range(len(grid.rows)), [f"{r} ({n})" for r, n in zip(grid.rows, grid.received, strict=True)]
    )
    ax.tick_params(labelsize=8, length=0)
    ax.set_xticks([x - 0.5 for x in range(1, len(grid.cols))], minor=True)
    ax.set_yticks([y - 0.5 for y in range(1, len(grid.rows))], minor=True)
    ax.grid(True, which="minor", color="#dddddd", lw=0.8)
    ax.set_xlabel("sender (sent)")
    ax.set_ylabel("receiver (received)")
    ax.set_title(f"{title}: {grid.total} communicates", fontsize=10)


def draw_matrix(ours: MatrixGrid, theirs: MatrixGrid) -> Figure:
    """Table 8 as two heat maps (this run, the paper), log colour scale, counts written in the
    cells, row sums (received) beside the receivers and column sums (sent) under the senders."""
    fig = _figure(11.0, 5.2)
    left, right = fig.subplots(1, 2)
    vmax = max([n for row in ours.cells + theirs.cells for n in row], default=1)
    _draw_grid(left, ours, "This run", vmax)
    _draw_grid(right, theirs, "Paper, Table 8 (it has no a_hi row)", vmax)
    fig.suptitle("Communicates per receiver (rows) and sender (columns), paper Table 8 layout")
    return fig


def _draw_gantt(ax: Axes, rows: Sequence[GanttRow], title: str, x_max: float) -> None:
    for y, row in enumerate(rows):
        colour = channel_colour(row.channels[0]) if row.channels else OTHER_COLOUR
        for start, end in row.spans:
            if end - start > 0.002 * x_max:
                ax.barh(y, end - start, left=start, height=0.6, color=colour, alpha=0.85)
            else:
                ax.plot([start], [y], marker="D", ms=5, color=colour, ls="none")
    ax.set_yticks(range(len(rows)), [r.label for r in rows])
    ax.tick_params(axis="y", labelsize=7)
    ax.set_ylim(len(rows) - 0.5, -0.5)
    ax.set_xlim(0, x_max)
    ax.grid(True, axis="x", alpha=0.3)
    ax.set_xlabel("time [s]")
    ax.set_title(title, fontsize=10, loc="left")


def draw_timeline(ours: Sequence[GanttRow], theirs: Sequence[GanttRow]) -> Figure:
    """Table 7 as Gantt charts: this run above, the paper's below (each its own time axis);
    bars are spans, diamonds instants, coloured by the first channel used (grey: none)."""
    from matplotlib.lines import Line2D

    heights = [max(len(ours), 1) * 0.27 + 0.9, len(theirs) * 0.27 + 0.9]
    fig = _figure(12.0, sum(heights) + 0.8)
    top, bottom = fig.subplots(2, 1, height_ratios=heights)
    ours_max = max((end for r in ours for _, end in r.spans), default=1.0)
    theirs_max = max(end for r in theirs for _, end in r.spans)
    _draw_gantt(top, ours, "This run (s since the run start)", ours_max * 1.02 or 1.0)
    _draw_gantt(bottom, theirs, "Paper, Table 7 (s since the start of its log)", theirs_max * 1.02)
    used = sorted({r.channels[0] for r in [*ours, *theirs] if r.channels})
    handles = [Line2D([], [], color=channel_colour(c), lw=6, label=channel_label(c)) for c in used]
    handles.append(Line2D([], [], color=OTHER_COLOUR, lw=6, label="no channel (robot action)"))
    handles.append(Line2D([], [], color="black", marker="D", ls="none", label="instant"))
    fig.legend(handles=handles, loc="outside lower center", ncols=4, fontsize=8)
    fig.suptitle("Event timeline (paper Table 7 layout), coloured by the first channel used")
    return fig


# ---------------------------------------------------------------------------------------------
# Writing


@dataclass(frozen=True)
class _Spec:
    name: str
    title: str
    caption: str
    draw: Callable[[], Figure]


def _specs(run: RunData, report: Report) -> list[_Spec]:
    messages = run.messages
    specs: list[_Spec] = []
    if messages:
        p1 = paper.PLANS[0]
        specs += [
            _Spec(
                "sizes_over_time",
                "Size of each communicate over time",
                "Each communicate is a point: its size on the wire (bytes of the msgpack "
                "communicate, log scale) against its arrival time at the traffic recorder (s "
                "since the run start), coloured by channel; planning phases (C3 request → plan) "
                "shaded. Paper: Figure 12 (not reproduced); its 0.5 kB mark and 86 % share are "
                "drawn as the dashed line and in the legend.",
                lambda: draw_sizes_over_time(
                    size_points(messages), report.plans, report.sizes.share_under_500
                ),
            ),
            _Spec(
                "bandwidth",
                "Bandwidth per channel",
                f"Bytes of each channel's communicates arriving in {BIN_S:g} s bins from the run "
                "start, × 8 / 1000 (kbit/s). Paper: Figure 13 (not reproduced); its C4 peak of "
                f"{p1.peak_kbps:.0f} kbit/s (end of planning #1) and C4 mean of {p1.mean_kbps:.0f} "
                "kbit/s are drawn as reference lines. The peaks here may differ from the planning "
                "table's, whose 1 s bins start at each plan request.",
                lambda: draw_bandwidth(bandwidth_series(messages), report.plans),
            ),
            _Spec(
                "size_histogram",
                "Distribution of communicate sizes",
                f"Sizes on the wire in logarithmic bins ({HIST_BINS_PER_DECADE} a decade). Paper "
                f"(§5.7, no figure): {100 * paper.SHARE_UNDER_500:.0f} % below 0.5 kB and a mean "
                f"of {paper.MEAN_SIZE_B} B, drawn as annotation and line.",
                lambda: draw_size_histogram(size_histogram(messages), report.sizes.mean_bytes),
            ),
        ]
    if report.matrix.total:
        specs.append(
            _Spec(
                "matrix",
                "Communicates per receiver and sender",
                "Counts from the traffic record (a communicate with several receivers counts "
                "once per receiver), log colour scale; beside it the paper's Table 8 numbers "
                "on the same agents.",
                lambda: draw_matrix(matrix_grid(report.matrix), paper_matrix_grid()),
            )
        )
    if report.events:
        specs.append(
            _Spec(
                "timeline",
                "Event timeline",
                "The rows of the table above as bars (spans) and diamonds (instants), times "
                "of arrival at the recorder; below, the paper's Table 7 rows drawn the same way "
                "on its own time axis.",
                lambda: draw_timeline(gantt_rows(report.events), paper_gantt_rows()),
            )
        )
    return specs


def figures_wanted() -> bool:
    """Whether a report draws its figures (setting ``report_figures``, default on), read now.
    Off, report.md is written without them, and says so (:data:`NOT_DRAWN`)."""
    return Settings.from_env(only=("report_figures",)).report_figures


NOT_DRAWN = f"figures not drawn: {Settings.env_name('report_figures')}=0"
"""The report's note when :func:`figures_wanted` is off."""


def write_figures(run: RunData, report: Report, run_dir: Path) -> tuple[list[FigureFile], list[str]]:
    """Draw the figures that have data into ``run_dir/figures/`` (PNG); returns the figures
    written and notes for those that could not be drawn (a failed figure's old file, if
    any, is removed so that no stale image is linked). Never raises for a figure."""
    out_dir = Path(run_dir) / FIGURES_DIR
    written: list[FigureFile] = []
    notes: list[str] = []
    specs = _specs(run, report)
    if not specs:
        return written, notes
    try:
        out_dir.mkdir(exist_ok=True)
    except OSError as exc:
        return written, [f"figures not drawn: cannot create {out_dir} ({exc})"]
    for spec in specs:
        path = out_dir / f"{spec.name}.png"
        try:
            fig = spec.draw()
            fig.savefig(path, dpi=DPI)
        except Exception as exc:  # any failure of one figure becomes a note
            notes.append(f"figure {path.name} not drawn: {type(exc).__name__}: {exc}")
            path.unlink(missing_ok=True)
            continue
        written.append(FigureFile(spec.name, f"{FIGURES_DIR}/{spec.name}.png", spec.title, spec.caption))
    return written, notes
