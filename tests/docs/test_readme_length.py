"""README.md stays a newcomer's page: at most :data:`MOST_WORDS` words (as ``wc -w`` counts
them: runs of non-space), the rest in docs/. Its figures table, rewritten by ``roco bench``
(services/bench/readme_figures.py), counts too."""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
MOST_WORDS = 1500


def words(text: str) -> int:
    return len(text.split())


def test_readme_is_short() -> None:
    n = words((ROOT / "README.md").read_text())
    assert n <= MOST_WORDS, f"README.md has {n} words (at most {MOST_WORDS}): move the detail to docs/"


def test_the_count_is_wc_s() -> None:
    assert words("a b\n\nc  d\t e") == 5
    assert words((ROOT / "README.md").read_text() + " word" * 200) > MOST_WORDS  # a longer one is caught
