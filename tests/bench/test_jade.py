"""``roco bench``'s jade part (services/bench/jade.py): skipped with one line naming what is
missing; with a JADE source tree (``ROCO_JADE_HOME``, e.g. a clone of
https://github.com/EnFlexIT/JADE) and a JDK (Debian package default-jdk-headless), a small real
run gives sane figures and leaves no JVM behind, also when it times out. No timing is asserted.

The first real run compiles JADE into .bench/jade/ (about a minute on 2 cores); later runs
reuse it."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from services.bench import jade, report
from services.bench.jade import JadeFigures
from services.bench.messaging import percentile
from shared.settings import Settings

ROOT = Path(__file__).resolve().parents[2]
HOME_VAR = Settings.env_name("jade_home")
HOME = Settings.from_env(only=("jade_home",)).jade_home
needs_jade = pytest.mark.skipif(bool(jade.missing(HOME)), reason=f"jade part: {jade.missing(HOME)}")


def _java_children() -> list[int]:
    """PIDs of the ``java`` processes whose parent is this process."""
    me, found = os.getpid(), []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            text = stat.read_text()
        except OSError:
            continue
        name, rest = text[text.index("(") + 1 : text.rindex(")")], text[text.rindex(")") + 2 :].split()
        if name == "java" and int(rest[1]) == me:
            found.append(int(stat.parent.name))
    return found


def test_without_a_jade_tree_the_bench_says_so_in_one_line_and_runs_on(tmp_path: Path) -> None:
    out = tmp_path / "b.md"
    env = {k: v for k, v in os.environ.items() if k != HOME_VAR}
    done = subprocess.run(
        [sys.executable, "-m", "services.cli", "bench", "--quick", "--only", "codec,jade", "--out", str(out)],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    why = f"no JADE source tree (give --jade-home or set {HOME_VAR})"
    said = [line for line in done.stderr.splitlines() if "jade:" in line]
    assert said == [f"roco bench: jade: skipped: {why}"]
    text = out.read_text()
    assert "## 1. Codec" in text  # the rest of the bench ran
    assert "- **JADE**: see services/bench/jade.py." in text and f"**Not measured: {why}**" in text


def test_what_is_missing_is_named(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    assert jade.missing(tmp_path) == f"{tmp_path} is not a JADE source tree (no src/jade/core/Agent.java)"
    tree = tmp_path / "src" / "jade" / "core"
    tree.mkdir(parents=True)
    (tree / "Agent.java").write_text("")
    monkeypatch.setenv("PATH", str(tmp_path / "bin"))
    assert jade.missing(tmp_path) == "no javac (Debian package default-jdk-headless)"


def test_a_line_is_read_within_its_bound(tmp_path: Path) -> None:
    read, write = os.pipe()
    with os.fdopen(read, "rb") as stream, os.fdopen(write, "wb") as sink:
        sink.write(b"JADE's banner\n  roco-bench-ready \n{")
        sink.flush()
        assert jade.read_line(stream, lambda line: line == jade.READY, 5, 1 << 10) == jade.READY
        sink.write(b"x" * 100)  # a line that never ends: the bound, not the timeout, stops the read
        sink.flush()
        assert jade.read_line(stream, lambda line: True, 30, 64) is None
        assert jade.read_line(stream, lambda line: True, 0.01, 1 << 10) is None  # nothing more comes


def test_the_jade_row_sits_beside_roco_and_raw_zenoh() -> None:
    fig = JadeFigures([400e-6, 500e-6, 900e-6], 4999, 5000, 0.25, {"jade": "4.6.5", "java": "17"})
    rows = report.messaging_table(None, None, fig, 200)
    assert rows[0].startswith("| system | link | round trip p50 µs | p90 µs | p99 µs |")
    assert rows[2] == (
        "| JADE 4.6.5, two containers in two JVMs (200-character content) | IMTP over TCP, one hop "
        "| 500 | 900 | 900 | 3 | 19,992 | 19,992 | 1 |"
    )
    assert report.messaging_table(None, None, JadeFigures(skipped="no javac"), 200) == []


@needs_jade
def test_a_small_jade_run_gives_sane_figures_and_ends_its_jvms() -> None:
    assert HOME is not None
    fig = jade.measure(HOME, warmup=50, round_trips=50, messages=500, size=200)
    assert not fig.error and not fig.skipped, fig.error
    assert len(fig.samples_s) == 50 and all(0 < s < 5 for s in fig.samples_s)
    assert percentile(fig.samples_s, 50) <= percentile(fig.samples_s, 90)
    assert fig.sent == fig.count == 500 and fig.span_s > 0 and fig.rate > 0
    assert fig.versions["java"] and fig.versions["jade"]
    assert "two JVMs" in fig.settings
    assert _java_children() == []


@needs_jade
def test_a_jade_run_that_times_out_ends_its_jvms(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    assert HOME is not None
    monkeypatch.setattr("tempfile.tempdir", str(tmp_path))  # the logs a failed run keeps
    fig = jade.measure(HOME, warmup=50, round_trips=50, messages=500, timeout=0.01)
    assert fig.error.startswith("the initiator printed no figures within 0 s"), fig.error
    assert _java_children() == []
