"""``roco bench`` (services/bench/): the quickest run of two parts writes the tables it should,
with positive figures; no timing is asserted (figures depend on the machine)."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest
import typer

from services.bench import parts, quiet, report, runner
from services.bench.gateway import BurstFigures, GatewayFigures, LoadFigures, WorstRow
from services.bench.jade import JadeFigures
from services.bench.messaging import (
    BenchInform,
    BenchRequest,
    ConcurrentFigures,
    Latency,
    MessagingFigures,
    PairFigures,
    ScaleRow,
    Throughput,
    bench_spec,
    median_run,
    pair_names,
    percentile,
    request_bytes,
    sized_data,
    steady_rate,
)
from services.bench.parts import (
    CodecRow,
    FleetFigures,
    MemoryFigures,
    PlanningFigures,
    QueryRow,
    TaskRun,
)
from services.bench.report import (
    condition_lines,
    memory_table,
    memory_verdicts,
    scale_table,
    scale_verdicts,
)
from services.bench.spade import SpadeFigures
from services.report.model import PlanPhase
from services.spec.model import interface
from shared.fipa_codec.languages import encode_content
from velma.executor.timing import TimingStats

ROOT = Path(__file__).resolve().parents[2]
bench_stop = parts.scripts_module("bench_stop")
bench_reading = parts.scripts_module("bench_reading")


def _rows(text: str, section: str) -> list[list[str]]:
    """The body rows of the first table after the heading ``section``."""
    part = text.split(section, 1)[1]
    rows = []
    started = False
    for line in part.splitlines():
        if line.startswith("|"):
            started = True
            rows.append([c.strip() for c in line.strip("|").split("|")])
        elif started:
            break
    return rows[2:]  # header and separator


def _number(cell: str) -> float:
    return float(cell.replace(",", "").split()[0])


@pytest.mark.parametrize("size", [0, 50, 200, 300, 10_000])
def test_content_has_the_size_asked_for(size: int) -> None:
    _, body = encode_content(BenchInform(seq=0, data=sized_data(size)))
    assert len(body) == max(size, len(encode_content(BenchInform(seq=0, data=b""))[1]))


def test_synthetic_spec_lets_a_pair_request_and_inform() -> None:
    spec = bench_spec(3)
    ini, par = pair_names(2)
    receives = {(k.sender, k.performative, k.protocol) for k in interface(spec, par).receives}
    assert (ini, "request", "fipa-request") in receives
    assert (ini, "subscribe", "fipa-subscribe") in receives
    sends = {(k.receiver, k.performative, k.protocol) for k in interface(spec, par).sends}
    assert (ini, "inform", "fipa-request") in sends
    assert (ini, "inform", "fipa-subscribe") in sends
    assert request_bytes(200) > len(encode_content(BenchRequest(seq=1, data=sized_data(200)))[1])


def test_a_stream_rate_leaves_out_what_its_first_stamp_counted() -> None:
    runs = Throughput()
    runs.add({"count": 1000, "span_s": 0.01, "first": 900}, 1000)  # 900 piled up before the first step
    runs.add({"count": 1001, "span_s": 0.01}, 1001)  # a counter stamping each arrival: one at the first
    runs.add({"count": 500, "span_s": 0.0, "first": 500}, 1000)  # all in one step: no rate, 500 lost
    assert runs.rates == [pytest.approx(10_000.0), pytest.approx(100_000.0), 0.0]
    assert runs.lost == 500


def test_percentile_is_nearest_rank() -> None:
    assert percentile([], 50) == 0.0
    assert percentile([3.0, 1.0, 2.0], 50) == 2.0
    assert percentile([float(i) for i in range(101)], 99) == 99.0


def test_steady_rate_counts_only_while_every_pair_runs() -> None:
    # pair 0 ends round trips at 0..10 s, one a second; pair 1 starts late (4 s) and ends early (8 s)
    first = [float(t) for t in range(11)]
    second = [4.0, 5.0, 6.0, 7.0, 8.0]
    # window (4, 8]: pair 0 ends 4 (5, 6, 7, 8), pair 1 ends 4 (5, 6, 7, 8) in 4 s
    assert steady_rate([first, second]) == 2.0
    assert steady_rate([[1.0, 2.0], [3.0, 4.0]]) == 0.0  # never both running
    assert steady_rate([first, []]) == 0.0
    assert steady_rate([]) == 0.0


def _row(agents: int, roco_per_s: float, raw_per_s: float | None) -> ScaleRow:
    def figures(rate: float) -> ConcurrentFigures:
        return ConcurrentFigures(Latency([0.001]), rate, rate)

    raw = figures(raw_per_s) if raw_per_s is not None else None
    return ScaleRow(agents, 1.0, 100.0, PairFigures(), figures(roco_per_s), 1, raw)


def test_the_scale_verdict_sets_roco_beside_raw_zenohs_own_share() -> None:
    (line,) = scale_verdicts([_row(10, 2000.0, 8000.0), _row(100, 1300.0, 3600.0)])
    assert "**65.0 %**" in line and ": met;" in line
    assert "raw Zenoh's own processes, measured the same way: 45 % (3,600 against 8,000 /s)" in line
    (line,) = scale_verdicts([_row(10, 2000.0, None), _row(100, 1000.0, None)])
    assert "**50.0 %**" in line and ": missed;" in line and "raw Zenoh" not in line
    (line,) = scale_verdicts([_row(10, 2000.0, None), _row(100, 1198.0, None)])
    assert "**59.9 %**" in line and ": missed;" in line  # not shown as the 60 % it misses


def test_all_pairs_runs_are_taken_as_their_median_and_shown_each() -> None:
    runs = [ConcurrentFigures(Latency([0.001 * k]), 10.0 * k, 100.0 * k) for k in (3, 1, 2)]
    median = median_run(runs)
    assert (median.round_trips_per_s, median.steady_per_s) == (20.0, 200.0)
    assert median.steady_runs == [300.0, 100.0, 200.0]
    assert sorted(median.latency.samples_s) == [0.001, 0.002, 0.003]
    with pytest.raises(ValueError, match="no all-pairs run"):
        median_run([])
    row = ScaleRow(10, 1.0, 100.0, PairFigures(), median, 1, median_run(runs[:1]))
    cells = scale_table([row])[-1].split("|")
    assert cells[-3].strip() == "200 (300, 100, 200)" and cells[-2].strip() == "300"


def test_the_memory_verdicts_take_the_largest_agent_and_the_fleet_at_rest() -> None:
    synthetic = {"b_ini0": (33.0, 19.0), "b_par0": (35.5, 19.5), "router": (40.0, 18.0)}
    fleet = {
        "fleet, camera process running": {"a_km": (69.0, 300.0), "ag_ex": (60.0, 100.0)},
        "fleet at rest": {"a_km": (69.0, 250.0), "ag_ex": (60.0, 99.0)},
    }
    agent, whole = memory_verdicts(MemoryFigures(synthetic, fleet))
    assert "**35.5 MiB**" in agent and agent.endswith("missed.")  # b_par0 over 35; the router not an agent
    assert "**349 MiB** PSS" in whole and "met" in whole and "camera process running: 400 MiB" in whole
    rows = memory_table(MemoryFigures(synthetic, fleet))
    assert rows[:3] == [
        "| idle synthetic pair | VmRSS MiB | PSS MiB |",
        "|---|---|---|",
        "| b_ini0 | 33.0 | 19.0 |",
    ]
    assert "| **total** | **108.5** | **56.5** |" in rows
    # the fleet: one VmRSS and one PSS column per state, the states' totals side by side
    assert "| a_km | 69.0 | 300.0 | 69.0 | 250.0 |" in rows
    assert "| **total** | **129.0** | **400.0** | **129.0** | **349.0** |" in rows
    header = next(r for r in rows if r.startswith("| `roco up`'s fleet"))
    assert "camera process running: VmRSS MiB" in header and "at rest: VmRSS MiB" in header


def test_a_process_missing_from_a_state_shows_a_dash() -> None:
    fleet = {"fleet, camera process running": {"ag_ex's velma-camera": (220.0, 195.0)}, "fleet at rest": {}}
    rows = memory_table(MemoryFigures({}, fleet))
    assert "| ag_ex's velma-camera | 220.0 | 195.0 | — | — |" in rows


def test_quick_bench_writes_codec_and_messaging_tables(tmp_path: Path) -> None:
    out = tmp_path / "benchmarks.md"
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "services.cli",
            "bench",
            "--quick",
            "--only",
            "codec,messaging",
            "--out",
            str(out),
        ],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    text = out.read_text()
    assert "Load average" in text and "roco bench --quick --only codec,messaging" in text
    assert "The machine's quiet was not waited for (`--settle 0`)" in text  # --quick's default
    codec = _rows(text, "## 1. Codec")
    assert [r[0] for r in codec] == ["200 B", "10 kB", "1 MB"]
    for r in codec:
        assert _number(r[2]) > 0 and _number(r[3]) > 0  # encode, decode µs
    messaging = _rows(text, "## 2–3. Messaging")
    systems, links = [r[0] for r in messaging], [r[1] for r in messaging]
    # each testbed: roco, raw Zenoh polling then sleeping on the same link, roco's stream batched
    assert links == ["mutual TLS + ACL, one hop"] * 4 + ["TCP, no ACL, one hop"] * 4
    for first in (0, 4):
        roco, polling, sleeping, batched = messaging[first : first + 4]
        assert roco[0].startswith("roco (Agent runtime") and "one communicate per put" in roco[0]
        assert "each end polling as roco's" in polling[0] and "each end sleeping" in sleeping[0]
        assert batched[0].startswith("roco, stream batched: the 256 informs of a step in one put")
        for r in (roco, polling, sleeping):
            p50, p90, p99, count = _number(r[2]), _number(r[3]), _number(r[4]), _number(r[5])
            assert 0 < p50 <= p90 <= p99 and count == 300
        for r in (roco, polling, batched):  # streams: roco one per put, raw Zenoh, roco batched
            assert _number(r[6]) > 0 and r[8] == "0"
    assert systems[0] == systems[4] and "mutual TLS + ACL" in text
    targets = text.split("## Targets", 1)[1].split("\n## ", 1)[0]
    assert "roco round trip / raw Zenoh's on the same link, both polling" in targets
    assert "Access control and mutual TLS: roco's round trip" in targets
    assert text.index("## This run") < text.index("## Targets") < text.index("## 1. Codec")


def test_settle_waits_for_a_quiet_window_and_says_so_when_there_is_none() -> None:
    # busy, stolen and idle ticks after each reading: a 1 s window is the difference of two
    ticks = iter([(0, 0, 0), (60, 30, 10), (60, 30, 10), (65, 125, 10)])
    waits: list[float] = []

    def reader() -> quiet.CpuTimes:
        busy, idle, steal = next(ticks)
        return quiet.CpuTimes(busy, idle, steal)

    got = quiet.settle(10.0, reader=reader, sleep=waits.append)
    # the first window was 60 % busy and 10 % stolen; the second 5 % busy, none stolen: quiet
    assert got.quiet and got.waited_s == 2.0 and waits == [1.0, 1.0]
    assert got.last == quiet.Share(busy=0.05, steal=0.0)
    assert "quiet" in got.text() and "waited 2 s" in got.text()
    noisy = iter([quiet.CpuTimes(0, 0, 0), quiet.CpuTimes(50, 50, 0)] * 3)
    got = quiet.settle(2.0, reader=lambda: next(noisy), sleep=lambda s: None)
    assert not got.quiet and got.waited_s == 2.0 and "still not quiet (50 % busy" in got.text()
    assert quiet.settle(5.0, reader=lambda: None, sleep=lambda s: None).last is None


def test_cpu_times_are_read_from_proc_stat(tmp_path: Path) -> None:
    stat = tmp_path / "stat"
    stat.write_text("cpu  10 1 5 100 4 2 3 7 0 0\ncpu0 5 0 2 50 2 1 1 3 0 0\n")
    assert quiet.read(stat) == quiet.CpuTimes(busy=21, idle=104, steal=7)
    assert quiet.read(tmp_path / "missing") is None
    assert quiet.share(quiet.CpuTimes(0, 0, 0), quiet.CpuTimes(30, 60, 10)) == quiet.Share(0.3, 0.1)


def test_the_head_says_how_busy_the_machine_was_around_the_timed_parts() -> None:
    lines = condition_lines(
        ["before messaging: waited 3 s; quiet (4 % busy, 0 % stolen over the last 1 s)"], 90
    )
    assert lines[0].startswith("- Before each timed part `roco bench` waited up to 90 s for a quiet machine")
    assert lines[1] == "  - before messaging: waited 3 s; quiet (4 % busy, 0 % stolen over the last 1 s)"
    assert condition_lines([], 0) == ["- The machine's quiet was not waited for (`--settle 0`)."]


def _stop_figures(
    plain: list[float] | None = None, long: list[float] | None = None, asked: int = 20, idle: int = 1
) -> object:
    """bench_stop's figures: the two conditions' halts (ms), the cancels' medians, the run's
    settings."""
    plain = [10.7] * 19 + [18.6] if plain is None else plain
    long = [24.4] * 19 + [55.4] if long is None else long
    return bench_stop.StopFigures(
        asked=asked,
        halts_ms={"plain": plain, "long line before": long},
        idle={"plain": idle, "long line before": 0},
        hops_ms={
            "plain": {"C2": 2.3, "C1": 5.3, "C5": 9.9},
            "long line before": {"C2": 13.2, "C1": 17.4, "C5": None},
        },
        first_pour_s=61.2,
        first_pour="succeeded",
        window_s=6.0,
        realtime=False,
        long_shape="command",
        long_chars=999,
        gap_ms=20.0,
    )


def _reading_rows() -> list[object]:
    row = bench_reading.ReadingRow
    return [
        row("command", 999, 262.357, 286.882, 142, "read: a command"),
        row("command", 100_000, 1.724, 1.788, 285, "refused: too long"),
        row("stop", 1000, 0.730, 0.800, 61, "stop"),
    ]


def test_the_stop_section_shows_each_condition_and_where_its_time_went() -> None:
    section = report.stop_section(_stop_figures())
    assert section.title == "10. A stop, from the line to the halt (`stop`)"
    text = "\n".join(section.lines())
    assert "one whole pour first (succeeded in 61.2 s)" in text and "U(0.3, 6) s" in text
    assert 'by "stop" alone, or 20 ms after a 999-character `command` line' in text
    assert section.table[0] == (
        "| before the stop | halts | p50 ms | p99 ms | max ms | stops with no motion to halt | "
        "a_hi's cancel (C2) ms | a_co's (C1) ms | a_ta's (C5) ms |"
    )
    assert section.table[2:] == [
        "| nothing | 20 | 10.7 | 18.6 | 18.6 | 1 | 2.3 | 5.3 | 9.9 |",
        "| a 999-character `command` line, 20 ms earlier | 20 | 24.4 | 55.4 | 55.4 | 0 | 13.2 | 17.4 | — |",
    ]


def test_the_stop_verdict_is_met_within_250_ms_with_the_halts_asked_for() -> None:
    (line,) = report.stop_verdicts(_stop_figures())
    assert line.startswith(
        "- A stop halts the commanded motion within 250 ms p99 of reaching a_hi, whatever came before it: "
        "alone: **18.6 ms** over 20 halts; 20 ms after a 999-character `command` line: **55.4 ms** over 20 "
        "halts (target ≤ 250 ms p99, 20 halts each): met."
    )
    # one slow stop in 20 sets the p99 (nearest rank): missed
    (line,) = report.stop_verdicts(_stop_figures(long=[24.4] * 19 + [251.0]))
    assert "line: **251.0 ms** over 20 halts" in line and line.endswith(": missed.")
    # fast, but fewer halts than asked (the fleet stopped pouring): missed, and said so
    (line,) = report.stop_verdicts(_stop_figures(plain=[10.7], asked=2, long=[20.0, 21.0]))
    assert "alone: **10.7 ms** over only 1 of the 2 halts asked;" in line and line.endswith(": missed.")
    (line,) = report.stop_verdicts(_stop_figures(plain=[], asked=2, long=[20.0, 21.0]))
    assert "alone: no halt;" in line and line.endswith(": missed.")
    assert report.stop_table(_stop_figures(plain=[], asked=2))[2].startswith("| nothing | 0 | — | — | — |")


def test_the_reading_section_shows_each_shape_and_length() -> None:
    section = report.reading_section(_reading_rows(), report.Counts.of(quick=True))
    assert section.title == "11. a_hi's reading time against line length (`reading`)"
    assert "5 lines per shape and length after 3 warm-up ones" in section.how[0]
    assert "within the 1,000-character bound" in section.how[0]
    assert section.table[2:] == [
        "| command | 999 | 262.357 | 286.882 | 142 | read: a command |",
        "| command | 100,000 | 1.724 | 1.788 | 285 | refused: too long |",
        "| stop | 1,000 | 0.730 | 0.800 | 61 | stop |",
    ]


def test_only_takes_the_stop_and_reading_parts_in_their_order() -> None:
    from services.cli.bench import _parts

    assert _parts("reading, stop") == ["stop", "reading"]
    assert _parts(None)[-3:] == ["gateway", "stop", "reading"]
    with pytest.raises(typer.BadParameter, match="unknown part"):
        _parts("stop,halt")


def _fixed_figures_document() -> str:
    """docs/benchmarks.md as ``roco bench`` renders it, from fixed figures of every part and
    the hand-written notes it appends."""
    counts = report.Counts()
    pair = PairFigures(
        roco_rt=Latency([346e-6] * 3),
        raw_rt=Latency([270e-6] * 3),
        raw_poll_rt=Latency([192e-6] * 3),
        poll_us=500.0,
        roco_tput=Throughput([(111_903, 50_000, 1.0, 1)]),
        roco_tput_single=Throughput([(71_001, 50_000, 1.0, 1)]),
        raw_tput=Throughput([(482_306, 50_000, 1.0, 1)]),
    )
    spade = SpadeFigures([1382e-6], 6134, 5000, 1.0, {"spade": "4.1.4"}, "", "two agents in two processes")
    jade = JadeFigures(
        [600e-6], 50_000, 50_000, 2.5, {"jade": "4.6.5"}, settings="two containers in two JVMs"
    )
    unsecured = PairFigures(
        roco_rt=Latency([300e-6] * 3),
        raw_rt=Latency([250e-6] * 3),
        raw_poll_rt=Latency([180e-6] * 3),
        poll_us=500.0,
        roco_tput=Throughput([(130_000, 50_000, 1.0, 1)]),
        roco_tput_single=Throughput([(80_001, 50_000, 1.0, 1)]),
        raw_tput=Throughput([(500_001, 50_000, 1.0, 1)]),
    )
    messaging = MessagingFigures(pair, unsecured, {}, 200, "peer")
    timing = TimingStats(
        pacing="realtime",
        cycles=54_890,
        window=54_890,
        compute_p50_us=231.0,
        compute_p99_us=406.0,
        compute_max_us=8931.0,
        lateness_p50_us=0.0,
        lateness_p99_us=2.0,
        lateness_max_us=30.0,
        overruns=59,
        overrun_share=59 / 54_890,
        max_consecutive_overruns=2,
        sim_time=54.9,
    )
    plan = PlanPhase(
        index=1,
        requested_t=1.0,
        received_t=1.109,
        c4_count=30,
        c4_bytes=9000,
        c4_queries=15,
        c4_last_t=1.1,
        mean_kbps=None,
        peak_kbps=None,
        outcome="partial",
        km_queries=15,
        planning_time_s=0.099,
    )
    task = TaskRun("real time (--realtime)", 61.1, True, "", None, 54.9, 294, timing, [plan], 512_000, 55.0)
    fleet = FleetFigures(1.53, 0.90, {"router": 34.0, "a_km": 69.0}, "")
    memory = MemoryFigures(
        {"b_ini0": (33.8, 18.8), "b_par0": (33.8, 18.8), "router": (31.2, 16.9)},
        {"fleet, camera process running": {"a_km": (69.3, 41.9)}, "fleet at rest": {"a_km": (69.3, 42.1)}},
    )
    planning = PlanningFigures([(0.081, 0.077, 15, 33), (0.062, 0.058, 15, 33)])

    def scale_row(agents: int, rate: float) -> ScaleRow:
        return ScaleRow(agents, 1.0, 40.0 * agents, pair, ConcurrentFigures(Latency([0.001]), rate, rate), 1)

    scale = [scale_row(10, 3385.0), scale_row(100, 1646.0)]
    gateway = GatewayFigures(
        LoadFigures(100, 20, 2000, 819.4, 101.0, 278.0, {200: 2000}),
        BurstFigures(500, 500, 0.72, {200: 500}),
        [WorstRow("body: 8 MiB of newlines", 406, 406, 14.6, 0.03)],
        79.8,
        117.0,
    )
    sections = [
        report.codec_section([CodecRow("200 B", 200, 412, 0.40, 1.25, 20_000)]),
        report.messaging_section(messaging, spade, jade, counts),
        report.knowledge_section(
            [QueryRow("ObjectQuery(jar)", 0.176, 0.286, 0.768, 0.933, 273)], "544 triples", counts
        ),
        report.planning_section(planning, [task]),
        report.fleet_section(fleet),
        report.memory_section(memory),
        report.task_section([task]),
        report.scale_section(scale, counts),
        report.gateway_section(gateway),
        report.stop_section(_stop_figures()),
        report.reading_section(_reading_rows(), counts),
    ]
    targets = [
        *report.verdict_lines(messaging, spade),
        *report.memory_verdicts(memory),
        *report.scale_verdicts(scale),
        *report.plan_and_fleet_verdicts(planning, fleet),
        *report.gateway_verdicts(gateway),
        *report.stop_verdicts(_stop_figures()),
    ]
    run_lines = [
        *report.machine_lines("roco bench", "0.10 / 0.20 / 0.30", "0.40 / 0.50 / 0.60", 1.8e9, 555.0),
        *condition_lines(
            ["before messaging: waited 1 s; quiet (0 % busy, 0 % stolen over the last 1 s)"], 90
        ),
    ]
    return report.document(run_lines, targets, sections, runner.NOTES.read_text())


HISTORY_HEADING = re.compile(
    r"^#+ .*\b(before|after|tried|stands|stood|changed|fixes|first cuts|again|\d{4}-\d{2}-\d{2})\b",
    re.IGNORECASE | re.MULTILINE,
)


def test_a_report_from_fixed_figures_states_the_method_and_the_present_only() -> None:
    text = _fixed_figures_document()
    # what it answers and how it was made come first, then the targets, the parts, the method
    headings = [line for line in text.splitlines() if line.startswith("## ")]
    assert headings[:2] == ["## This run", "## Targets"]
    assert [h.split(" ", 2)[1] for h in headings[2:13]] == [
        "1.",
        "2–3.",
        "4.",
        "5.",
        "6.",
        "6b.",
        "7.",
        "8.",
        "9.",
        "10.",
        "11.",
    ]
    assert headings[13:] == ["## Method and where the time goes"]
    assert text.startswith("# roco benchmarks\n\nWhat roco costs on one machine")
    assert "- Command: `roco bench` (took 555 s), at commit" in text
    assert "- Before each timed part `roco bench` waited up to 90 s for a quiet machine" in text
    # each part says how much it measured
    assert "2000 round trips each (after 50 warm-up ones), 50,000 communicates per stream" in text
    assert "- **JADE**: two containers in two JVMs; versions: jade 4.6.5. Round trip" in text
    assert (
        "| JADE 4.6.5, two containers in two JVMs (200-character content) | IMTP over TCP, one hop | 600 |"
        in text
    )
    assert "500 round trips per initiator after 50 warm-up ones, 3 time(s)" in text
    assert "in turn until each has 20 halts" in text
    assert "50 lines per shape and length after 3 warm-up ones" in text
    # targets named by what they are, each met or missed by the figures given
    targets = text.split("## Targets", 1)[1].split("\n## ", 1)[0]
    assert "**1.80×** (346 against 192 µs; target ≤ 1.3×): missed" in targets
    assert "**+15 %**); its stream 71,000 against 80,000 /s." in targets
    assert (
        "**48.6 %** of the 10-agent round trips /s while every pair runs (target ≥ 60 %): missed" in targets
    )
    assert (
        "`roco up` until every agent is alive (its start to its exit): **1.53 s** (target ≤ 3 s): met."
        in targets
    )
    assert "whatever came before it: alone: **18.6 ms** over 20 halts;" in targets
    # no work history: no issue numbers, no sessions, no sections of attempts, before/after or dates
    assert not re.search(r"\bissues?\b", text, re.IGNORECASE), re.findall(r".{40}issue.{20}", text, re.I)
    assert not re.search(r"\bsessions?\b", text, re.IGNORECASE), re.findall(r".{40}session.{20}", text, re.I)
    assert not HISTORY_HEADING.findall(text), HISTORY_HEADING.findall(text)


def test_the_hand_written_method_is_short() -> None:
    notes = runner.NOTES.read_text()
    assert notes.startswith("## Method and where the time goes\n")
    assert len(notes.split()) <= 1500


def test_the_history_check_catches_what_it_is_for() -> None:
    for heading in (
        "### Tried and left",
        "### Before and after (same machine)",
        "## Where it stands",
        "### Runs of 2026-11-23",
    ):
        assert HISTORY_HEADING.findall(heading + "\n"), heading
    assert not HISTORY_HEADING.findall("### Where the limit is\n### Adaptive polling\n")


def test_the_targets_missed_stand_beside_the_met_and_are_counted() -> None:
    lines = [
        "- roco round trip / raw Zenoh (p50): **0.73×** (target ≤ 1.3×): met.",
        "- On equal terms, raw Zenoh's ends polling the same way: **2.48×** (98 against 39 µs).",
        "- An idle synthetic agent: **35.5 MiB** VmRSS at most (b_ini0; target ≤ 35 MiB): missed.",
        "- Against SPADE: round trip (target ≥ 3.0×): met; throughput (target ≥ 10.0×): missed.",
        "- `roco up` until every agent is alive: **2.16 s** (target ≤ 3 s): met.",
    ]
    section = report.targets_section(lines)
    assert section.how == [f"{report.TARGETS_INTRO} **2 missed**, 3 met."]
    assert section.table == [
        report.MISSED,
        "",
        lines[2],
        lines[3],
        "",
        report.MET,
        "",
        lines[0],
        lines[1],  # a figure without a verdict stays with the line before it
        lines[4],
    ]
    only_met = report.targets_section([lines[0], lines[4]])
    assert report.MISSED not in only_met.table and only_met.how[0].endswith("**0 missed**, 2 met.")
