"""What is recorded: the traffic recorder's writer puts fault events in faults.jsonl (and
nothing when none came), the report's section 8 lists them grouped; the launcher keeps the
environment a service is started again with."""

from __future__ import annotations

from pathlib import Path

import msgspec
import pytest

from services.fleet.launcher import process_environ, save_launch_env
from services.recorder.record import FAULTS_JSONL, read_fault_events
from services.recorder.recorder import TrafficWriter
from services.report import build_report
from services.report.markdown import render
from services.runtime.faults import FaultEvent
from services.runtime.run_folder import LAUNCH_ENV, RunInfo, load_launch_env, write_run_info


def ev(t: float, kind: str, agent: str = "a_km", **kw: str) -> bytes:
    return msgspec.json.encode(FaultEvent(t=t, agent=agent, kind=kind, **kw))


def test_writer_records_fault_events_only_when_there_are_some(tmp_path: Path) -> None:
    w = TrafficWriter(tmp_path)
    w.write(1.0, "roco/fipa/C4/a_pl/a_km", b"\xc1")
    w.flush()
    assert not (tmp_path / FAULTS_JSONL).exists()
    assert w.fault(ev(2.0, "drop", channel="C4", conversation_id="c1"))
    assert not w.fault(b"{not an event")
    w.close()
    events, bad = read_fault_events(tmp_path)
    assert bad == 0 and [(e.kind, e.conversation_id) for e in events] == [("drop", "c1")]


def test_report_lists_injected_faults_grouped(tmp_path: Path) -> None:
    write_run_info(tmp_path, RunInfo(started=100.0))
    lines = [
        ev(101.0, "settings", detail='{"channels":{"C4":{"drop":0.5}}}'),
        ev(101.2, "settings", agent="a_co", detail='{"channels":{"C4":{"drop":0.5}}}'),
        ev(102.0, "drop", channel="C4"),
        ev(103.5, "drop", channel="C4"),
        ev(104.0, "kill", agent="roco", target="a_km", detail="pid 42"),
    ]
    (tmp_path / FAULTS_JSONL).write_bytes(b"\n".join(lines) + b"\nnot json\n")
    report = build_report(tmp_path)
    rows = [(f.kind, f.by, f.where, f.count, round(f.first_t, 3), round(f.last_t, 3)) for f in report.faults]
    assert rows == [
        ("settings", "a_co, a_km", "—", 2, 1.0, 1.2),
        ("drop", "a_km", "C4", 2, 2.0, 3.5),
        ("kill", "roco", "a_km", 1, 4.0, 4.0),
    ]
    assert any("faults.jsonl: 1 unreadable line" in n for n in report.notes)
    text = render(report)
    assert "## 8. Injected faults" in text and "| drop | a_km | C4 | 2 | 2.0 | 3.5 |" in text


def test_report_without_faults_has_no_fault_section(tmp_path: Path) -> None:
    write_run_info(tmp_path, RunInfo(started=100.0))
    report = build_report(tmp_path)
    assert report.faults == [] and "Injected faults" not in render(report)


def test_launch_environment_is_kept_for_a_later_start(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("ROCO_FAULTS", '{"seed": 1}')
    env = process_environ(tmp_path, "tcp/127.0.0.1:1", {"ROCO_REALTIME": "0", "OTHER": "x"})
    save_launch_env(tmp_path, env, {"ROCO_REALTIME": "0", "OTHER": "x"})
    assert (tmp_path / LAUNCH_ENV).exists()
    monkeypatch.setenv("ROCO_FAULTS", "changed since")
    monkeypatch.setenv("ROCO_STRAY", "not at launch")
    later = load_launch_env(tmp_path)
    assert later is not None
    assert later["ROCO_FAULTS"] == '{"seed": 1}' and later["ROCO_ROUTER"] == "tcp/127.0.0.1:1"
    assert later["ROCO_RUN_DIR"] == str(tmp_path) and later["OTHER"] == "x" and "ROCO_STRAY" not in later
    assert load_launch_env(tmp_path / "nowhere") is None
