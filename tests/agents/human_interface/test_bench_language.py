"""scripts/bench_language.py: its figures count what they name, and a wrong command is caught."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]


def _bench(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, str(ROOT / "scripts" / "bench_language.py"), *args],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=ROOT,
    )


def test_a_command_where_a_refusal_is_meant_is_a_wrong_command(tmp_path: Path) -> None:
    corpus = tmp_path / "planted.toml"
    corpus.write_text(
        "voices = [\n"
        '  { say = "I\'d like the beans in the bowl, please", want = "pour jar bowl" },\n'
        '  { say = "bring me the cup", want = "refuse" },\n'  # planted: a_hi reads a command
        '  { say = "fly me to the moon", want = "refuse" },\n'
        "]\n"
    )
    done = _bench("--file", str(corpus))
    assert done.returncode == 0, done.stderr
    assert "| planted.toml: voices | 3 | 1/1 (100.0 %) | 1/2 (50.0 %) | 1 | – |" in done.stdout
    assert "as meant: 2/3 (66.7 %); wrong commands: 1" in done.stdout
    assert "wrong: 'bring me the cup': means 'refuse', read as" in done.stdout


def test_a_missing_corpus_is_one_line_and_exit_2(tmp_path: Path) -> None:
    done = _bench("--file", str(tmp_path / "none.toml"))
    assert done.returncode == 2
    assert done.stderr == f"bench_language: {tmp_path / 'none.toml'}: no such corpus file\n"
