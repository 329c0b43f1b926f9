"""One ``roco bench`` run (its command: services/cli/bench.py): the parts chosen measured in
order, each part's table printed and its section kept, then docs/benchmarks.md (or the output
asked for) written with the command, commit, machine and load, and README.md's figures table
from it after a whole run (services/bench/readme_figures.py)."""

from __future__ import annotations

import functools
import shutil
import sys
import tempfile
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from services.bench import quiet
from services.bench.setup_check import SetupRefused
from shared.settings import Settings

if TYPE_CHECKING:
    from services.bench import falls, jade, report
    from services.bench.messaging import MessagingSummary

PARTS = (
    "codec",
    "messaging",
    "spade",
    "jade",
    "knowledge",
    "planning",
    "fleet",
    "memory",
    "task",
    "scale",
    "gateway",
    "stop",
    "reading",
)
ROOT = Path(__file__).resolve().parents[2]
DEFAULT_OUT = ROOT / "docs" / "benchmarks.md"


@dataclass
class _Bench:
    """One `roco bench` run, part by part: each part's method runs it (``run``: waits for a
    quiet machine first when timed, keeps its error), prints its table and keeps its section
    (``emit``) and its verdicts (``targets``). The parts run in ``PARTS``'s order, save the
    task's table, which follows memory's (planning's section quotes the task's runs)."""

    chosen: list[str]
    quick: bool
    settle: float
    counts: report.Counts
    sections: list[report.Section] = field(default_factory=list)
    targets: list[str] = field(default_factory=list)
    errors: dict[str, str] = field(default_factory=dict)
    results: dict[str, Any] = field(default_factory=dict)
    conditions: list[str] = field(default_factory=list)
    """How busy the machine was before and during the timed parts."""
    task_runs: list[Any] = field(default_factory=list)
    jade_home: Path | None = None
    """The JADE source tree of the jade part (None: the part is skipped)."""

    def settled(self, label: str) -> None:
        if self.settle > 0:
            _say(f"roco bench: waiting up to {self.settle:.0f} s for a quiet machine ({label})…", err=True)
            self.conditions.append(f"{label}: {quiet.settle(self.settle).text()}")

    def run(self, name: str, fn: Callable[[], Any], timed: bool = False) -> Any:
        if timed:
            self.settled(f"before {name}")
        _say(f"roco bench: {name}…", err=True)
        t, cpu = time.perf_counter(), quiet.read() if timed else None
        try:
            self.results[name] = fn()
        except SetupRefused as exc:  # its set-up went wrong: no figure, one line says why
            self.errors[name] = str(exc)
            _say(f"roco: bench: {name}: {exc}", err=True)
            self.results[name] = None
        except Exception as exc:  # one part failing must not lose the others
            self.errors[name] = f"{type(exc).__name__}: {exc}"
            traceback.print_exc()
            self.results[name] = None
        during = quiet.share(cpu, quiet.read()) if timed else None
        if during is not None:
            self.conditions.append(
                f"during {name}: {during.steal * 100:.1f} % of the CPU time stolen by the hypervisor"
            )
        _say(f"roco bench: {name} done in {time.perf_counter() - t:.0f} s", err=True)
        return self.results[name]

    def emit(self, section: report.Section, verdicts: list[str] | None = None) -> None:
        _say("\n".join(section.lines()))
        self.sections.append(section)
        self.targets.extend(verdicts or [])

    def ran(self, name: str, fn: Callable[[], Any], timed: bool = False) -> Any:
        """``run``'s result when ``name`` is chosen, else None."""
        return self.run(name, fn, timed) if name in self.chosen else None

    def codec(self) -> None:
        from services.bench import parts, report

        if self.ran("codec", lambda: parts.codec(self.quick)) is not None:
            self.emit(report.codec_section(self.results["codec"]))

    def messaging(self) -> None:
        from services.bench import messaging, report, spade

        n = self.counts
        before = self.recorded_ratios() if "messaging" in self.chosen else None
        got = self.ran(
            "messaging",
            lambda: messaging.messaging(n.rounds, n.round_trips, n.communicates, n.content_bytes),
            timed=True,
        )
        if got is not None and before is not None:
            self.notice_falls(before, got.summary)
        sp = self.ran(
            "spade", lambda: spade.measure(n.spade_round_trips, n.spade_messages, n.content_bytes), timed=True
        )
        jd = self.jade_part()
        if got is not None or sp is not None or jd is not None:
            self.emit(report.messaging_section(got, sp, jd, n), report.verdict_lines(got, sp))

    @staticmethod
    def recorded_ratios() -> falls.Ratios | None:
        """The messaging ratios of the run docs/benchmarks.md holds (services/bench/falls.py),
        read before this run overwrites it; None, said in one line, when it holds none."""
        from services.bench import falls

        try:
            return falls.recorded(ROOT)
        except falls.FiguresError as exc:
            _say(f"roco bench: no recorded ratios to compare with: {exc}", err=True)
            return None

    def notice_falls(self, before: falls.Ratios, now: MessagingSummary) -> None:
        """Print this run's ratios beside the recorded ones, and a warning line per fall."""
        from services.bench import falls

        ratios = falls.Ratios.of(now)
        _say(falls.compared(before, ratios), err=True)
        for line in falls.falls(before, ratios):
            _say(line, err=True)
            self.conditions.append(line.removeprefix("roco bench: "))

    def jade_part(self) -> jade.JadeFigures | None:
        """The jade part's figures; when a prerequisite is missing, one line saying which and
        figures that say so (no quiet wait, nothing run); None when the part is not chosen."""
        from services.bench import jade

        if "jade" not in self.chosen:
            return None
        why = jade.missing(self.jade_home)
        if why:
            _say(f"roco bench: jade: skipped: {why}", err=True)
            return jade.JadeFigures(skipped=why)
        home, n = self.jade_home, self.counts
        assert home is not None  # missing() said so
        return self.run(
            "jade",
            lambda: jade.measure(home, n.jade_warmup, n.jade_round_trips, n.communicates, n.content_bytes),
            timed=True,
        )

    def knowledge(self) -> None:
        from services.bench import parts, report

        if self.ran("knowledge", lambda: parts.knowledge(self.quick)) is not None:
            rows, store = self.results["knowledge"]
            self.emit(report.knowledge_section(rows, store, self.counts))

    def task(self) -> None:
        from services.bench import parts

        if "task" not in self.chosen:
            return
        runs_dir = Path(tempfile.mkdtemp(prefix="roco-bench-runs-"))
        for realtime in (False,) if self.quick else (False, True):
            got = self.run(
                f"task{' (real time)' if realtime else ''}", functools.partial(parts.task, realtime, runs_dir)
            )
            if got is not None:
                self.task_runs.append(got)

    def planning(self) -> None:
        from services.bench import parts, report

        if "planning" in self.chosen:
            self.emit(
                report.planning_section(
                    self.run("planning", lambda: parts.planning(self.quick)), self.task_runs
                )
            )

    def fleet_and_memory(self) -> None:
        from services.bench import parts, report

        if self.ran("fleet", parts.fleet) is not None:
            self.emit(report.fleet_section(self.results["fleet"]))
        if self.ran("memory", parts.memory) is not None:
            self.emit(
                report.memory_section(self.results["memory"]), report.memory_verdicts(self.results["memory"])
            )
        if self.task_runs:
            self.emit(report.task_section(self.task_runs))

    def scale(self, scale_agents: str) -> None:
        from services.bench import messaging, report

        if "scale" not in self.chosen:
            return
        n = self.counts
        agent_counts = [int(x) for x in scale_agents.split(",") if x.strip()]
        agent_counts = agent_counts[:1] if self.quick else agent_counts

        def one(meshed: bool) -> list[Any]:
            return messaging.scale(
                agent_counts,
                n.scale_round_trips,
                n.scale_communicates,
                n.scale_all_pairs,
                n.content_bytes,
                meshed=meshed,
                all_rounds=n.scale_all_rounds,
                before=self.settled,
            )

        rows = self.run("scale", lambda: one(False) + one(True), timed=True)
        if rows is not None:
            self.emit(report.scale_section(rows, n), report.scale_verdicts(rows))

    def gateway_stop_reading(self) -> None:
        from services.bench import parts, report

        if "gateway" in self.chosen:
            from services.bench import gateway

            got = self.run("gateway", lambda: gateway.measure(self.quick), timed=True)
            if got is not None:
                self.emit(report.gateway_section(got), report.gateway_verdicts(got))
        got = self.ran("stop", lambda: parts.stop(self.counts.stops), timed=True)
        if got is not None:
            self.emit(report.stop_section(got), report.stop_verdicts(got))
        if self.ran("reading", lambda: parts.reading(self.counts.reading_repeats)) is not None:
            self.emit(report.reading_section(self.results["reading"], self.counts))

    def finish(self) -> None:
        """The verdicts on planning and the fleet, the task runs' files removed when every run
        succeeded (kept when one failed), and the failed parts' section."""
        from services.bench import report

        self.targets.extend(
            report.plan_and_fleet_verdicts(self.results.get("planning"), self.results.get("fleet"))
        )
        if self.task_runs and all(r.ok for r in self.task_runs):
            shutil.rmtree(self.task_runs[0].run_dir.parent, ignore_errors=True)
        if self.errors:
            self.emit(report.failed_section(self.errors))


