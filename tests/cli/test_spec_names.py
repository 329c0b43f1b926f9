"""``roco spec names [--check] [--file F] [--spec S]`` (services/cli/spec.py): writes the names
module the specification gives, or only says whether a file is it — exit 0, 1 with one line
saying how it differs, 2 for a specification or file that cannot be read."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from services.cli import app
from services.spec.model import load
from services.spec.render_names import NAMES_FILE, render
from tests.spec_check.walkthrough import NEXT, walkthrough_spec

runner = CliRunner()


def test_roco_spec_names_checks_the_committed_module() -> None:
    done = runner.invoke(app, ["spec", "names", "--check"])
    assert done.exit_code == 0, done.output
    assert done.output.startswith("roco: ") and done.output.rstrip().endswith(
        "is what the specification gives"
    )


@pytest.mark.walkthrough
def test_roco_spec_names_writes_and_checks_a_file(tmp_path: Path) -> None:
    spec = walkthrough_spec(tmp_path / "spec.toml")
    target = tmp_path / "names.py"
    target.write_text(NAMES_FILE.read_text())
    args = ["--file", str(target), "--spec", str(spec)]
    done = runner.invoke(app, ["spec", "names", "--check", *args])
    assert done.exit_code == 1
    assert done.output == (
        f"roco: {target} differs from what the specification gives "
        f"(no name {NEXT.channel_name}, {NEXT.notice_channel_name}, KITCHEN_WARNING): "
        "run `roco spec names`\n"
    )
    counts = f"{len(load(spec).channels)} channels, {len(load(spec).protocols)} protocols, 6 languages"
    done = runner.invoke(app, ["spec", "names", *args])
    assert done.exit_code == 0 and done.output == f"roco: wrote {target} ({counts})\n"
    assert target.read_text() == render(load(spec))
    done = runner.invoke(app, ["spec", "names", "--check", *args])
    assert done.exit_code == 0 and done.output == f"roco: {target} is what the specification gives\n"
    done = runner.invoke(app, ["spec", "names", *args])
    assert done.exit_code == 0 and done.output == f"roco: {target} is up to date ({counts})\n"


def test_a_file_or_specification_that_cannot_be_read_exits_2(tmp_path: Path) -> None:
    missing = tmp_path / "none.py"
    done = runner.invoke(app, ["spec", "names", "--check", "--file", str(missing)])
    assert done.exit_code == 2 and done.output == f"roco: {missing}: no such names module\n"
    bad = tmp_path / "bad.toml"
    bad.write_text('system = "x"\n')
    done = runner.invoke(app, ["spec", "names", "--spec", str(bad), "--file", str(missing)])
    assert done.exit_code == 2 and done.output.startswith(f"roco: {bad}: ") and done.output.count("\n") == 1
    assert not missing.exists()
