"""The report of a complete synthetic pour run (see conftest.py): counts, sizes, the Table 8
matrix, the Table 7 timeline, planning phases, sphere share, and the Markdown."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import msgspec
import pytest

from services.report import Event, Report, build_report, paper, write_report
from shared.fipa_codec.languages.l_ex import LookAt
from tests.report.conftest import RunBuilder
from velma.world.timing import WorldTiming

COMMAND = "pour the jar into the bowl"


@pytest.fixture
def report(run_dir: Path) -> Report:
    return build_report(run_dir)


def _event(report: Report, kind: str, n: int = 0) -> Event:
    found = [e for e in report.events if e.kind == kind]
    assert len(found) > n, f"no event #{n} of kind {kind}: {report.events}"
    return found[n]


def test_counts_and_sizes(report: Report, pour: Any) -> None:
    sizes = pour.sizes()
    s = report.sizes
    assert s.count == 40
    assert s.total_bytes == sum(sizes)
    assert s.min_bytes == min(sizes)
    assert s.max_bytes == max(sizes)
    assert s.max_bytes is not None and s.max_bytes > 3000  # the Answer with 20 grasps
    assert s.mean_bytes == pytest.approx(sum(sizes) / 40)
    small = sum(1 for n in sizes if n < 500)
    assert small >= 30  # the pour's communicates are small but for a few (plans, the answer)
    assert s.under_500 == small
    assert s.share_under_500 == pytest.approx(small / 40)


def test_channels(report: Report, pour: Any) -> None:
    counts = {c.channel: c.count for c in report.channels}
    assert counts == {"C1": 10, "C2": 3, "C3": 4, "C4": 8, "C5": 10, "C6": 5}
    c4_bytes = sum(r.size for r in pour.records if r.channel == "C4")
    assert {c.channel: c.bytes for c in report.channels}["C4"] == c4_bytes


def test_table8_matrix(report: Report) -> None:
    m = report.matrix
    assert m.agents == ["a_co", "a_hi", "a_km", "a_pl", "a_ta", "ag_ex"]
    nonzero = {r: {s: n for s, n in row.items() if n} for r, row in m.cells.items()}
    assert nonzero == {
        "a_co": {"a_hi": 1, "a_pl": 2, "a_ta": 4},
        "a_hi": {"a_co": 2},
        "a_km": {"a_ta": 4, "a_pl": 4},
        "a_pl": {"a_co": 2, "a_km": 4},
        "a_ta": {"a_km": 1, "ag_ex": 5, "a_co": 6},
        "ag_ex": {"a_ta": 5},
    }
    assert m.received == {"a_co": 7, "a_hi": 2, "a_km": 8, "a_pl": 6, "a_ta": 12, "ag_ex": 5}
    assert m.sent == {"a_co": 10, "a_hi": 1, "a_km": 5, "a_pl": 6, "a_ta": 13, "ag_ex": 5}
    assert m.total == 40


def test_header(report: Report) -> None:
    h = report.header
    assert h.command == COMMAND
    assert h.succeeded is True
    assert h.detail == "poured 17 of 20"
    assert h.outcome_source == "C2 CommandOutcome"
    assert h.command_t == pytest.approx(10.0)
    assert h.finished_t == pytest.approx(44.0)
    assert h.task_duration_s == pytest.approx(34.0)


def test_timeline(report: Report) -> None:
    init = _event(report, "initial_knowledge")
    assert (init.start, init.end) == pytest.approx((1.0, 3.0))
    assert init.channels == ["C5", "C6"]
    assert _event(report, "command").start == pytest.approx(10.0)
    assert COMMAND in _event(report, "command").text
    req = [e.start for e in report.events if e.kind == "plan_request"]
    assert req == pytest.approx([12.0, 27.0])
    p1, p2 = _event(report, "planning", 0), _event(report, "planning", 1)
    assert (p1.start, p1.end) == pytest.approx((12.0, 16.0))
    assert "plan #1" in p1.text and "6 communicates on C4" in p1.text
    assert (p2.start, p2.end) == pytest.approx((27.0, 28.0))
    assert "2 communicates on C4" in p2.text
    got = [(e.start, e.text) for e in report.events if e.kind == "plan_received"]
    assert [t for t, _ in got] == pytest.approx([17.0, 29.0])
    assert "partial" in got[0][1] and "complete" in got[1][1]
    x1, x2 = _event(report, "execution", 0), _event(report, "execution", 1)
    assert (x1.start, x1.end) == pytest.approx((18.0, 26.0))
    assert "plan #1" in x1.text and "Replan" in x1.text
    assert (x2.start, x2.end) == pytest.approx((31.0, 43.0))
    assert "plan #2" in x2.text and "Succeeded" in x2.text
    grasp = _event(report, "grasp")
    assert grasp.start == pytest.approx(21.0)
    assert grasp.text == "left hand grasps (step fetch_jar/grasp)"
    assert _event(report, "tilt").start == pytest.approx(40.0)
    obs = [e for e in report.events if e.kind == "observation"]
    assert [e.start for e in obs] == pytest.approx([24.5, 42.0])
    assert obs[0].text.startswith("bowl localised")
    assert "17 of 20 spheres in the bowl (2 of them inferred, not seen)" in obs[1].text
    env = [e for e in report.events if e.kind == "environment"]
    assert [(e.start, e.end) for e in env] == [
        (pytest.approx(22.0), None),
        (pytest.approx(24.5), pytest.approx(25.0)),
    ]
    assert env[1].channels == ["C5", "C6"]
    fin = _event(report, "finished")
    assert fin.start == pytest.approx(44.0)
    assert "succeeded" in fin.text
    starts = [e.start for e in report.events]
    assert starts == sorted(starts)


def test_planning_phases(report: Report, pour: Any) -> None:
    p1, p2 = report.plans
    assert (p1.index, p1.c4_count, p1.c4_queries, p1.km_queries) == (1, 6, 3, 3)
    assert (p1.planning_time_s, p1.complete, p1.outcome) == (4.8, False, "partial")
    assert (p2.index, p2.c4_count, p2.c4_queries, p2.km_queries) == (2, 2, 1, 1)
    assert (p2.planning_time_s, p2.complete, p2.outcome) == (1.9, True, "complete")
    c4 = [(r.t - 1_700_000_000.0, r.size) for r in pour.records if r.channel == "C4"]
    b1 = sum(size for t, size in c4 if t < 20)
    assert p1.c4_bytes == b1
    assert p1.mean_kbps == pytest.approx(b1 * 8 / 1000 / 5.0)  # 12.0 → 17.0 s
    # 1 s bins from 12.0: the largest holds the 14.0 s answer and the 14.5 s query
    big = sum(size for t, size in c4 if 14.0 <= t < 15.0)
    assert p1.peak_kbps == pytest.approx(big * 8 / 1000)


def test_sphere_share(report: Report) -> None:
    c = report.content
    assert c.observed and c.container == "bowl"
    assert (c.inside, c.total) == (17, 20)
    assert (c.seen, c.inferred, c.look) == (15, 2, 1)
    assert c.share == pytest.approx(0.85)
    assert c.t == pytest.approx(42.0)
    assert c.stamp == pytest.approx(30.0)


def test_the_content_counted_after_a_turn_of_the_head_is_the_second_look(
    make_run: Callable[..., Path], pour: RunBuilder
) -> None:
    # a_ta turns the head to the bowl after the pour (verdict.py: the inferred spheres decided)
    pour.add(
        40.5,
        "C5",
        "a_ta",
        "ag_ex",
        "request",
        LookAt(point=(0.4, 0.0, 0.8)),
        conversation="ex-look",
        protocol="fipa-request",
        reply_with="rl",
    )
    run = make_run(pour)
    assert build_report(run).content.look == 2
    assert "15 seen and 2 inferred behind its wall (not seen), at the second look" in write_report(
        run
    ).read_text(encoding="utf-8")


def test_no_notes_for_clean_run(report: Report) -> None:
    assert report.notes == []


def test_markdown(run_dir: Path, pour: Any) -> None:
    path = write_report(run_dir)
    assert path == run_dir / "report.md"
    md = path.read_text(encoding="utf-8")
    sizes = pour.sizes()
    assert f"| communicates | 40 | {paper.COMMUNICATES} " in md
    assert f"| min size | {min(sizes)} B | 231 B |" in md
    assert f"{sum(sizes) / 40:.1f} B" in md
    assert f"{max(sizes)} B ({max(sizes) / 1000:.1f} kB)" in md
    small = sum(1 for n in sizes if n < 500)
    assert f"{small / 40 * 100:.1f} % ({small} of 40)" in md
    assert "| 86 % |" in md
    assert "20.0 s robot time; 34.0 s wall (human command at 10.0 s → outcome at 44.0 s)" in md
    # the paper's robot ran in real time: its duration is set beside this run's robot time
    assert "| task duration (robot time) | 20.0 s robot time | 778 s from the log's start" in md
    assert "| task duration (wall clock) | 34.0 s | the same (a real robot) |" in md
    assert "succeeded — poured 17 of 20" in md
    # Table 8, ours and the paper's
    assert "| a_ta | 6 |  | 1 |  |  | 5 | 12 |" in md
    assert "| send | 10 | 1 | 5 | 6 | 13 | 5 | 40 |" in md
    assert "| a_km |  |  |  | 925 | 83 | 24 | 1032 |" in md
    assert "| send | 6 | 1 | 815 | 927 | 92 | 24 | 1865 |" in md
    # timeline, ours and the paper's
    # robot time from ag_ex's answers (— before the first and after the last), then wall time
    assert "| —–0.7 | 1.0–3.0 | a_km receives an initial knowledge" in md
    assert "| 4.6–6.3 | 12.0–16.0 | a_pl generates the plan #1" in md
    assert "| 8.5 | 21.0 | left hand grasps (step fetch_jar/grasp) | C5 |" in md
    assert "| — | 44.0 | the task is finished: succeeded" in md
    # the sections present are numbered 1, 2, 3, … without a gap (no faults, no camera here)
    numbers = [
        int(line[3:].split(".")[0]) for line in md.splitlines() if line[:3] == "## " and line[3].isdigit()
    ]
    assert numbers == list(range(1, len(numbers) + 1)) and len(numbers) == 7
    assert "| 97–152 | a_pl generates the plan #1, and queries a_km | C4 |" in md
    # planning and content
    assert "| #1 | 12.0 | 17.0 | 6 |" in md
    assert "| partial |" in md and "| complete |" in md
    assert "| #1 | 97 | 153 | 1598 |" in md
    assert "17 of 20 spheres (85.0 %) ended in the bowl: 15 seen and 2 inferred behind its wall" in md
    assert "at the first look" in md
    assert "None: every file was read completely." in md


def test_control_loop_section(run_dir: Path, control_timing: Any) -> None:
    report = build_report(run_dir)
    assert report.control == control_timing
    text = write_report(run_dir).read_text(encoding="utf-8")
    section = text.split("## 6. Control loop")[1].split("## Notes")[0]
    assert "14 overruns (0.025 %)" in section
    assert "SCHED_FIFO priority 80, pinned to CPU 1" in section
    assert "Impedance law: compiled. MuJoCo side of the cycle: compiled." in section
    assert "| compute time per cycle (µs) | 410 | 720 | 1300 |" in section
    assert "CPU wake-up latency held at 0 µs (PM QoS)" in section
    assert "3 cycles took over 1 ms; 2 cycles stalled (off their CPU for more than 100 µs" in section
    assert "at most 950 µs); the longest other cycle took 1100 µs." in section


def test_control_loop_section_shows_the_world_process_s_cycle_beside_the_loop_s(
    run_dir: Path, control_timing: Any
) -> None:
    world = WorldTiming(
        pacing="realtime",
        cycles=57_000,
        paced=57_000,
        late=12,
        late_max_us=151_300.0,
        resets=1,
        stalls=2,
        gap_max_us=152_000.0,
        held=900,
        waits=0,
        wait_max_us=0.0,
        stale=7,
        stale_worst_age=3,
        stale_by_age=(4, 2, 1, 0),
    )
    timing = msgspec.structs.replace(control_timing, world=world)
    (run_dir / "ag_ex_timing.json").write_bytes(msgspec.json.encode(timing))
    assert build_report(run_dir).control == timing
    section = write_report(run_dir).read_text(encoding="utf-8").split("## 6. Control loop")[1]
    section = section.split("## Notes")[0]
    assert "| cycles (of them paced on the wall clock) | 57000 (57000) |  |" in section
    assert "| late cycles (started over 1 ms after due) | 12 | 151300 µs |" in section
    assert "| schedule resets (over 100 ms behind) | 1 |  |" in section
    assert "| stalls (over 10 ms between cycle starts, waits excluded) | 2 | 152000 µs |" in section
    assert "| stale commands (by age 1 … 4 cycles: 4 / 2 / 1 / 0) | 7 | age 3 |" in section
    assert "| steps held (no command applied) | 900 |  |" in section
    assert "pacing: realtime" in section


def test_control_loop_section_without_a_world_process_says_so(run_dir: Path) -> None:
    section = write_report(run_dir).read_text(encoding="utf-8").split("## 6. Control loop")[1]
    assert "**The world's cycle.** No figures" in section.split("## Notes")[0]


def test_control_loop_missing_or_corrupt(make_run: Callable[..., Path], pour: Any) -> None:
    missing = make_run(pour, timing=False, name="a")
    report = build_report(missing)
    assert report.control is None
    assert any("ag_ex_timing.json" in n for n in report.notes)
    assert "Not recorded" in write_report(missing).read_text(encoding="utf-8")
    corrupt = make_run(pour, name="b")
    (corrupt / "ag_ex_timing.json").write_text("{not json")
    report = build_report(corrupt)
    assert report.control is None
    assert any("unreadable" in n for n in report.notes)


def test_access_control_row_names_refusals_and_recorded_spoofs(
    make_run: Callable[..., Path], pour: Any
) -> None:
    """The report's header says what the router refused (refusals.jsonl) and how many
    recorded communicates claim another sender than their key's; no row without the file."""
    import msgspec

    from services.runtime.refusals import REFUSALS_JSONL, Refusal

    plain = make_run(pour, name="plain")
    assert build_report(plain).header.access_control == ""
    assert "| Access control |" not in write_report(plain).read_text()
    pour.records[3] = msgspec.structs.replace(pour.records[3], key_sender="a_pl")  # claims another
    d = make_run(pour, name="acl")
    put = {"message": "put", "flow": "ingress", "session": "z", "identity": "a_pl"}
    refused = [
        Refusal(t=1.0, key="roco/fipa/C1/a_co/a_ta", **put),
        Refusal(t=2.0, key="roco/fipa/C1/a_pl/a_ta", **put),
        Refusal(t=3.0, identity="a_hi", message="declare_subscriber", flow="egress", key="k", session="y"),
    ]
    lines = b"".join(msgspec.json.encode(r) + b"\n" for r in refused)
    (d / REFUSALS_JSONL).write_bytes(lines + b"not json\n")
    line = build_report(d).header.access_control
    assert line.startswith("on; 2 message(s) refused (a_pl 2)"), line
    assert "; 1 recorded communicate(s) claim another sender" in line, line
    assert f"| Access control | {line} |" in write_report(d).read_text()


