"""The report's figures (services/report/figures.py): PNGs written into <run>/figures/ and
linked from report.md in their sections, and the data behind each figure checked against the
traffic record of the synthetic pour run (conftest.py: known times and sizes)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest

from services.report import build_report, figures, paper, write_report
from services.report.figures import (
    FIGURES_DIR,
    bandwidth_series,
    byte_tick,
    gantt_rows,
    matrix_grid,
    paper_gantt_rows,
    paper_matrix_grid,
    size_histogram,
    size_points,
)
from services.report.load import load_run
from shared.settings import Settings

STARTED = 1_700_000_000.0
"""conftest.py's run start (run.json ``started``); checked against the run folder below."""

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
SECTIONS = {
    "sizes_over_time": "## 1. Communication statistics",
    "bandwidth": "## 1. Communication statistics",
    "size_histogram": "## 1. Communication statistics",
    "matrix": "## 2. Communicates sent and received",
    "timeline": "## 3. Event timeline",
}


def png_size(path: Path) -> tuple[int, int]:
    """(width, height) in pixels from the PNG's IHDR chunk; asserts the signature."""
    data = path.read_bytes()
    assert data[:8] == PNG_MAGIC and data[12:16] == b"IHDR", path
    return int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")


def section_of(md: str, link: str) -> str:
    """The ``## `` heading of the section in which ``link`` appears."""
    before = md[: md.index(link)]
    return before[before.rindex("\n## ") + 1 :].splitlines()[0]


def times(pour: Any, channel: str) -> list[float]:
    return [r.t - STARTED for r in pour.records if r.channel == channel]


def test_write_report_draws_every_figure_and_links_it_in_its_section(run_dir: Path) -> None:
    md = write_report(run_dir).read_text(encoding="utf-8")
    for name, heading in SECTIONS.items():
        path = run_dir / FIGURES_DIR / f"{name}.png"
        width, height = png_size(path)
        assert 700 <= width <= 1600 and 350 <= height <= 2600, (name, width, height)
        assert path.stat().st_size > 10_000
        link = f"(figures/{name}.png)"
        assert md.count(link) == 1
        assert section_of(md, link).startswith(heading), name
        # the image is followed by its caption: what it shows and how it was measured
        after = md[md.index(link) :].split("\n\n")[1]
        assert after.startswith("*") and ("Paper" in after or "paper" in after), after
    assert sorted(p.name for p in (run_dir / FIGURES_DIR).iterdir()) == sorted(f"{n}.png" for n in SECTIONS)
    assert "None: every file was read completely." in md  # no figure failed


def test_size_points_are_the_recorded_times_and_sizes(run_dir: Path, pour: Any) -> None:
    run = load_run(run_dir)
    assert run.t0 == STARTED
    points = size_points(run.messages)
    assert list(points) == ["C1", "C2", "C3", "C4", "C5", "C6"]
    c4_times, c4_sizes = points["C4"]
    assert c4_times == pytest.approx([12.5, 13.0, 13.5, 14.0, 14.5, 16.0, 27.5, 28.0])
    assert c4_sizes == [r.size for r in pour.records if r.channel == "C4"]
    assert sum(len(t) for t, _ in points.values()) == len(pour.records) == 40
    for channel, (ts, sizes) in points.items():
        assert ts == pytest.approx(times(pour, channel))
        assert sizes == [r.size for r in pour.records if r.channel == channel]


def test_bandwidth_series_bins_bytes_per_second(run_dir: Path, pour: Any) -> None:
    bw = bandwidth_series(load_run(run_dir).messages)
    assert bw.bin_s == 1.0
    assert bw.starts == [float(k) for k in range(45)]  # last communicate at 44.0 s
    size = {(r.channel, round(r.t - STARTED, 1)): r.size for r in pour.records}
    c4 = bw.kbps["C4"]
    assert c4[12] == pytest.approx(size["C4", 12.5] * 8 / 1000)
    assert c4[13] == pytest.approx((size["C4", 13.0] + size["C4", 13.5]) * 8 / 1000)
    assert c4[14] == pytest.approx((size["C4", 14.0] + size["C4", 14.5]) * 8 / 1000)
    assert c4[16] == pytest.approx(size["C4", 16.0] * 8 / 1000)
    assert c4[27] == pytest.approx(size["C4", 27.5] * 8 / 1000)
    assert c4[28] == pytest.approx(size["C4", 28.0] * 8 / 1000)
    assert [k for k, v in enumerate(c4) if v] == [12, 13, 14, 16, 27, 28]
    # the busiest C4 second holds the answer with 20 grasps (14.0 s)
    assert bw.peak("C4") == (14.0, pytest.approx(c4[14]))
    assert size["C4", 14.0] > 3000
    # C2: request 10.0 and agree 10.1 share bin 10; the outcome at 44.0 is the last bin
    assert bw.kbps["C2"][10] == pytest.approx((size["C2", 10.0] + size["C2", 10.1]) * 8 / 1000)
    assert bw.kbps["C2"][44] == pytest.approx(size["C2", 44.0] * 8 / 1000)
    for channel, series in bw.kbps.items():
        recorded = sum(r.size for r in pour.records if r.channel == channel)
        assert sum(series) * 1000 / 8 == pytest.approx(recorded)
    assert bandwidth_series([]).starts == []


