"""README.md's figures against the documents the runs wrote (services/bench/readme_figures.py):
each figure is the one its cited document gives, each row names its run's commit and machine,
and the documents' run headers are read as their writers write them. Each check is also shown
failing on a planted fault in a copy of the repository's files."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from services.bench import readme_figures, report, run_header, runner
from services.bench.bench_docs import FiguresError
from services.bench.readme_figures import BENCHMARKS, LOOP, POUR_SEEDS

ROOT = Path(__file__).resolve().parents[2]


def _copy(tmp_path: Path) -> Path:
    """README.md and the source documents, copied under ``tmp_path``."""
    for rel in ("README.md", BENCHMARKS, LOOP, POUR_SEEDS):
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(ROOT / rel, tmp_path / rel)
    return tmp_path


def _edit(path: Path, old: str, new: str) -> None:
    text = path.read_text()
    assert text.count(old) >= 1, f"{old!r} not in {path}"
    path.write_text(text.replace(old, new, 1))


def _readme_row(root: Path, figure: str) -> str:
    start, end = readme_figures.between((root / "README.md").read_text())
    rows = [
        r for r in (root / "README.md").read_text()[start:end].splitlines() if r.startswith(f"| {figure}")
    ]
    assert len(rows) == 1, figure
    return rows[0]


# --- README as it is ---------------------------------------------------------------------------


def test_readme_figures_are_the_documents_figures() -> None:
    found = readme_figures.differences(ROOT)
    assert not found, "\n".join(found)


def test_every_readme_figure_names_its_runs_commit_and_machine() -> None:
    readme = (ROOT / "README.md").read_text()
    missing = readme_figures.rows_without_run(readme)
    assert not missing, "\n".join(missing)
    start, end = readme_figures.between(readme)
    assert len([r for r in readme[start:end].splitlines() if r.startswith("|")]) == 2 + len(
        readme_figures.ROWS
    )


# --- planted faults ----------------------------------------------------------------------------


def test_an_edited_readme_figure_is_caught(tmp_path: Path) -> None:
    root = _copy(tmp_path)
    row = _readme_row(root, "request → inform round trip")
    value = row.split(" | ")[1]  # "207 µs"
    planted = f"{int(value.split()[0]) + 1} µs"
    _edit(root / "README.md", row, row.replace(f"| {value} |", f"| {planted} |"))
    found = readme_figures.differences(root)
    assert len(found) == 1 and planted in found[0] and value in found[0]


def _first_overrun_cell(text: str) -> str:
    """The overruns cell ``"| N (x %) |"`` of the loop document's first fleet row."""
    row = next(line for line in text.splitlines() if line.startswith("| fleet:"))
    m = re.search(r"\| \d+ \([\d.]+ %\) \|", row)
    assert m is not None, row
    return m.group(0)


def test_a_document_s_new_figure_not_in_readme_is_caught(tmp_path: Path) -> None:
    root = _copy(tmp_path)
    cell = _first_overrun_cell((root / LOOP).read_text())
    _edit(root / LOOP, cell, re.sub(r"\([\d.]+ %\)", "(0.160 %)", cell))
    found = readme_figures.differences(root)
    assert len(found) == 1 and "0.160 %" in found[0] and ": missed" in found[0]


def test_a_target_missed_in_the_run_but_not_in_readme_is_caught(tmp_path: Path) -> None:
    root = _copy(tmp_path)
    met, missed = (
        int(n) for n in re.findall(r"(\d+) met, (\d+) missed", _readme_row(root, "`roco bench`"))[0]
    )
    _edit(root / BENCHMARKS, "(target ≤ 2 s): met", "(target ≤ 2 s): missed")
    found = readme_figures.differences(root)
    assert (
        len(found) == 1
        and f"{met - 1} met, {missed + 1} missed" in found[0]
        and "Plan #1 wall time" in found[0]
    )


def _commit(text: str) -> str:
    """The commit a document's or a README row's run header names."""
    m = re.search(r"at (?:commit )?([0-9a-f]{7,40})", text)
    assert m is not None
    return m.group(1)


def test_a_readme_row_without_commit_or_machine_is_caught(tmp_path: Path) -> None:
    root = _copy(tmp_path)
    row = _readme_row(root, "pours with the jar")
    _edit(root / "README.md", row, row.replace(f" at {_commit(row)}", ""))
    row = _readme_row(root, "the fleet's memory")
    machine = row.rstrip(" |").rsplit("; ", 1)[1]
    _edit(root / "README.md", row, row.replace(f"; {machine}", ""))
    missing = readme_figures.rows_without_run((root / "README.md").read_text())
    assert [r.split(" | ")[0] for r in missing] == [
        "| the fleet's memory at rest",
        "| pours with the jar and bowl moved ±2 cm, turned ±10°",
    ]


