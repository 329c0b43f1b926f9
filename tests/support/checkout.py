"""A copy of this checkout, grown the documented way: the walk-through's watcher a_wt
(docs/spec.md) and the scratch agent a_sc (tests/spec_check/walkthrough/scratch.py), each
added to the copy's specification and written by the copy's ``roco spec new-agent``. Every
command runs in the copy (its working folder, first on PYTHONPATH), so that the copy's code runs,
not this checkout's (which the virtual environment installs editable). Used by
tests/integration/test_new_agent.py and scripts/check_growth.py."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

from tests.spec_check.walkthrough import (
    AGENT,
    TERMS_MODULE,
    WATCHER_REQUIREMENT,
    fill,
    requirement_test,
    walkthrough_spec,
    write_terms,
)
from tests.spec_check.walkthrough.scratch import SCRATCH, fill_scratch, scratch_spec, scratch_test

ROOT = Path(__file__).resolve().parents[2]
BUILT = ("services/**/*.so", "velma/**/*.so", "shared/**/*.so", "services/runtime/_compiled.json")
"""What ``pip install -e .`` built beside the sources (not tracked): the compiled control law
and runtime, copied so that the copy runs as fast as this checkout."""
SPEC = Path("services/spec/robot_companion.toml")
"""The shipped specification, relative to a checkout's root."""


def copy_checkout(to: Path) -> None:
    """The checkout's files as git sees them (tracked, and new files not ignored) and what the
    install built, copied to ``to``, which becomes a repository of its own with those files
    committed (what reads the checkout's commit, as the run headers do, reads the copy's).
    Raises CalledProcessError when git cannot list or commit them."""
    listed = subprocess.run(
        ["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"],
        cwd=ROOT,
        capture_output=True,
        check=True,
    ).stdout.decode()
    files = [ROOT / name for name in listed.split("\0") if name]
    files += [p for pattern in BUILT for p in ROOT.glob(pattern)]
    for source in files:
        if source.is_file() and ".venv" not in source.relative_to(ROOT).parts:
            target = to / source.relative_to(ROOT)
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(source, target)
    git = ["git", "-c", "user.name=roco", "-c", "user.email=roco@localhost", "-c", "commit.gpgsign=false"]
    commit = ["commit", "-q", "--no-verify", "-m", "a copy of the checkout"]
    for args in (["init", "-q"], ["add", "-A"], commit):
        subprocess.run([*git, *args], cwd=to, capture_output=True, check=True)


@dataclass(frozen=True)
class Checkout:
    """A copy of the checkout at ``root``, with the environment its commands run in."""

    root: Path

    @property
    def env(self) -> dict[str, str]:
        """This process's environment without a run's settings, the copy first on PYTHONPATH."""
        env = {k: v for k, v in os.environ.items() if k not in ("ROCO_ACL", "ROCO_SPEC", "ROCO_RUN_DIR")}
        return env | {"PYTHONPATH": str(self.root)}

    def run(self, *args: str, timeout: float = 300) -> subprocess.CompletedProcess[str]:
        """``python ARGS`` run in the copy, by the copy's code."""
        command = [sys.executable, *args]
        env = self.env
        return subprocess.run(
            command, cwd=self.root, env=env, capture_output=True, text=True, timeout=timeout
        )

    def roco(self, *args: str, timeout: float = 300) -> subprocess.CompletedProcess[str]:
        """``roco ARGS`` run in the copy, by the copy's code."""
        return self.run("-m", "services.cli", *args, timeout=timeout)

    def add_watcher(self) -> subprocess.CompletedProcess[str]:
        """The walk-through's stages 1–3 in the copy: the watcher's terms module, its
        specification entries, ``roco spec new-agent a_wt``, its handlers as the document writes
        them and a test naming its requirement, as the document asks of a new agent (when
        new-agent succeeded). What new-agent did."""
        doc = self.root / "docs" / "spec.md"
        folder = self.root / "services" / "agents" / "watch"
        write_terms(folder, doc)  # before the specification names it: loading it imports the module
        walkthrough_spec(self.root / SPEC, base=self.root / SPEC, doc=doc, terms=TERMS_MODULE)
        done = self.roco("spec", "new-agent", AGENT)
        if done.returncode == 0:
            fill(folder / "agent.py", doc, terms=TERMS_MODULE)
            requirement_test(self.root / "tests", (self.root / SPEC).read_text(), AGENT, WATCHER_REQUIREMENT)
        return done

    def add_scratch(self) -> subprocess.CompletedProcess[str]:
        """The scratch agent in the copy: its specification entries, ``roco spec new-agent
        a_sc``, its handlers written and its requirement's test (when new-agent succeeded).
        What new-agent did."""
        spec = self.root / SPEC
        scratch_spec(spec, spec)
        done = self.roco("spec", "new-agent", SCRATCH)
        if done.returncode == 0:
            fill_scratch(self.root / "services" / "agents" / "scratch" / "agent.py")
            scratch_test(self.root / "tests", spec.read_text())
        return done