def test_the_header_says_what_the_robot_perceived_with(make_run: Callable[..., Path], pour: Any) -> None:
    """Without ``ag_ex_perception.jsonl`` the header says no head-camera Observation was logged
    (the ground truth answered); with it, how many Observations the perception section compares."""
    import msgspec

    from services.report.model import PerceptionRow
    from velma.executor.capture import PERCEPTION_LOG

    truth = make_run(pour, name="truth")
    assert "| Perception | no head-camera Observation logged: the physics' ground truth" in (
        write_report(truth).read_text()
    )
    camera = make_run(pour, name="camera")
    rows = [
        PerceptionRow(sim_time=9.6, object="bowl", seen=True, error_mm=3.0),
        PerceptionRow(sim_time=9.6, object="jar", seen=True, error_mm=4.0),
        PerceptionRow(sim_time=30.1, object="bowl", seen=True, error_mm=2.0),
    ]
    (camera / PERCEPTION_LOG).write_bytes(b"".join(msgspec.json.encode(r) + b"\n" for r in rows))
    assert build_report(camera).perception == rows
    text = write_report(camera).read_text()
    # no faults were injected: the perception section follows the seventh without a gap
    assert "| Perception | head camera: 2 Observation(s), beside the ground truth in section 8 |" in text
    assert "## 8. Perception (head camera)" in text


