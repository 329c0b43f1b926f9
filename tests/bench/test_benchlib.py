"""scripts/benchlib.py ``recorded``: a script's output written to its document as the current
run, the document's earlier runs kept below, nothing written by a run that raised."""

from __future__ import annotations

from pathlib import Path

import pytest

from services.bench.parts import scripts_module

benchlib = scripts_module("benchlib")


def test_the_current_run_replaces_the_last_and_earlier_runs_are_kept(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    out = tmp_path / "loop.md"
    out.write_text(f"# old\n\n| condition |\n| old row |\n\n{benchlib.EARLIER}\n\nthe run before\n")
    with benchlib.recorded(out):
        print("# new\n\n| condition |\n| new row |")
    assert capsys.readouterr().out == "# new\n\n| condition |\n| new row |\n"  # printed as well
    assert out.read_text() == f"# new\n\n| condition |\n| new row |\n\n{benchlib.EARLIER}\n\nthe run before\n"


def test_a_run_that_raised_writes_nothing(tmp_path: Path) -> None:
    out = tmp_path / "seeds.md"
    out.write_text("the last finished run\n")
    with pytest.raises(RuntimeError), benchlib.recorded(out):
        print("half a table")
        raise RuntimeError("a fleet did not start")
    assert out.read_text() == "the last finished run\n"


def test_without_a_file_it_only_prints(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    with benchlib.recorded(None):
        print("figures")
    assert capsys.readouterr().out == "figures\n"
    assert list(tmp_path.iterdir()) == []