def run_bench(
    chosen: list[str],
    quick: bool,
    settle: float,
    out: Path,
    scale_agents: str,
    jade_home: Path | None,
    command: str,
) -> bool:
    """Run the parts ``chosen`` (with ``quick``'s small counts, waiting up to ``settle`` s for a
    quiet machine before each timed one), print each table, write them to ``out`` with the
    ``command`` that ran them, and README.md's figures after a whole run; False when a part
    failed or README.md's figures could not be written (each said in a line)."""
    from services.bench import report

    started, t0, load_start = time.time(), time.perf_counter(), report.load()
    b = _Bench(chosen, quick, settle, report.Counts.of(quick))
    b.jade_home = jade_home or Settings.from_env(only=("jade_home",)).jade_home
    b.codec()
    b.messaging()
    b.knowledge()
    b.task()
    b.planning()
    b.fleet_and_memory()
    b.scale(scale_agents)
    b.gateway_stop_reading()
    b.finish()
    seconds = time.perf_counter() - t0
    run_lines = [
        *report.machine_lines(command, load_start, report.load(), started, seconds),
        *report.condition_lines(b.conditions, settle),
    ]
    notes = NOTES.read_text() if NOTES.exists() else ""
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(report.document(run_lines, b.targets, b.sections, notes))
    _say("\n".join(report.targets_section(b.targets).lines()))
    _say(f"roco bench: wrote {out} in {seconds:.0f} s", err=True)
    return update_readme(chosen, quick, out, b.errors) and not b.errors


