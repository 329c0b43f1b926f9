"""The web viewer ``roco view RUN --web`` serves, loaded in headless Chromium
(scripts/viewer_screenshot.py): a small recording (synthetic traffic and robot states, the
run's layout) is served, the viewer app starts in the page, ingests the recording, and is
drawn. Skipped when Chromium is not installed (CI: ``apt-get install -y chromium``)."""

from __future__ import annotations

import importlib.util
import io
import os
import sys
from pathlib import Path
from types import ModuleType

import pytest
from PIL import Image

from tests.support.machine import needs_chromium
from tests.support.rerun_run import rerun_run_dir
from tests.viewer.test_recording import RUN, record_run

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "viewer_screenshot.py"
WIDTH, HEIGHT = 1000, 640


def load_script() -> ModuleType:
    spec = importlib.util.spec_from_file_location("viewer_screenshot", SCRIPT)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


vs = load_script()


@pytest.fixture
def run_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    return rerun_run_dir(tmp_path / RUN, monkeypatch)


def test_no_chromium_is_one_line_and_exit_2(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setenv("PATH", str(tmp_path))  # nothing to find
    assert vs.main([str(tmp_path), "--out", str(tmp_path / "x.png")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Chromium not found" in err
    assert not (tmp_path / "x.png").exists()


def test_newest_run(tmp_path: Path) -> None:
    assert vs.newest_run(tmp_path) is None
    for name, mtime in (("20261121-100000", 1_000), ("20261121-090000", 2_000)):  # the later written wins
        (tmp_path / name).mkdir()
        (tmp_path / name / "recording.rrd").write_bytes(b"")
        os.utime(tmp_path / name / "recording.rrd", (mtime, mtime))
    (tmp_path / "20261121-110000").mkdir()  # no recording
    assert vs.newest_run(tmp_path) == tmp_path / "20261121-090000"


@needs_chromium
def test_web_viewer_renders_recording(run_dir: Path) -> None:
    chromium = vs.find_chromium()
    assert chromium is not None
    record_run(run_dir)
    lines: list[str] = []
    shot = vs.take_screenshot(
        run_dir,
        chromium=chromium,
        width=WIDTH,
        height=HEIGHT,
        settle=1.5,
        load_timeout=120.0,
        log=lines.append,
    )
    (run_dir / "viewer.png").write_bytes(shot.png)  # to look at when this fails
    # The viewer app started in the page and says it holds this run's recording.
    assert shot.loaded, (lines, run_dir / "viewer.png")
    assert f"recording_id={RUN}".encode() in shot.state
    # A PNG of the page's size showing the viewer drawn, not the dark loading page (a few
    # colours, one of them over nearly every pixel) nor a blank one. (The viewer's light
    # background covers ≈ 85 % of it.)
    image = Image.open(io.BytesIO(shot.png))
    assert image.format == "PNG" and image.size == (WIDTH, HEIGHT)
    colours = image.convert("RGB").getcolors(maxcolors=WIDTH * HEIGHT)
    assert colours is not None
    most = max(count for count, _ in colours)
    assert len(colours) > 200, f"{len(colours)} colours"
    assert most < 0.95 * WIDTH * HEIGHT, f"one colour covers {most / (WIDTH * HEIGHT):.0%}"
    # What was started has been stopped.
    for pid in (shot.viewer_pid, shot.browser_pid):
        assert not Path(f"/proc/{pid}").exists() or "zombie" in Path(f"/proc/{pid}/status").read_text()