def test_the_link_row_says_what_the_link_between_the_hosts_carried(
    make_run: Callable[..., Path], pour: Any
) -> None:
    """A run of two hosts: the relay's count per second (link_bytes.jsonl) and the link
    device's counters (link.jsonl) make one header row; a run on one host has none."""
    plain = make_run(pour, name="one_host")
    assert build_report(plain).header.link == ""
    d = make_run(pour, name="two_hosts")
    seconds = [
        {"t": 100, "up": 1000, "down": 250},
        {"t": 101, "up": 0, "down": 0},
        {"t": 103, "up": 500, "down": 0},
    ]
    (d / "link_bytes.jsonl").write_text("".join(json.dumps(s) + "\n" for s in seconds) + "garbage\n")
    counters = {
        "t": 104.0,
        "event": "counters",
        "tx_bytes": 2100,
        "tx_packets": 9,
        "rx_bytes": 600,
        "rx_packets": 7,
    }
    (d / "link.jsonl").write_text(json.dumps(counters) + "\n")
    line = build_report(d).header.link
    assert line.startswith("robot → brain 1.5 kB, brain → robot 0.2 kB over 4 s: mean 3.5 kbit/s"), line
    assert "busiest second 10.0 kbit/s" in line
    assert "on the link device: robot → brain 2.1 kB in 9 packets, brain → robot 0.6 kB in 7" in line
    assert f"| Link between the hosts | {line} |" in write_report(d).read_text()


