"""README.md's "Figures" table, rendered from the documents the measuring runs wrote, and
written between its two markers (:data:`BEGIN`, :data:`END`).

Sources, each opening with its run's header (services/bench/run_header.py: command, commit,
date, CPU and cores):

- docs/benchmarks.md, written by ``roco bench`` (services/bench/report.py);
- docs/bench/loop.md, the output of ``python scripts/bench_loop.py``;
- docs/bench/pour_seeds_fleet.md, the output of ``python scripts/bench_pour_seeds.py --mode fleet``.

One function per row (:data:`ROWS`), each reading named cells of its source's tables and
returning the figure, its value, what it is compared with and how, and the run it is from.
``roco bench`` calls :func:`write` after a whole run to docs/benchmarks.md; tests/docs checks
README against the documents with :func:`differences`.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from services.bench import report, targets
from services.bench.bench_docs import Document, FiguresError, Table, number, slug

BEGIN = "<!-- figures:begin: written by `roco bench` (services/bench/readme_figures.py) -->"
END = "<!-- figures:end -->"
BENCHMARKS = "docs/benchmarks.md"
LOOP = "docs/bench/loop.md"
POUR_SEEDS = "docs/bench/pour_seeds_fleet.md"
HEADER = ["figure", "value", "compared with, how", "measured by: command, commit, machine"]


@dataclass(frozen=True)
class Row:
    """One row of README's figures: the figure, its value, what it is compared with and how,
    and where it was measured (the document, its section, the run's header)."""

    figure: str
    value: str
    compared: str
    source: Document
    section: str = ""
    part: str = ""
    """The ``roco bench`` parts (``--only``) that measured it; empty for a script's figure."""

    def measured_by(self) -> str:
        run = self.source.run
        anchor = f"#{slug(self.source.heading(self.section))}" if self.section else ""
        part = f" (`--only {self.part}`)" if self.part else ""
        return (
            f"[`{run.command}`]({self.source.path}{anchor}){part} at {run.commit}, {run.date}; {run.machine}"
        )

    def cells(self) -> list[str]:
        return [self.figure, self.value, self.compared, self.measured_by()]


def _span(cells: list[str]) -> str:
    """``"a–b"`` over the cells' numbers as written (``"a"`` when all are equal)."""
    ordered = sorted(cells, key=number)
    return ordered[0] if ordered[0] == ordered[-1] else f"{ordered[0]}–{ordered[-1]}"


# ------------------------------------------------------------------------- one function per row

MESSAGING = "2–3. Messaging"
ROCO_ROW = "roco (Agent runtime"
RAW_SLEEPING_ROW = "raw Zenoh ("
RAW_POLLING_ROW = "each end polling"
BATCHED_ROW = "roco, stream batched"
SECURE_LINK = "mutual TLS + ACL"
OPEN_LINK = "TCP, no ACL"


def _messaging_row(t: Table, link: str, label: str) -> list[str] | None:
    """The messaging table's first row on a link starting ``link`` whose system contains
    ``label`` (raw Zenoh's sleeping row: the raw row that does not poll), or None."""
    link_col = t.column("link", MESSAGING)
    for r in t.rows:
        if not r[link_col].startswith(link):
            continue
        if label == RAW_SLEEPING_ROW:
            if r[0].startswith(label) and RAW_POLLING_ROW not in r[0]:
                return r
        elif label in r[0]:
            return r
    return None


def _cell(t: Table, link: str, label: str, column: int) -> str:
    r = _messaging_row(t, link, label)
    if r is None:
        raise FiguresError(f"{MESSAGING}: no row {label!r} on the link {link!r}")
    return r[column]


def _platforms(t: Table, column: int, unit: str) -> list[str]:
    """``"NAME: VALUE UNIT"`` of JADE's and SPADE's rows when the run had them."""
    found = ((name, t.rows_starting(name)) for name in ("JADE", "SPADE"))
    return [f"{name}: {rows[0][column]}{unit}" for name, rows in found if rows]


def bench_targets(docs: dict[str, Document]) -> Row:
    """``roco bench``'s targets: how many met and missed, and each missed one with its figure
    and bound; reads the ``Targets`` section's ``Missed:`` and ``Met:`` lines (services/bench/
    report.py ``targets_section``)."""
    doc, title = docs[BENCHMARKS], report.TARGETS_TITLE
    lines = [line for line in doc.section(title).splitlines() if line.startswith("- ")]
    verdicts = [w for line in lines for w in report.VERDICT.findall(line)]
    if not verdicts:
        raise FiguresError(f"{doc.path}: no verdict '(target …): met|missed' in '{title}'")
    missed = []
    for line in lines:
        for m in re.finditer(r"\(([^()]*; )?target:? ([^()]*)\): missed", line):
            name, figure = line[2:].split(": ", 1)[0], re.search(r"\*\*([^*]+)\*\*", line)
            missed.append(f"{name}: {figure[1] if figure else '?'} (target {m[2]})")
    return Row(
        "`roco bench`'s targets",
        f"{verdicts.count('met')} met, {verdicts.count('missed')} missed",
        ("missed: " + "; ".join(missed)) if missed else "none missed",
        doc,
        title,
        "",
    )


def pour(docs: dict[str, Document]) -> Row:
    """Part 7 (`task`): ``roco run`` of the pour, start to exit, unpaced and in real time;
    reads the task table's ``pacing``, ```roco run` wall s`` and ``simulated s`` cells."""
    doc, title = docs[BENCHMARKS], "7. Task"
    t = doc.table(title, "pacing")
    wall, sim = t.column("`roco run` wall s", title), t.column("simulated s", title)
    fast = t.row("as fast as possible", title)
    value = f"{fast[wall]} s as fast as possible"
    paced = t.rows_starting("real time")
    if paced:
        value += f"; {paced[0][wall]} s in real time"
    return Row(
        "the pour, `roco run` start to exit",
        value,
        f"the {fast[sim]} s of simulated time it covers, from the run folder",
        doc,
        title,
        "task",
    )


def plan_1(docs: dict[str, Document]) -> Row:
    """Part 5 (`planning`): plan #1 of the pour, request → plan; reads the planning table's
    ``plan #1, request N`` rows (``request → plan s (wall)``, ``a_km queries``, ``leaves``)."""
    doc, title = docs[BENCHMARKS], "5. Planning"
    t = doc.table(title, "plan")
    wall, queries = t.column("request → plan s", title), t.column("a_km queries", title)
    leaves = t.column("leaves", title)
    rows = t.rows_starting("plan #1, request")
    if not rows:
        raise FiguresError(f"{doc.path}: no row 'plan #1, request …' in '{title}'")
    worst = max(number(r[wall]) for r in rows)
    paper = report.PAPER_PLAN_1_TEXT
    return Row(
        "plan #1 of the pour, request → plan",
        f"{_span([r[wall] for r in rows])} s over {len(rows)} requests, "
        f"{_span([r[leaves] for r in rows])} leaves (the pour's plan #1, checked), "
        f"{_span([r[queries] for r in rows])} a_km queries",
        f"target ≤ {report.TARGET_PLAN_1_S:g} s: {'met' if worst <= report.TARGET_PLAN_1_S else 'missed'}; "
        f"{paper[0].lower()}{paper[1:].rstrip('.')}",
        doc,
        title,
        "planning",
    )


def round_trip(docs: dict[str, Document]) -> Row:
    """Parts 2–3 (`messaging`, `spade`, `jade`): request → inform round trip, p50; reads the
    messaging table's ``round trip p50 µs`` of roco's and raw Zenoh's rows on the secured link
    (mutual TLS + ACL, as fleets run; raw Zenoh polling the same way is the headline), roco's on
    the open link, and SPADE's and JADE's rows."""
    doc = docs[BENCHMARKS]
    t = doc.table(MESSAGING, "system")
    p50 = t.column("round trip p50 µs", MESSAGING)
    roco, polling = _cell(t, SECURE_LINK, ROCO_ROW, p50), _cell(t, SECURE_LINK, RAW_POLLING_ROW, p50)
    sleeping = _cell(t, SECURE_LINK, RAW_SLEEPING_ROW, p50)
    roco_open = _cell(t, OPEN_LINK, ROCO_ROW, p50)
    others = [
        f"raw Zenoh on the same link, polling as roco does: {polling} µs "
        f"({number(roco) / number(polling):.1f} ×)",
        f"sleeping in `recv()`: {sleeping} µs",
        f"roco without TLS and access control: {roco_open} µs",
        *(f"{o} (no TLS, no access control)" for o in _platforms(t, p50, " µs")),
    ]
    return Row(
        "request → inform round trip between two agent processes, p50, mutual TLS and access control on",
        f"{roco} µs",
        "; ".join(others) + f" (each p50, {report.Counts().content_bytes} B of content, two processes)",
        doc,
        MESSAGING,
        "messaging,spade,jade",
    )


def stream(docs: dict[str, Document]) -> Row:
    """Parts 2–3: one pair streaming 200 B informs, one communicate per put; reads the messaging
    table's ``throughput /s (median)`` of roco's rows (secured and open links, one per put;
    batched), raw Zenoh's, SPADE's and JADE's."""
    doc = docs[BENCHMARKS]
    t = doc.table(MESSAGING, "system")
    rate = t.column("stream /s", MESSAGING)
    value = _cell(t, SECURE_LINK, ROCO_ROW, rate)
    others = [
        f"without TLS and access control: {_cell(t, OPEN_LINK, ROCO_ROW, rate)} /s",
        *(f"{o} (one per send, no TLS, no access control)" for o in _platforms(t, rate, " /s")),
        f"roco batched (a step's {report.STREAM_BATCH} informs in one put): "
        f"{_cell(t, SECURE_LINK, BATCHED_ROW, rate)} /s",
        f"raw Zenoh on the same link: {_cell(t, SECURE_LINK, RAW_POLLING_ROW, rate)} /s",
    ]
    return Row(
        "one pair streaming 200 B informs, one communicate per put, mutual TLS and access control on",
        f"{value} communicates/s",
        f"target ≥ {report.TARGET_TPUT:,.0f} /s: "
        f"{'met' if number(value) >= report.TARGET_TPUT else 'missed'}; " + "; ".join(others),
        doc,
        MESSAGING,
        "messaging,spade,jade",
    )


def fleet_memory(docs: dict[str, Document]) -> Row:
    """Part 6b (`memory`): the fleet's memory at rest; reads the fleet table's ``**total**``
    row, the PSS column after ``at rest: VmRSS MiB``."""
    doc, title = docs[BENCHMARKS], "6b. Memory"
    t = doc.table(title, "`roco up`'s fleet")
    pss = t.column("at rest", title) + 1
    total = t.row("**total**", title)[pss].strip("*")
    return Row(
        "the fleet's memory at rest",
        f"{total} MiB PSS in all",
        f"target ≤ {report.TARGET_FLEET_MIB:g} MiB: "
        f"{'met' if number(total) <= report.TARGET_FLEET_MIB else 'missed'}; "
        "the sum of every process's PSS (a shared page counted once)",
        doc,
        title,
        "memory",
    )


def _shares(doc: Document, cells: list[str]) -> list[str]:
    """The share in each overruns cell ``"N (x %)"``, as written; FiguresError when a cell
    lacks it."""
    shares = [re.search(r"\(([\d.]+) %\)", c) for c in cells]
    if not all(shares):
        raise FiguresError(f"{doc.path}: an overruns cell without its share '(x %)'")
    return [m.group(1) for m in shares if m]


def _world(cells: list[str]) -> str:
    """The world process's cells ``late (resets) / stalls / stale (worst age) / held`` summed
    over the runs, in words (scripts/bench_loop.py ``world``)."""
    runs = [re.findall(r"\d+", c) for c in cells if c.strip() not in ("", "-")]
    if not runs:
        return "the world process's timing not measured"
    late, resets, stalls, stale = (sum(int(r[i]) for r in runs) for i in (0, 1, 2, 3))
    return (
        f"the world process: {late} late cycles, {resets} schedule resets, {stalls} stalls, "
        f"{stale} stale commands"
    )


def loop(docs: dict[str, Document]) -> Row:
    """scripts/bench_loop.py: ag_ex's 1 kHz loop in real time with the whole fleet; reads the
    current run's ``fleet:`` rows (``compute p99 µs``, ``overruns``, and the world process's
    ``world: …`` cell)."""
    doc = docs[LOOP]
    t = doc.table("", "condition")
    p99, over = t.column("compute p99 µs", LOOP), t.column("overruns", LOOP)
    rows = t.rows_starting("fleet:")
    if not rows:
        raise FiguresError(f"{doc.path}: no 'fleet:' row in its current run")
    share_cells = _shares(doc, [r[over] for r in rows])
    world = _world([r[t.column("world", LOOP)] for r in rows])
    work_ok = all(targets.LOOP_WORK_P99.met(number(r[p99])) for r in rows)
    over_ok = all(targets.LOOP_OVERRUNS.met(float(s)) for s in share_cells)
    return Row(
        "ag_ex's 1 kHz loop in real time, whole fleet",
        f"cycle work p99 {_span([r[p99] for r in rows])} µs, {_span(share_cells)} % of cycles overrun "
        f"({len(rows)} runs); {world}",
        f"targets {targets.LOOP_WORK_P99.text()} and {targets.LOOP_OVERRUNS.text()} in every run: "
        f"{'met' if work_ok and over_ok else 'missed'}",
        doc,
    )


def pour_seeds(docs: dict[str, Document]) -> Row:
    """scripts/bench_pour_seeds.py --mode fleet: pours with the jar and bowl moved; reads its
    ``Success (…): N of M`` and ``Verdict matches truth: N of M`` lines, the table's ``spheres
    in bowl`` cells and, when it planted failures (its ``planted`` column: spheres removed from
    the jar), the plain seeds' ``success`` cells, the planted seeds' spheres and its
    ``Confusion: …`` line (the verdicts on true successes and on true failures)."""
    doc = docs[POUR_SEEDS]
    m = _line(doc, r"^Success \(([^)]*)\): (\d+) of (\d+)", "Success (…): N of M")
    v = _line(doc, r"^Verdict matches truth: (\d+) of (\d+)", "Verdict matches truth: N of M")
    t = doc.table("", "seed")
    planted_at = next((i for i, h in enumerate(t.header) if h.startswith("planted")), None)
    plain = [r for r in t.rows if planted_at is None or r[planted_at] == "—"]
    planted = [r for r in t.rows if r not in plain]
    inside, total = _spheres(t, plain)
    value = (
        f"{m[2]} of {m[3]} succeeded, {inside} of {total} spheres in the bowl; a_ta's verdict "
        f"matched the simulation's truth in {v[1]} of {v[2]}"
    )
    if planted and planted_at is not None:
        value = _with_planted(doc, t, plain, planted, planted_at)
    return Row("pours with the jar and bowl moved ±2 cm, turned ±10°", value, f"success: {m[1]}", doc)


def _line(doc: Document, pattern: str, shape: str) -> re.Match[str]:
    """The first line of ``doc`` that ``pattern`` matches; FiguresError naming ``shape``."""
    found = re.search(pattern, doc.text, re.MULTILINE)
    if found is None:
        raise FiguresError(f"{doc.path}: no line '{shape}'")
    return found


def _spheres(t: Table, rows: list[list[str]]) -> tuple[str, str]:
    """The counts of spheres in the bowl ``rows`` show (``17 or 18``), and the content's total."""
    at = t.column("spheres in bowl", POUR_SEEDS)
    inside = sorted({r[at] for r in rows}, key=number)
    return " or ".join(dict.fromkeys(c.split("/")[0] for c in inside)), inside[-1].split("/")[-1]


def _with_planted(
    doc: Document, t: Table, plain: list[list[str]], planted: list[list[str]], planted_at: int
) -> str:
    """The row's value when failures were planted: both sides of the verdict (its
    ``Confusion: …`` line)."""
    c = _line(
        doc,
        r"^Confusion: .* in (\d+) of (\d+): (\d+ of \d+) successes, (\d+ of \d+) failures",
        "Confusion: … in N of M: X of X successes, Y of Y failures",
    )
    success = t.column("success", POUR_SEEDS)
    removed = " or ".join(dict.fromkeys(r[planted_at].split()[0] for r in planted))
    inside, total = _spheres(t, plain)
    planted_inside, _ = _spheres(t, planted)
    return (
        f"{sum(r[success] == 'yes' for r in plain)} of {len(plain)} plain pours succeeded, {inside} of "
        f"{total} spheres in the bowl; {len(planted)} more with {removed} of {total} spheres removed "
        f"from the jar first, {planted_inside} in the bowl; a_ta's verdict matched the simulation's "
        f"truth in {c[1]} of {c[2]}: {c[3]} successes, {c[4]} failures"
    )


ROWS: list[Callable[[dict[str, Document]], Row]] = [
    bench_targets,
    pour,
    plan_1,
    round_trip,
    stream,
    fleet_memory,
    loop,
    pour_seeds,
]
"""README's rows, in order."""


# ------------------------------------------------------------------------- README


def documents(root: Path) -> dict[str, Document]:
    """The source documents under ``root``, each with its run header."""
    return {p: Document.read(root, p) for p in (BENCHMARKS, LOOP, POUR_SEEDS)}


def render(root: Path) -> list[str]:
    """README's figures table from the documents under ``root`` (FiguresError when one lacks
    a figure or its run header)."""
    docs = documents(root)
    rows = [f(docs).cells() for f in ROWS]
    return [
        "| " + " | ".join(HEADER) + " |",
        "|" + "---|" * len(HEADER),
        *("| " + " | ".join(r) + " |" for r in rows),
    ]


def between(readme: str) -> tuple[int, int]:
    """The character offsets of the text between the markers (ValueError when they are missing,
    repeated or out of order)."""
    if readme.count(BEGIN) != 1 or readme.count(END) != 1:
        raise ValueError(f"README.md: expected one line {BEGIN!r} and one {END!r}")
    start, end = readme.index(BEGIN) + len(BEGIN), readme.index(END)
    if end < start:
        raise ValueError(f"README.md: {END!r} comes before {BEGIN!r}")
    return start, end


def replaced(readme: str, table: list[str]) -> str:
    """``readme`` with the text between the markers replaced by ``table``."""
    start, end = between(readme)
    return readme[:start] + "\n" + "\n".join(table) + "\n" + readme[end:]


def differences(root: Path) -> list[str]:
    """How README.md's table under ``root`` differs from the one its documents give (empty:
    none): each README line that is not the rendered one, beside it."""
    readme = (root / "README.md").read_text()
    start, end = between(readme)
    have = readme[start:end].strip("\n").splitlines()
    want = render(root)
    out = [f"README.md: {h!r}\n  documents: {w!r}" for h, w in zip(have, want, strict=False) if h != w]
    if len(have) != len(want):
        out.append(f"README.md has {len(have)} lines of figures, the documents give {len(want)}")
    return out


RUN_CELL = re.compile(
    r"\) at [0-9a-f]{7,40}(?: \+ working tree)?, \d{4}-\d{2}-\d{2}[^;|]*; [^|]*\d+ cores? *$"
)
"""The last cell of a row: the run's command (a link), commit, date; its CPU and cores."""


def rows_without_run(readme: str) -> list[str]:
    """README's figure rows whose last cell does not name the run's commit and machine."""
    start, end = between(readme)
    rows = [line for line in readme[start:end].splitlines() if line.startswith("|")][2:]
    return [r for r in rows if not RUN_CELL.search(r.rstrip("|").rstrip())]


def write(root: Path) -> None:
    """Write README.md's figures table under ``root`` from its documents."""
    path = root / "README.md"
    path.write_text(replaced(path.read_text(), render(root)))
