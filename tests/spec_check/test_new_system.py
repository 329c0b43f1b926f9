"""``roco spec init NAME DIR`` (services/spec_check/new_system.py) writes a system that roco's
spec tools accept at once, and refuses, writing nothing, a name that cannot be a package's or a
folder that is not empty. Run as a user runs it (the CLI in a process of its own): the system's
package is imported there, not in the test's process."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from services.spec_check.new_system import files_of

ROCO = [sys.executable, "-m", "services.cli"]


def roco(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*ROCO, *args], capture_output=True, text=True, timeout=120)


def test_the_new_system_passes_check_deadlock_verify_code_and_its_names_are_current(tmp_path: Path) -> None:
    folder = tmp_path / "mine"
    done = roco("spec", "init", "shop", str(folder))
    assert done.returncode == 0, done.stderr
    spec = str(folder / "shop.toml")
    assert {p.relative_to(folder).as_posix() for p in folder.rglob("*.py")} >= {
        "shop/terms.py",
        "shop/names.py",
        "shop/ui/agent.py",
        "shop/worker/agent.py",
        "tests/test_shop.py",
    }
    for tool in (("check",), ("deadlock",), ("verify-code",), ("names", "--check")):
        checked = roco("spec", *tool, "--spec", spec)
        assert checked.returncode == 0, checked.stdout + checked.stderr


@pytest.mark.parametrize("name", ["Shop", "services", "class", "9lives", "a-b", "x" * 41])
def test_a_name_that_cannot_be_a_package_s_is_refused_and_nothing_written(tmp_path: Path, name: str) -> None:
    done = roco("spec", "init", name, str(tmp_path / "mine"))
    assert done.returncode == 1 and done.stderr.startswith(f"roco: {name!r} cannot name a system")
    assert not (tmp_path / "mine").exists()


def test_a_folder_that_is_not_empty_is_refused_and_left_as_it_was(tmp_path: Path) -> None:
    (tmp_path / "notes.txt").write_text("mine")
    done = roco("spec", "init", "shop", str(tmp_path))
    assert done.returncode == 1 and "not an empty folder" in done.stderr
    assert [p.name for p in tmp_path.iterdir()] == ["notes.txt"]


def test_each_name_gets_its_own_language_and_package() -> None:
    files = files_of("cell_two")
    assert "[languages.L_CELL_TWO]" in files["cell_two.toml"]
    assert 'implementation = "cell_two.ui.agent:Interface"' in files["cell_two.toml"]
    assert "from cell_two.names import C1, FIPA_REQUEST, L_CELL_TWO" in files["cell_two/ui/agent.py"]
