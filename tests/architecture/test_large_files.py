"""A file of more than :data:`LARGE` lines under ``services/``, ``shared/`` and ``velma/`` names
its one job in its docstring's first sentence: a module docstring whose first sentence (up to
the first full stop followed by a space or a line end) is at most :data:`MOST_WORDS` words. A
file that cannot say what it is for in one sentence has more than one job, and is split."""

from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SCANNED = ("services", "shared", "velma")
LARGE = 700
MOST_WORDS = 60
SENTENCE_END = re.compile(r"\.(?:\s|$)")


def first_sentence(doc: str) -> str:
    """``doc`` up to its first full stop that ends a sentence (the whole of it when none does)."""
    end = SENTENCE_END.search(doc)
    return doc[: end.start() + 1] if end else doc


def offences(root: Path) -> list[str]:
    """One line per large file that has no module docstring or a first sentence too long."""
    out = []
    for package in SCANNED:
        for path in sorted((root / package).rglob("*.py")):
            text = path.read_text(encoding="utf-8")
            if text.count("\n") <= LARGE:
                continue
            doc = ast.get_docstring(ast.parse(text)) or ""
            words = len(first_sentence(doc).split())
            if not doc or words > MOST_WORDS:
                out.append(f"{path.relative_to(root)}: {words} words in its docstring's first sentence")
    return out


def test_every_large_file_names_its_one_job() -> None:
    assert offences(ROOT) == []


def test_a_large_file_without_its_job_is_named(tmp_path: Path) -> None:
    (tmp_path / "services").mkdir()
    (tmp_path / "services" / "big.py").write_text("x = 1\n" * (LARGE + 1))
    (tmp_path / "services" / "told.py").write_text('"""Does one thing. More."""\n' + "x = 1\n" * (LARGE + 1))
    assert offences(tmp_path) == ["services/big.py: 0 words in its docstring's first sentence"]
    said = "The replay of one agent: its input fed."
    assert first_sentence(said + " More.") == said
