"""Figures that notice a fall: the messaging part's ratios to raw Zenoh, against those the
benchmarks document holds.

Absolute times move from one machine (or day) to the next; roco's figure over raw Zenoh's, both
measured in one run on the same link, moves much less. ``roco bench --only messaging`` reads
the ratios of the run docs/benchmarks.md holds before it overwrites it (:func:`recorded`) and,
once measured, prints one warning line per ratio more than :data:`TOLERANCE` worse
(:func:`falls`):

- **round trip, secured** (mutual TLS and access control, as every fleet runs): roco's p50 over
  raw Zenoh's, each end polling (higher is worse);
- **round trip, open** (neither): the same (higher is worse);
- **stream, secured**: roco's communicates per second, one per put, over raw Zenoh's payloads
  per second (lower is worse).

Read from the section "2–3. Messaging" (services/bench/report.py ``messaging_section``), the
rows of roco and of raw Zenoh polling on each link; a document without them gives no ratios
and the run says so (:class:`~services.bench.bench_docs.FiguresError`)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from services.bench.bench_docs import Document, FiguresError, number
from services.bench.messaging import MessagingSummary

TOLERANCE = 0.20
"""A ratio this much worse than the recorded one is a fall (docs/benchmarks.md: "a ratio 20 %
worse is a defect")."""
SECTION = "2–3. Messaging"
ROCO_ROW = "roco (Agent runtime"
RAW_ROW = "raw Zenoh"
POLLING = "polling"
SECURED = "mutual TLS"
OPEN = "TCP, no ACL"


@dataclass(frozen=True)
class Ratios:
    """roco over raw Zenoh in one run: round trips' p50 (secured, open; higher is worse) and
    the one-per-put stream (secured; lower is worse)."""

    round_trip_secured: float
    round_trip_open: float
    stream_secured: float

    @classmethod
    def of(cls, s: MessagingSummary) -> Ratios:
        """The ratios of a run's summary (services/bench/messaging.py)."""
        return cls(
            round_trip_secured=_over(s.round_trip_p50_us, s.raw_polling_p50_us),
            round_trip_open=_over(s.round_trip_open_p50_us, s.raw_polling_open_p50_us),
            stream_secured=_over(s.stream_per_s, s.raw_stream_per_s),
        )


def _over(a: float, b: float) -> float:
    return a / b if b else float("inf")


def recorded(root: Path, path: str = "docs/benchmarks.md") -> Ratios:
    """The ratios of the run ``root / path`` holds. Raises FiguresError when the document, its
    run header, its messaging table or one of its rows or cells is missing."""
    table = Document.read(root, path).table(SECTION, "system")
    rt, stream, link = (table.column(c, SECTION) for c in ("round trip p50", "stream /s", "link"))

    def row(system: str, on: str, polling: bool) -> list[str]:
        for r in table.rows_starting(system):
            if r[link].startswith(on) and (POLLING in r[0]) == polling:
                return r
        raise FiguresError(f"{path}: no row {system!r} on {on!r} in '{SECTION}'")

    return Ratios(
        round_trip_secured=_cell_over(row(ROCO_ROW, SECURED, False), row(RAW_ROW, SECURED, True), rt),
        round_trip_open=_cell_over(row(ROCO_ROW, OPEN, False), row(RAW_ROW, OPEN, True), rt),
        stream_secured=_cell_over(row(ROCO_ROW, SECURED, False), row(RAW_ROW, SECURED, True), stream),
    )


def _cell_over(a: list[str], b: list[str], column: int) -> float:
    return _over(number(a[column]), number(b[column]))


def falls(before: Ratios, now: Ratios, tolerance: float = TOLERANCE) -> list[str]:
    """One line per ratio of ``now`` more than ``tolerance`` worse than ``before``'s."""
    out = []
    for name, was, is_, higher_worse in (
        ("round trip, mutual TLS + ACL", before.round_trip_secured, now.round_trip_secured, True),
        ("round trip, TCP, no ACL", before.round_trip_open, now.round_trip_open, True),
        ("stream one per put, mutual TLS + ACL", before.stream_secured, now.stream_secured, False),
    ):
        worse = is_ / was if higher_worse else was / is_
        if worse > 1 + tolerance:
            out.append(
                f"roco bench: WARNING: {name}: roco/raw Zenoh {is_:.2f} against {was:.2f} in the "
                f"recorded run: {100 * (worse - 1):.0f} % worse (more than {100 * tolerance:.0f} %)"
            )
    return out


def compared(before: Ratios, now: Ratios) -> str:
    """One line giving both runs' ratios."""
    return (
        f"roco bench: roco/raw Zenoh now (recorded): round trip, mutual TLS + ACL "
        f"{now.round_trip_secured:.2f} ({before.round_trip_secured:.2f}); TCP, no ACL "
        f"{now.round_trip_open:.2f} ({before.round_trip_open:.2f}); stream one per put, mutual "
        f"TLS + ACL {now.stream_secured:.3f} ({before.stream_secured:.3f})"
    )


__all__ = ["TOLERANCE", "FiguresError", "Ratios", "compared", "falls", "recorded"]