def test_size_histogram_has_the_500_byte_edge_and_every_size(run_dir: Path, pour: Any) -> None:
    h = size_histogram(load_run(run_dir).messages)
    sizes = pour.sizes()
    assert h.count == 40 and sum(h.counts) == 40
    small = sum(1 for n in sizes if n < 500)
    assert small >= 30 and h.under == small and h.share_under == pytest.approx(small / 40)
    assert any(math.isclose(e, 500) for e in h.edges)
    assert h.edges[0] <= min(sizes) and max(sizes) < h.edges[-1]
    ratios = [b / a for a, b in zip(h.edges, h.edges[1:], strict=False)]
    assert ratios == pytest.approx([10 ** (1 / figures.HIST_BINS_PER_DECADE)] * len(ratios))
    expected = [sum(1 for s in sizes if a <= s < b) for a, b in zip(h.edges, h.edges[1:], strict=False)]
    assert h.counts == expected
    below = [n for a, n in zip(h.edges, h.counts, strict=False) if a < 500 - 1e-6]
    assert sum(below) == small  # bins left of the 0.5 kB edge hold exactly the small ones
    assert h.counts[-1] == 1  # the 20-grasp answer alone in the top bin
    assert size_histogram([]).count == 0


def test_matrix_grids_are_table8_of_the_run_and_of_the_paper(run_dir: Path) -> None:
    report = build_report(run_dir)
    g = matrix_grid(report.matrix)
    assert g.rows == g.cols == ["a_co", "a_hi", "a_km", "a_pl", "a_ta", "ag_ex"]
    assert g.cells[g.rows.index("a_ta")] == [6, 0, 1, 0, 0, 5]  # a_ta received from a_co, a_km, ag_ex
    assert g.received == [7, 2, 8, 6, 12, 5]
    assert g.sent == [10, 1, 5, 6, 13, 5] and g.total == 40
    p = paper_matrix_grid()
    assert p.total == paper.TABLE8_TOTAL
    assert dict(zip(p.cols, p.sent, strict=True)) == paper.table8_sent()
    assert p.cells[p.rows.index("a_km")][p.cols.index("a_pl")] == 925
    assert p.received[p.rows.index("a_hi")] == 0  # the paper has no a_hi row


def test_gantt_rows_follow_the_timeline(run_dir: Path) -> None:
    report = build_report(run_dir)
    rows = gantt_rows(report.events)
    assert len(rows) == len(report.events)
    by_label = {r.label: r for r in rows}
    planning = next(r for r in rows if r.label.startswith("a_pl generates the plan #1"))
    assert planning.spans == [pytest.approx((12.0, 16.0))] and planning.channels == ["C4"]
    grasp = by_label["left hand grasps"]  # "(step fetch_jar/grasp)" left out of the label
    assert grasp.spans == [pytest.approx((21.0, 21.0))] and grasp.channels == ["C5"]
    assert all(len(r.label) <= figures.LABEL_CHARS for r in rows)
    theirs = paper_gantt_rows()
    assert len(theirs) == len(paper.TABLE7)
    assert theirs[0].spans == [(0.0, 37.0)] and theirs[0].channels == ["C5", "C6"]
    assert theirs[6].spans == [(293.0, 315.0), (674.0, 680.0)]
    assert theirs[7].spans == [(300.0, 300.0)] and theirs[7].channels == []


def test_a_figure_that_fails_becomes_a_note(run_dir: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    write_report(run_dir)
    stale = run_dir / FIGURES_DIR / "bandwidth.png"
    assert stale.exists()

    def boom(*args: object) -> None:
        raise RuntimeError("boom")

    monkeypatch.setattr(figures, "draw_bandwidth", boom)
    md = write_report(run_dir).read_text(encoding="utf-8")
    assert "- figure bandwidth.png not drawn: RuntimeError: boom" in md
    assert "figures/bandwidth.png" not in md and not stale.exists()  # no stale image linked
    assert "(figures/sizes_over_time.png)" in md and "(figures/timeline.png)" in md


def test_no_traffic_no_figures(tmp_path: Path) -> None:
    empty = tmp_path / "empty"
    empty.mkdir()
    md = write_report(empty).read_text(encoding="utf-8")
    assert "figures/" not in md
    assert not (empty / FIGURES_DIR).exists()


def test_with_figures_off_the_report_draws_none_and_says_so(
    run_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``ROCO_REPORT_FIGURES=0``: report.md links no figure, notes why, and neither the report
    nor the coverage count (``roco report``'s and a fleet's end) draws a PNG."""
    from services.spec_check.coverage_figure import report_summary

    monkeypatch.setenv(Settings.env_name("report_figures"), "0")
    summary = report_summary(run_dir)
    md = write_report(run_dir, coverage=summary).read_text(encoding="utf-8")
    assert f"- {figures.NOT_DRAWN}" in md and "figures/" not in md
    assert summary.figure == "" and "Specification coverage" in md
    assert not (run_dir / FIGURES_DIR).exists()
    monkeypatch.setenv(Settings.env_name("report_figures"), "1")
    md = write_report(run_dir, coverage=report_summary(run_dir)).read_text(encoding="utf-8")
    assert figures.NOT_DRAWN not in md and "(figures/coverage.png)" in md
    assert len(list((run_dir / FIGURES_DIR).glob("*.png"))) == len(SECTIONS) + 1


def test_byte_ticks() -> None:
    assert [byte_tick(x) for x in (100, 200, 500, 1000, 2000, 20_000)] == [
        "100 B",
        "200 B",
        "500 B",
        "1 kB",
        "2 kB",
        "20 kB",
    ]
