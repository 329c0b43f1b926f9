"""The report survives missing, empty and corrupt inputs: it notes them and carries on."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import msgspec
import pytest

from services.recorder.record import TRAFFIC_JSONL, TRAFFIC_RAW
from services.report import build_report, write_report
from shared.fipa_codec import Communicate, Performative, encode
from shared.fipa_codec.aid import aid
from shared.fipa_codec.languages.l_ex import Arm, CommandResult, Grasp
from shared.fipa_codec.languages.l_hfsm import GroundTaskNetwork, PlanFailure

MakeRun = Callable[..., Path]


def _notes(run_dir: Path) -> str:
    return "\n".join(build_report(run_dir).notes)


def test_missing_folder_raises_with_path(tmp_path: Path) -> None:
    missing = tmp_path / "no-such-run"
    with pytest.raises(FileNotFoundError, match="no-such-run"):
        build_report(missing)
    with pytest.raises(FileNotFoundError, match="no-such-run"):
        write_report(missing)


def test_empty_folder(tmp_path: Path) -> None:
    empty = tmp_path / "empty"
    empty.mkdir()
    report = build_report(empty)
    assert report.sizes.count == 0
    assert report.sizes.min_bytes is None and report.sizes.share_under_500 is None
    assert report.matrix.total == 0
    assert report.events == [] and report.plans == []
    assert not report.content.observed
    notes = "\n".join(report.notes)
    assert "no traffic record" in notes and "no run.json" in notes
    md = write_report(empty).read_text(encoding="utf-8")
    assert "| communicates | 0 |" in md
    assert "Spheres in the bowl: not observed" in md
    assert "No events" in md
    assert "no traffic record" in md


def test_empty_traffic_record(tmp_path: Path) -> None:
    run = tmp_path / "run"
    run.mkdir()
    (run / TRAFFIC_JSONL).write_bytes(b"")
    report = build_report(run)
    assert report.sizes.count == 0
    assert any("holds no communicates" in n for n in report.notes)


def test_corrupt_lines_are_skipped_and_noted(make_run: MakeRun, pour: Any) -> None:
    run = make_run(pour)
    lines = (run / TRAFFIC_JSONL).read_bytes().splitlines(keepends=True)
    lines.insert(3, b"{not json\n")
    lines.insert(7, b'{"seq": "x"}\n')
    (run / TRAFFIC_JSONL).write_bytes(b"".join(lines))
    report = build_report(run)
    assert report.sizes.count == 40
    assert report.matrix.total == 40
    notes = "\n".join(report.notes)
    assert "2 corrupt line(s) skipped (line 4, 8;" in notes
    md = write_report(run).read_text(encoding="utf-8")
    assert "2 corrupt line(s) skipped" in md
    assert "| communicates | 40 |" in md


def test_undecodable_payload_is_noted(make_run: MakeRun, pour: Any) -> None:
    # Replace the last observation's payload (17 of 20 in the bowl) with garbage: the report
    # falls back to the earlier observation (0 of 20) and still counts the record.
    last_obs = max(r.seq for r in pour.records if r.channel == "C5" and r.sender == "ag_ex")
    pour.payloads[last_obs] = b"\xc1\xc1 not msgpack"
    run = make_run(pour)
    report = build_report(run)
    assert report.sizes.count == 40
    notes = "\n".join(report.notes)
    assert f"1 payload(s) not the communicate their record describes (-/{last_obs})" in notes
    assert (report.content.inside, report.content.total) == (0, 20)
    assert report.content.t == pytest.approx(24.5)


def test_undecodable_content_is_noted(make_run: MakeRun, pour: Any) -> None:
    bad = Communicate(
        performative=Performative.INFORM,
        sender=aid("ag_ex"),
        receiver=(aid("a_ta"),),
        content=b"\x01\x02",
        language="L_SD",
        encoding="msgpack",
    )
    pour.payloads[3] = encode(bad)
    # the record describes the communicate it is paired with (else the pairing is refused)
    pour.records[3] = msgspec.structs.replace(
        pour.records[3],
        size=len(pour.payloads[3]),
        performative="inform",
        sender="ag_ex",
        conversation_id=None,
    )
    run = make_run(pour)
    assert "1 content(s) not decodable in their language (seq 3)" in _notes(run)


def test_truncated_raw_stream(make_run: MakeRun, pour: Any) -> None:
    run = make_run(pour)
    raw = (run / TRAFFIC_RAW).read_bytes()
    (run / TRAFFIC_RAW).write_bytes(raw[: len(raw) // 2])
    report = build_report(run)
    assert report.sizes.count == 40  # sizes come from the records
    notes = "\n".join(report.notes)
    assert f"{TRAFFIC_RAW} corrupt after" in notes
    assert "29 record(s) without payload" in notes


def test_missing_raw_stream_uses_metadata_and_run_json(make_run: MakeRun, pour: Any) -> None:
    run = make_run(pour)
    (run / TRAFFIC_RAW).unlink()
    report = build_report(run)
    assert report.sizes.count == 40
    assert [p.index for p in report.plans] == [1, 2]  # ordinals without content
    assert [p.c4_count for p in report.plans] == [6, 2]
    assert report.header.outcome_source == "run.json"
    assert report.header.succeeded is True
    assert report.header.command == "pour the jar into the bowl"
    assert not report.content.observed
    assert any(f"no {TRAFFIC_RAW}" in n for n in report.notes)


def test_without_run_json_times_count_from_first_record(make_run: MakeRun, pour: Any) -> None:
    run = make_run(pour, info=False)
    report = build_report(run)
    assert report.header.command_t == pytest.approx(9.0)  # first record at 1.0 s
    assert report.header.task_duration_s == pytest.approx(34.0)
    assert report.header.started_wall is None
    assert any("no run.json" in n for n in report.notes)
    write_report(run)


def test_failures_appear_in_timeline_and_planning(make_run: MakeRun, pour: Any) -> None:
    t = 50.0
    pour.add(t, "C5", "a_ta", "ag_ex", "request", Grasp(arm=Arm.RIGHT), conversation="ex-9")
    pour.add(
        t + 1,
        "C5",
        "ag_ex",
        "a_ta",
        "inform",
        CommandResult(command="grasp", ok=False, reason="no contact"),
        conversation="ex-9",
    )
    pour.add(
        t + 2,
        "C3",
        "a_co",
        "a_pl",
        "request",
        GroundTaskNetwork(task_id="cmd-1", tasks=(), plan_index=3),
        conversation="p3",
    )
    pour.add(
        t + 3,
        "C3",
        "a_pl",
        "a_co",
        "failure",
        PlanFailure(task_id="cmd-1", reason="jar unreachable"),
        conversation="p3",
    )
    report = build_report(make_run(pour))
    failed = [e for e in report.events if e.kind == "action_failed"]
    assert [e.text for e in failed] == ["right hand fails to grasp: no contact"]
    assert failed[0].start == pytest.approx(51.0)
    assert report.plans[-1].outcome == "failed: jar unreachable"
    assert any(e.kind == "plan_failed" for e in report.events)
    assert [e for e in report.events if e.kind == "self_contact"] == []


def test_a_command_that_made_the_robot_touch_itself_is_in_the_timeline(make_run: MakeRun, pour: Any) -> None:
    touched = ("left_arm_3_link + left_ft_geom",)
    pour.add(50.0, "C5", "a_ta", "ag_ex", "request", Grasp(arm=Arm.LEFT), conversation="ex-9")
    result = CommandResult(command="grasp", ok=True, self_contacts=touched)
    pour.add(51.0, "C5", "ag_ex", "a_ta", "inform", result, conversation="ex-9")
    report = build_report(make_run(pour))
    events = [e for e in report.events if e.kind == "self_contact"]
    assert [e.text for e in events] == [f"the robot touched itself during Grasp: {touched[0]}"]
    assert events[0].start == pytest.approx(51.0)