def test_the_ledger_row_holds_ag_ex_s_ledger_against_the_record(run_dir: Path) -> None:
    """The header's "ag_ex's ledger" row (services/report/ledger.py): without a ledger every
    done answer is unaccounted for; a ledger with a run of each agrees; a start written twice
    (planted) is named."""
    from services.report.load import load_run
    from tests.support.ledger import ran
    from velma.executor.ledger import LEDGER_FILE

    answers = load_run(run_dir).messages
    done = sorted(
        {m.conversation or "" for m in answers if m.sender == "ag_ex" and m.performative == "inform"}
    )
    assert len(done) >= 3 and "" not in done
    row = "| ag_ex's ledger | no ledger (ag_ex_ledger.jsonl): answered done, never ran: "
    assert row in write_report(run_dir).read_text()
    ran(run_dir, *((c, "move_tool", float(k), k + 0.5) for k, c in enumerate(done)))
    agrees = (
        f"| ag_ex's ledger | {len(done)} command(s) started by 1 ag_ex process(es): nothing executed twice"
    )
    assert agrees in write_report(run_dir).read_text()
    first = (run_dir / LEDGER_FILE).read_text().splitlines(keepends=True)[0]
    with (run_dir / LEDGER_FILE).open("a") as f:
        f.write(first)
    twice = f"executed twice: move_tool ({done[0]}): started at 0.000, 0.000 s"
    assert twice in write_report(run_dir).read_text()
