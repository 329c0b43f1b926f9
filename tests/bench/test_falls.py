"""The messaging part notices a fall (services/bench/falls.py): the ratios to raw Zenoh are read
from the benchmarks document this checkout holds, and a run more than 20 % worse on one of
them prints a warning line; one within 20 % prints none."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest

from services.bench import falls
from services.bench.falls import Ratios
from services.bench.messaging import MessagingSummary

ROOT = Path(__file__).resolve().parents[2]


def _summary(rt: float = 230.0, raw: float = 80.0, stream: float = 80_000.0) -> MessagingSummary:
    return MessagingSummary(
        round_trip_p50_us=rt,
        raw_polling_p50_us=raw,
        raw_sleeping_p50_us=210.0,
        round_trip_open_p50_us=rt,
        raw_polling_open_p50_us=raw,
        stream_per_s=stream,
        stream_batched_per_s=130_000.0,
        stream_open_per_s=90_000.0,
        raw_stream_per_s=540_000.0,
        content_bytes=200,
        links="peer",
        poll_us=500.0,
    )


def test_the_recorded_ratios_are_read_from_the_document() -> None:
    got = falls.recorded(ROOT)
    assert 1.0 < got.round_trip_secured < 20.0 and 1.0 < got.round_trip_open < 20.0
    assert 0.0 < got.stream_secured < 1.0


def test_a_ratio_more_than_20_percent_worse_is_a_fall() -> None:
    before = Ratios.of(_summary())
    slower = Ratios.of(_summary(rt=230.0 * 1.25))  # both round trips 25 % slower against raw Zenoh
    lines = falls.falls(before, slower)
    assert len(lines) == 2 and all("WARNING" in line and "25 % worse" in line for line in lines), lines
    fewer = Ratios.of(_summary(stream=80_000.0 / 1.3))
    assert [line for line in falls.falls(before, fewer) if "stream" in line], falls.falls(before, fewer)


def test_a_ratio_within_20_percent_or_better_is_no_fall() -> None:
    before = Ratios.of(_summary())
    assert falls.falls(before, Ratios.of(_summary(rt=230.0 * 1.15, stream=80_000.0 / 1.15))) == []
    assert falls.falls(before, replace(before, round_trip_secured=1.0, stream_secured=0.9)) == []


def test_a_document_without_the_messaging_table_says_so(tmp_path: Path) -> None:
    (tmp_path / "docs").mkdir()
    text = (ROOT / "docs" / "benchmarks.md").read_text()
    (tmp_path / "docs" / "benchmarks.md").write_text(
        text.replace("| roco (Agent runtime", "| roko (Agent runtime")
    )
    with pytest.raises(falls.FiguresError, match="no row 'roco"):
        falls.recorded(tmp_path)
