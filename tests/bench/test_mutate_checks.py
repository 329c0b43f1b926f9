"""scripts/mutate_checks.py's own logic, on a tiny tree of its own (never roco's): a snippet that
is not in its file stops the script with exit 2 before any test runs; a mutant whose tests still
pass SURVIVED (exit 1), one whose test fails is caught, and the tree itself is left as it was;
the copy leaves out environments, caches and compiled extensions; ``--only`` selects by prefix;
every group's mutants are named by its prefix."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from services.bench import parts

mutate_checks = parts.scripts_module("mutate_checks")

CHECK = """def check(x: int) -> str | None:
    if x < 0:
        return "negative"
    return None
"""
TESTS = """from tinycheck.check import check


def test_a_positive_number_passes() -> None:
    assert check(1) is None


def test_a_negative_number_is_refused() -> None:
    assert check(-1) == "negative"
"""
PASSES = "test_tiny.py::test_a_positive_number_passes"
REFUSES = "test_tiny.py::test_a_negative_number_is_refused"


@pytest.fixture
def tree(tmp_path: Path) -> Path:
    """A tiny repository: a package whose one check refuses negative numbers, and its tests."""
    root = tmp_path / "tree"
    (root / "tinycheck").mkdir(parents=True)
    (root / "tinycheck" / "__init__.py").write_text("")
    (root / "tinycheck" / "check.py").write_text(CHECK)
    (root / "test_tiny.py").write_text(TESTS)
    (root / "pyproject.toml").write_text("[tool.pytest.ini_options]\n")  # the copy is pytest's rootdir
    return root


def _check_off(name: str, test: str, old: str = "    if x < 0:\n") -> Any:
    """The mutant that deletes the tiny check (its snippet ``old``), which ``test`` must catch."""
    return mutate_checks.Mutant(name, "tinycheck/check.py", old, "    if False:\n", (test,))


def test_a_snippet_not_in_its_file_exits_2_before_any_test_runs(
    tree: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    def nothing_runs(*args: object) -> None:
        raise AssertionError("the script ran something")

    monkeypatch.setattr(mutate_checks, "run_tests", nothing_runs)
    monkeypatch.setattr(mutate_checks, "check_imports", nothing_runs)
    missing = _check_off("tiny.missing", REFUSES, old="    if x <= 0:\n")
    mutants = [_check_off("tiny.caught", REFUSES), missing]
    assert mutate_checks.main(["--root", str(tree)], mutants=mutants) == 2
    assert "tiny.missing: its snippet is not found in tinycheck/check.py" in capsys.readouterr().err
    assert mutate_checks.main(["--root", str(tree), "--list"], mutants=mutants) == 2
    listed = capsys.readouterr().out.splitlines()
    assert listed[0].endswith("  ok") and "NOT APPLICABLE" in listed[1]
    assert mutate_checks.main(["--root", str(tree), "--only", "other."], mutants=mutants) == 2


def test_a_mutant_whose_tests_pass_survived_and_one_whose_test_fails_is_caught(
    tree: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    # the tiny tests need no plugin: a pytest that loads none starts in a tenth of the time
    monkeypatch.setenv("PYTEST_DISABLE_PLUGIN_AUTOLOAD", "1")
    monkeypatch.setattr(mutate_checks, "PYTEST", ("-m", "pytest", "-x", "-q", "-p", "no:cacheprovider"))
    mutants = [_check_off("tiny.survives", PASSES), _check_off("tiny.caught", REFUSES)]
    assert mutate_checks.main(["--root", str(tree), "--timeout", "120"], mutants=mutants) == 1
    out = capsys.readouterr().out
    verdicts = {line.split()[0]: line.split()[1] for line in out.splitlines() if line.startswith("tiny.")}
    assert verdicts == {"tiny.survives": "SURVIVED", "tiny.caught": "caught"}, out
    assert "1 of 2 mutant(s) caught; not caught: tiny.survives" in out
    assert (tree / "tinycheck" / "check.py").read_text() == CHECK  # only copies are mutated


def test_the_copy_leaves_out_environments_caches_and_compiled_extensions(tmp_path: Path) -> None:
    root, copy = tmp_path / "tree", tmp_path / "copy"
    kept = ["services/a.py", "shared/b/c.py", "velma/d.so", "tests/runs/e.txt", "build.py"]
    left_out = [".venv/f.py", ".git/HEAD", "runs/g.jsonl", "build/h.o", "roco.egg-info/PKG-INFO"]
    left_out += ["services/i.so", "shared/b/j.so", "tests/__pycache__/k.pyc", "docs/.mypy_cache/l"]
    for name in kept + left_out:
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text(name)
    mutate_checks.copy_tree(root, copy)
    copied = sorted(str(p.relative_to(copy)) for p in copy.rglob("*") if p.is_file())
    assert copied == sorted(kept)


def test_only_selects_the_mutants_that_start_with_any_prefix_given() -> None:
    mutants = mutate_checks.MUTANTS
    names = [m.name for m in mutate_checks.selected(mutants, ["verify.key", "plan-check.goal."])]
    assert names == ["verify.key", *(m.name for m in mutants if m.name.startswith("plan-check.goal."))]
    assert mutate_checks.selected(mutants, []) == mutants


def test_every_mutant_is_named_by_its_group_once() -> None:
    names = [m.name for m in mutate_checks.MUTANTS]
    assert len(names) == len(set(names))
    for prefix, group in mutate_checks.GROUPS.items():
        assert group and all(m.name.startswith(prefix) and m.tests for m in group), prefix


@pytest.mark.parametrize(
    ("returncode", "verdict"),
    [(None, "TIMEOUT"), (0, "SURVIVED"), (1, "caught"), (2, "caught"), (4, "ERROR (pytest exit 4)")],
)
def test_the_verdict_follows_pytest_exit_code(returncode: int | None, verdict: str) -> None:
    assert mutate_checks.Outcome(returncode, 0.0, "").verdict == verdict
