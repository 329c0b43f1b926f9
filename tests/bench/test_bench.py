"""``roco bench`` (services/bench/): the quickest run of two parts writes the tables it should,
with positive figures; no timing is asserted (figures depend on the machine)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from services.bench import quiet
from services.bench.messaging import (
    BenchInform,
    BenchRequest,
    ConcurrentFigures,
    Latency,
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
from services.bench.parts import MemoryFigures
from services.bench.report import (
    condition_lines,
    memory_table,
    memory_verdicts,
    scale_table,
    scale_verdicts,
)
from services.spec.model import interface
from shared.fipa_codec.languages import encode_content

ROOT = Path(__file__).resolve().parents[2]


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
    assert "| fleet at rest | **total** | **129.0** | **349.0** |" in rows


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
    systems = [r[0] for r in messaging]
    assert systems[0].startswith("raw Zenoh (put/subscriber")
    assert systems[1].startswith("raw Zenoh, each end polling") and systems[2].startswith("roco")
    for r in messaging[:3]:
        p50, p99, count = _number(r[1]), _number(r[2]), _number(r[3])
        assert 0 < p50 <= p99 and count == 300
    assert _number(messaging[0][4]) > 0 and _number(messaging[2][4]) > 0  # throughput /s
    # the same stream with each communicate in a put of its own (no batches), nothing lost either
    assert (
        systems[3].startswith("roco, each communicate in a put of its own") and _number(messaging[3][4]) > 0
    )
    assert messaging[2][6] == messaging[3][6] == "0"
    assert "## Messaging targets" in text
    assert "On equal terms, raw Zenoh's ends polling the same way" in text


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