def test_a_document_without_its_run_header_is_refused(tmp_path: Path) -> None:
    root = _copy(tmp_path)
    text = (root / POUR_SEEDS).read_text()
    _edit(root / POUR_SEEDS, f", at commit {_commit(text)}", ",")
    with pytest.raises(FiguresError, match=r"pour_seeds_fleet\.md: no line '- Command"):
        readme_figures.render(root)


def test_randomised_pours_without_their_verdict_check_are_refused(tmp_path: Path) -> None:
    root = _copy(tmp_path)
    _edit(root / POUR_SEEDS, "Verdict matches truth:", "Verdict:")
    with pytest.raises(FiguresError, match=r"pour_seeds_fleet\.md: no line 'Verdict matches truth: N of M'"):
        readme_figures.render(root)


def test_a_missing_table_row_is_refused(tmp_path: Path) -> None:
    root = _copy(tmp_path)
    _edit(root / BENCHMARKS, "| roco (Agent runtime,", "| roco runtime (")
    with pytest.raises(FiguresError, match="no row 'roco \\(Agent runtime' on the link"):
        readme_figures.render(root)


def test_the_markers_must_be_there_once(tmp_path: Path) -> None:
    root = _copy(tmp_path)
    _edit(root / "README.md", readme_figures.END, "")
    with pytest.raises(ValueError, match="expected one line"):
        readme_figures.write(root)


def test_write_replaces_only_the_table(tmp_path: Path) -> None:
    root = _copy(tmp_path)
    row = _readme_row(root, "the pour,")
    _edit(root / "README.md", row, "| stale |")
    before = (root / "README.md").read_text()
    readme_figures.write(root)
    after = (root / "README.md").read_text()
    assert after == (ROOT / "README.md").read_text()
    assert before.split(readme_figures.BEGIN)[0] == after.split(readme_figures.BEGIN)[0]


# --- the run headers ---------------------------------------------------------------------------


def test_roco_bench_s_header_is_read() -> None:
    lines = report.machine_lines("roco bench", "0 / 0 / 0", "0 / 0 / 0", 1.8e9, 12.0)
    run = run_header.read("\n".join(lines))
    assert run.command == "roco bench" and run.commit == report.commit()
    assert run.cpu == report.cpu_model() and run.date.startswith("2027-01-15")


def test_a_script_s_header_is_read() -> None:
    run = run_header.read("\n".join(run_header.script_lines(["scripts/bench_loop.py", "--repeat", "3"])))
    assert run.command == "python scripts/bench_loop.py --repeat 3"
    assert run.commit == report.commit() and run.cpu == report.cpu_model() and run.cores >= 1


def test_a_header_without_the_cpu_line_is_refused() -> None:
    lines = run_header.script_lines(["scripts/bench_loop.py"])
    with pytest.raises(run_header.HeaderError, match="no line '- CPU"):
        run_header.read(lines[0], "loop.md")


# --- who writes README -------------------------------------------------------------------------


def test_only_a_whole_run_to_the_default_output_writes_readme() -> None:
    every = list(runner.PARTS)
    assert runner.writes_readme(every, False, runner.DEFAULT_OUT, {}) is None
    assert runner.writes_readme(["codec"], False, runner.DEFAULT_OUT, {}) is not None
    assert runner.writes_readme(every, True, runner.DEFAULT_OUT, {}) is not None
    assert runner.writes_readme(every, False, Path("/tmp/b.md"), {}) is not None
    assert runner.writes_readme(every, False, runner.DEFAULT_OUT, {"task": "RuntimeError: x"}) is not None


def test_a_partial_run_leaves_readme_alone(tmp_path: Path) -> None:
    before = (ROOT / "README.md").read_text()
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "services.cli",
            "bench",
            "--only",
            "codec",
            "--quick",
            "--out",
            str(tmp_path / "b.md"),
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert "README.md's figures left as they are (a run of some parts or with --quick)" in done.stderr
    assert (ROOT / "README.md").read_text() == before


def test_a_whole_run_writes_readme_and_says_why_not_when_it_cannot(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    root = _copy(tmp_path)
    monkeypatch.setattr(runner, "ROOT", root)
    monkeypatch.setattr(runner, "DEFAULT_OUT", root / BENCHMARKS)
    row = _readme_row(root, "the pour,")
    _edit(root / "README.md", row, "| stale |")
    assert runner.update_readme(list(runner.PARTS), False, root / BENCHMARKS, {})
    assert (root / "README.md").read_text() == (ROOT / "README.md").read_text()
    assert "roco bench: wrote README.md's figures" in capsys.readouterr().err
    # a source without its run header: one line saying so, a non-zero exit, README unchanged
    _edit(root / LOOP, "- CPU: AMD EPYC", "- AMD EPYC")
    assert not runner.update_readme(list(runner.PARTS), False, root / BENCHMARKS, {})  # roco bench: exit 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        "roco: README.md's figures not written: docs/bench/loop.md: no line '- CPU: …, N of M cores usable'"
    ]
    assert (root / "README.md").read_text() == (ROOT / "README.md").read_text()
