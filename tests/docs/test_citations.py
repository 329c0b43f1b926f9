"""No file of the repository cites a note it does not hold, nor an absolute path of some
machine's home or work folder (the checker: tests/docs/citations.py). The tests below plant such
citations in copies of real files and show that the check finds each one."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from tests.docs import citations
from tests.docs.doccheck import Finding, Repository

ROOT = Path(__file__).resolve().parents[2]
FACTS, PITFALLS, DESIGN = (stem + ".md" for stem in citations.OUTSIDE_NOTES)


@pytest.fixture(scope="module")
def repo() -> Repository:
    return Repository(ROOT)


def report(found: list[Finding]) -> str:
    return f"{len(found)} citation(s) outside the repository:\n" + "\n".join(str(f) for f in found)


# --- the repository as it is ---------------------------------------------------------------


def test_no_file_cites_outside_the_repository(repo: Repository) -> None:
    found = citations.findings(repo)
    assert not found, report(found)


def test_the_check_reads_the_code_the_tests_and_the_manual(repo: Repository) -> None:
    """Not a vacuous pass: the sources, the tests, the manual and the model's README are read."""
    read = {p.relative_to(ROOT).as_posix() for p in citations.scanned_files(repo)}
    assert len(read) > 400
    assert {
        "velma/model/robot_mjcf.py",
        "velma/model/README.md",
        "velma/control/_plant.hpp",
        "services/runtime/transport.py",
        "shared/fipa_codec/names.py",
        "scripts/build_image.sh",
        "tests/velma/test_velma_model.py",
        "docs/executor.md",
        "README.md",
    } <= read


# --- the check finds what is planted --------------------------------------------------------


@pytest.mark.parametrize(
    ("planted", "problem"),
    [
        (f"# the torso's limits ({FACTS})", f"cites {FACTS}, which the repository does not hold"),
        (f'"""Spawn, never fork ({PITFALLS})."""', f"cites {PITFALLS},"),
        (f"# ({DESIGN} layer 5: a tool)", f"cites {DESIGN},"),
        (f"# numbers: /work/shared/{FACTS}", f"cites /work/shared/{FACTS},"),
        (f"# see ../notes/{DESIGN}", f"cites ../notes/{DESIGN},"),
        ("# measured with /home/alice/roco/bench.py", "names /home/alice…, a path outside the repository"),
        ('"""Kept as /Users/bob/notes.txt."""', "names /Users/bob…"),
        ("# copied from /work/main/.venv", "names /work/main…"),
        ("# C:\\Users\\carol\\roco", "names C:\\Users\\…"),
    ],
)
def test_a_citation_planted_in_a_copy_of_a_real_file_is_found(
    tmp_path: Path, planted: str, problem: str
) -> None:
    copy = tmp_path / "velma" / "control" / "hand.py"
    copy.parent.mkdir(parents=True)
    shutil.copy(ROOT / "velma" / "control" / "hand.py", copy)
    text = copy.read_text()
    line = 20
    lines = text.splitlines(keepends=True)
    copy.write_text("".join([*lines[: line - 1], planted + "\n", *lines[line - 1 :]]))

    found = citations.findings(Repository(tmp_path))

    assert [(f.path, f.line) for f in found] == [("velma/control/hand.py", line)], report(found)
    assert problem in found[0].message


def test_a_citation_planted_in_each_scanned_folder_is_found(tmp_path: Path) -> None:
    """A source, a script, a test, a doc and the top-level README: each planted citation found."""
    planted = {
        "services/runtime/x.py": f'"""Zenoh in client mode ({DESIGN})."""\n',
        "shared/fipa_codec/x.py": f"# key chunks ({DESIGN})\n",
        "scripts/x.sh": f"# see {PITFALLS}\n",
        "tests/x/test_x.py": f"# the arm's table ({FACTS})\n",
        "docs/x.md": f"The facts are in [the notes](/work/shared/{FACTS}).\n",
        "README.md": "Run it from /home/alice/roco.\n",
    }
    for name, text in planted.items():
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text("Fine first line.\n" + text)

    found = citations.findings(Repository(tmp_path))

    assert sorted((f.path, f.line) for f in found) == sorted((name, 2) for name in planted), report(found)


def test_what_is_not_a_citation_outside_the_repository(tmp_path: Path) -> None:
    """A URL to another project's file of the same name, a path to a file the repository holds,
    keys and system paths, and quoted program output in a test's data."""
    (tmp_path / "docs").mkdir()
    (tmp_path / "docs" / DESIGN).write_text("# The design\n")
    (tmp_path / "tests").mkdir()
    (tmp_path / "tests" / "test_log.py").write_text('LINE = "panic at /root/.cargo/registry/x.rs:1"\n')
    page = tmp_path / "docs" / "a.md"
    page.write_text(
        f"rmw_zenoh's wire format: https://github.com/ros2/rmw_zenoh/blob/rolling/docs/{DESIGN}.\n"
        f"Our own: docs/{DESIGN}, or ({DESIGN}) from this folder.\n"
        f"A name that only ends like one: my-{DESIGN}, old_{FACTS}.\n"
        "Keys roco/work/a_pl and roco/fipa/C4/a_pl/a_km; logs in /tmp/roco and /var/tmp/roco-build.\n"
        "`roco bench --out /tmp/b.md`; `/usr/sbin/dockerd`; `~/work/roco` is the reader's own.\n"
    )

    assert citations.findings(Repository(tmp_path)) == []
