"""Figures read back from the Markdown documents the benchmarks wrote (docs/benchmarks.md,
docs/bench/*.md): a document's run header (services/bench/run_header.py), its ``## `` sections,
their tables, and a table's rows and columns by the text they start with.

A document that keeps earlier runs below its current one has them under ``## Earlier runs``;
its tables are read above that heading only.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

from services.bench import run_header
from services.bench.run_header import RunHeader

EARLIER_RUNS = "\n## Earlier runs"


class FiguresError(ValueError):
    """A source document lacks the header, section, table, row or cell a figure is read from."""


@dataclass(frozen=True)
class Table:
    """A Markdown table: its header cells and its rows' cells."""

    header: list[str]
    rows: list[list[str]]

    def row(self, first: str, where: str) -> list[str]:
        """The first row whose first cell starts with ``first``; FiguresError when none does."""
        for r in self.rows:
            if r[0].startswith(first):
                return r
        raise FiguresError(f"{where}: no row starting {first!r}")

    def rows_starting(self, first: str) -> list[list[str]]:
        return [r for r in self.rows if r[0].startswith(first)]

    def column(self, name: str, where: str) -> int:
        """The index of the first column whose header starts with ``name``."""
        for i, h in enumerate(self.header):
            if h.startswith(name):
                return i
        raise FiguresError(f"{where}: no column starting {name!r}")


@dataclass(frozen=True)
class Document:
    """A source document: its path from the repository root, its text and its run's header."""

    path: str
    text: str
    run: RunHeader

    @classmethod
    def read(cls, root: Path, path: str) -> Document:
        """``root / path`` with its run header (FiguresError when the file or header is missing)."""
        try:
            text = (root / path).read_text()
        except OSError as exc:
            raise FiguresError(f"{path}: {exc.strerror}") from exc
        try:
            return cls(path, text, run_header.read(text, path))
        except run_header.HeaderError as exc:
            raise FiguresError(str(exc)) from exc

    def section(self, title: str) -> str:
        """The text of the ``## `` section whose heading starts with ``title`` (the whole
        document when ``title`` is empty)."""
        if not title:
            return self.text
        for part in self.text.split("\n## ")[1:]:
            if part.startswith(title):
                return part
        raise FiguresError(f"{self.path}: no section '## {title}…'")

    def heading(self, title: str) -> str:
        return self.section(title).split("\n", 1)[0]

    def tables(self, title: str = "") -> list[Table]:
        """The tables of a section (of the document's current run: before ``## Earlier runs``)."""
        text = self.section(title).split(EARLIER_RUNS, 1)[0]
        out, block = [], []
        for line in [*text.splitlines(), ""]:
            if line.startswith("|"):
                block.append(line)
            elif block:
                cells = [[c.strip() for c in b.strip().strip("|").split("|")] for b in block]
                out.append(Table(cells[0], cells[2:]))
                block = []
        if not out:
            raise FiguresError(f"{self.path}: no table in '{title or 'the document'}'")
        return out

    def table(self, title: str, first_column: str) -> Table:
        """The section's first table whose first header cell starts with ``first_column``."""
        for t in self.tables(title):
            if t.header[0].startswith(first_column):
                return t
        raise FiguresError(f"{self.path}: no table headed {first_column!r} in '{title}'")


def slug(heading: str) -> str:
    """A heading's anchor as GitHub makes it: lower case, punctuation dropped, spaces to ``-``."""
    text = re.sub(r"[`*]", "", heading).strip().lower()
    return re.sub(r"[^\w\- ]", "", text).replace(" ", "-")


def number(cell: str) -> float:
    """The first number in a cell (``"1,418"`` → 1418.0, ``"7 (0.013 %)"`` → 7.0)."""
    m = re.search(r"-?\d[\d,]*(?:\.\d+)?", cell)
    if m is None:
        raise FiguresError(f"no number in {cell!r}")
    return float(m.group().replace(",", ""))