def writes_readme(chosen: list[str], quick: bool, out: Path, errors: dict[str, str]) -> str | None:
    """None when this run writes README.md's figures (every part, full counts, to the default
    output, none failed); else why not."""
    if chosen != list(PARTS) or quick:
        return "a run of some parts or with --quick"
    if out.resolve() != DEFAULT_OUT.resolve():
        return f"written to {out}, not {DEFAULT_OUT.relative_to(ROOT)}"
    if errors:
        return f"part(s) {', '.join(errors)} failed"
    return None


def update_readme(chosen: list[str], quick: bool, out: Path, errors: dict[str, str]) -> bool:
    """README.md's figures from the documents a whole run leaves (services/bench/readme_figures.py),
    said in one line; False when they could not be written."""
    from services.bench import readme_figures

    why = writes_readme(chosen, quick, out, errors)
    if why is not None:
        _say(f"roco bench: README.md's figures left as they are ({why})", err=True)
        return True
    try:
        readme_figures.write(ROOT)
    except (readme_figures.FiguresError, ValueError) as exc:
        _say(f"roco: README.md's figures not written: {exc}", err=True)
        return False
    _say("roco bench: wrote README.md's figures", err=True)
    return True


def _say(line: str, err: bool = False) -> None:
    """``line`` on stdout (``err``: stderr), flushed at once: the parts' progress keeps its
    order with their tables."""
    print(line, file=sys.stderr if err else sys.stdout, flush=True)


NOTES = Path(__file__).with_name("notes.md")
"""The hand-written "Method and where the time goes" appended to the generated document."""
