"""``roco spec``: show and check the specification, verify code and runs against it
(docs/spec.md; services/spec_check/), and write a new system or agent from it (``roco spec
new-agent`` brings the compose files up to date too: services/deploy/new_agent.py)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from services.cli.common import MARKUP, CheckOnly, SpecFile, fail, run_folder, shown
from shared.settings import Settings

if TYPE_CHECKING:
    from services.spec_check.coverage import Coverage


spec_app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    rich_markup_mode=MARKUP,
    help="The specification (services/spec/robot_companion.toml): show it, check it, verify code and runs.",
    short_help="The specification: show it, check it, verify code and runs.",
)


def _spec_path(path: Path | None) -> Path:
    """``--spec``'s file, else the shipped specification."""
    from services.spec.model import DEFAULT_SPEC

    return path if path is not None else DEFAULT_SPEC


def _readable_spec(path: Path | None, *, decomposition: bool = False) -> Path:
    """``--spec``'s file (default: the shipped one) once it loads, and with ``decomposition``
    its requirement tree and steps too; for one that does not, the one-line ``roco:`` refusal,
    exit 2."""
    from services.spec.decomposition import load_decomposition
    from services.spec.model import SpecError, load

    path = _spec_path(path)
    try:
        load(path)
        if decomposition:
            load_decomposition(path)
    except SpecError as exc:
        raise fail(str(exc), code=2) from None
    return path


def _run_spec(spec: Path | None, run_dirs: Sequence[Path]) -> Path:
    """``--spec``'s file (or ``ROCO_SPEC``'s), else the one the first of ``run_dirs`` that names
    one used (its ``launch_env.json``: services/runtime/run_folder.py ``spec_of_run``), else the
    shipped one, once it loads; else the one-line refusal, exit 2."""
    from services.runtime.run_folder import spec_of_run

    named = spec or next((used for r in run_dirs if (used := spec_of_run(r)) is not None), None)
    return _readable_spec(named)


@spec_app.command("show", short_help="The decomposition, channels, interfaces and agent graph.")
def spec_show(
    spec: SpecFile = None,
    svg: Annotated[Path | None, typer.Option(help="write the agent/channel graph as SVG here")] = None,
    dot: Annotated[Path | None, typer.Option(help="write the graph as Graphviz DOT here")] = None,
) -> None:
    """The decomposition step by step (paper Tables 1–2), the fringe after each step, and the
    agents' interfaces; the agent/channel graph as SVG or DOT."""
    from services.spec.decomposition import load_decomposition
    from services.spec.model import SpecError, load
    from services.spec.show import (
        channels_markdown,
        graph_dot,
        graph_svg,
        interfaces_markdown,
        steps_markdown,
    )

    path = _spec_path(spec)
    try:
        system, d = load(path), load_decomposition(path)
    except SpecError as exc:
        raise fail(str(exc), code=2) from None
    typer.echo(steps_markdown(d))
    typer.echo(channels_markdown(system))
    typer.echo(interfaces_markdown(system))
    if svg is not None:
        svg.write_text(graph_svg(system))
        typer.echo(f"\nroco: graph written to {svg}")
    if dot is not None:
        dot.write_text(graph_dot(system))
        typer.echo(f"roco: graph written to {dot}")


@spec_app.command("check", short_help="Check the decomposition and the agents' interfaces.")
def spec_check(spec: SpecFile = None) -> None:
    """Check the decomposition (each step splits one fringe group in two, reallocated channels
    end at groups that exist, every requirement addressed, the stop condition) and that the
    agents' interfaces match the channels. Exit 1 with one line per problem; exit 2 for a
    specification that does not load."""
    from services.spec.check import check_report

    ok, text = check_report(_readable_spec(spec, decomposition=True))
    typer.echo(text)
    if not ok:
        raise typer.Exit(1)


@spec_app.command("deadlock", short_help="Search the protocols and agents for reachable deadlocks.")
def spec_deadlock(
    spec: SpecFile = None,
    library: Annotated[
        bool,
        typer.Option(
            "--library", help="explore every built-in interaction protocol instead of a specification's"
        ),
    ] = False,
) -> None:
    """Explore every channel protocol as two role automata over bounded FIFO queues, and the
    agents' wait-for graph; report reachable deadlocks with the trace that leads there
    (paper §4 step 3). With --library, every protocol of the built-in library (FIPA SC00026
    to SC00036) instead. Exit 1 when one is found."""
    from services.spec.model import SpecError
    from services.spec_check.deadlock import deadlock_report, library_report

    if library and spec is not None:
        raise fail("--library explores the built-in protocols; give no --spec with it", code=2)
    try:
        found, text = library_report() if library else deadlock_report(_spec_path(spec))
    except SpecError as exc:
        raise fail(str(exc), code=2) from None
    typer.echo(text)
    if found:
        raise typer.Exit(1)


@spec_app.command("what-if", short_help="Weigh a placement of the agents on hosts from a run's record.")
def spec_what_if(
    run_dir: Annotated[Path, typer.Argument(metavar="RUN", help="a run folder")],
    hosts: Annotated[
        str | None,
        typer.Option(help='the agents per host, hosts split by |: "ag_ex | a_co a_pl a_km a_ta a_hi"'),
    ] = None,
    merge: Annotated[
        list[str] | None, typer.Option(help="agents in one process, joined by +: a_pl+a_km (again for more)")
    ] = None,
    rtt: Annotated[str | None, typer.Option(help="the round-trip time of each link: 20ms, 0.5s")] = None,
    recorder_with: Annotated[
        str | None,
        typer.Option(
            help="the agent whose host carries the traffic recorder, or none "
            "[default: the agent that plays the person (a_hi), else none]",
            show_default=False,
        ),
    ] = None,
    spec: SpecFile = None,
) -> None:
    """From a run's record, what a placement of the agents would put on each link between
    hosts (per channel, mean and peak kbps), the sizes against the specification's estimates,
    the round trips each conversation's critical path would cross and the reply-by deadlines an
    RTT would break; or what merged agents take off Zenoh (docs/spec.md). Exit 1 when a
    deadline breaks at --rtt; exit 2 for an option that does not read or a folder that is not
    a run folder."""
    from services.spec.model import SpecError, load
    from services.spec_check.placement import NO_RECORDER, PlacementError
    from services.spec_check.whatif_text import what_if_report

    try:
        run = run_folder(run_dir)
        path = _run_spec(spec, [run])
        beside = recorder_with or load(path).playing("person") or NO_RECORDER
        ok, text = what_if_report(
            run, hosts=hosts, merges=merge or (), rtt=rtt, recorder_with=beside, spec_path=path
        )
    except (PlacementError, SpecError) as exc:
        raise fail(str(exc), code=2) from None
    typer.echo(text)
    if not ok:
        raise typer.Exit(1)


@spec_app.command("verify", short_help="Check a run's recorded traffic against the specification.")
def spec_verify(
    run_dir: Annotated[Path, typer.Argument(metavar="RUN", help="a run folder")], spec: SpecFile = None
) -> None:
    """Check a run's recorded traffic against the specification: every communicate on a
    channel between its sender and receiver, allowed for its role and in its language, and
    every conversation following its protocol's state machine. Exit 1 unless fully
    conformant; exit 2 for a folder that is not a run folder or a specification that does not
    load."""
    from services.spec_check.conformance import verify_report

    run = run_folder(run_dir)
    ok, text = verify_report(run, _run_spec(spec, [run]))
    typer.echo(text)
    if not ok:
        raise typer.Exit(1)


@spec_app.command("coverage", short_help="Which parts of the specification runs and tests exercised.")
def spec_coverage(
    runs: Annotated[list[Path] | None, typer.Argument(metavar="RUN…", help="run folders")] = None,
    tests: Annotated[
        bool, typer.Option("--tests", help="also the test suite's traffic, tapped into ROCO_TAP_DIR or --tap")
    ] = False,
    tap: Annotated[
        Path | None, typer.Option(help="the tap folder a test run wrote (default: ROCO_TAP_DIR)")
    ] = None,
    minimum: Annotated[
        float | None,
        typer.Option("--min", min=0.0, max=1.0, help="exit 1 when the share exercised is under this (0–1)"),
    ] = None,
    svg: Annotated[
        Path | None, typer.Option(help="write the figure (agent graph, state machines) as SVG here")
    ] = None,
    brief: Annotated[bool, typer.Option("--brief", help="list only what was never taken")] = False,
    spec: SpecFile = None,
) -> None:
    """Count which parts of the specification the runs RUN… and, with `--tests`, the test
    suite exercised: every transition of each channel's interaction protocols (with
    not-understood and reply-by time-outs), every state and arc of each agent's FSM, every
    content term; list what was taken, how often, and what never was (docs/spec.md,
    "Coverage"). The tests' traffic: run them with `ROCO_TAP_DIR=FOLDER`. Exit 1 when the
    share exercised is under `--min`; exit 2 for a folder that is not there."""
    from services.spec_check.coverage_text import headline, render

    cov = _coverage(runs or [], tap, tests, spec)
    typer.echo(render(cov, detail=not brief))
    if svg is not None:
        from services.spec_check.coverage_figure import write_figure

        write_figure(cov, svg)
        typer.echo(f"roco: figure written to {svg}")
    if minimum is not None and cov.share < minimum:
        raise fail(f"{headline(cov)}: under --min {100 * minimum:.1f} %")


def _tap_folder(tap: Path | None) -> Path:
    """``tap``, else ``ROCO_TAP_DIR``; one line and exit 2 when neither is given."""
    tapped = tap or Settings.from_env(only=("tap_dir",)).tap_dir
    if tapped is None:
        raise fail(
            f"--tests needs the folder the tests tapped: give --tap or set {Settings.env_name('tap_dir')}", 2
        )
    return tapped


def _coverage(runs: list[Path], tap: Path | None, tests: bool, spec: Path | None) -> Coverage:
    """The coverage of the run folders ``runs`` and, with ``tests``, of the tap folder ``tap``
    (default ``ROCO_TAP_DIR``); one line and exit 2 for what cannot be counted."""
    from services.spec.model import SpecError
    from services.spec_check.coverage import coverage_of

    folders = [run_folder(r) for r in runs]
    tapped = _tap_folder(tap) if tests else None
    if not folders and tapped is None:
        raise fail("nothing to count: give run folders, or --tests", 2)
    try:
        return coverage_of(folders, tapped, _run_spec(spec, folders))
    except (SpecError, ValueError) as exc:
        raise fail(str(exc), 2) from None
    except FileNotFoundError as exc:
        raise fail(f"{exc.filename or exc}: no such folder", 2) from None


@spec_app.command("trace", short_help="The requirement tree with the evidence that each requirement holds.")
def spec_trace(
    run_dirs: Annotated[list[Path], typer.Argument(metavar="RUN…", help="run folders")],
    spec: SpecFile = None,
    require_shown: Annotated[
        bool, typer.Option("--require-shown", help="exit 1 also when a leaf requirement is not exercised")
    ] = False,
    tests: Annotated[
        Path | None,
        typer.Option(
            "--tests",
            help="the folder of the system's tests, read for their requirement marks "
            "[default: roco's tests/ for roco's specification, else tests/ beside the specification]",
            show_default=False,
        ),
    ] = None,
) -> None:
    """The requirement tree (paper Figure 5) with, for each leaf requirement, the steps and
    channels that serve it, the tests that name it (`@pytest.mark.requirement("R1.2")` in the
    system's tests, read without running them: --tests), its `properties` in the specification
    evaluated over each RUN's communicates in causal order (what must have happened, in order and linked by
    conversation-id and in-reply-to) and a verdict: *shown* (every property held in one run),
    *violated* (a conformance violation on a channel serving it, a failed command for a
    requirement with `task = true`, or a property whose situation happened and whose rest did
    not follow) or *not exercised*. Exit 0 when no leaf is violated; 1 when a leaf is
    violated, and with --require-shown also when one is not exercised; 2 for a specification,
    run folder or marker that cannot be read (docs/spec.md, "Requirements traced to
    evidence")."""
    from services.spec_check.trace import TraceError, tests_beside, trace_report

    runs = [run_folder(r) for r in run_dirs]
    path = _run_spec(spec, runs)
    try:
        code, text = trace_report(runs, path, require_shown=require_shown, tests=tests or tests_beside(path))
    except TraceError as exc:
        raise fail(str(exc), code=2) from None
    typer.echo(text)
    if code:
        raise typer.Exit(code)


@spec_app.command("verify-code", short_help="Compare every agent's code with its interface.")
def spec_verify_code(spec: SpecFile = None) -> None:
    """Compare every agent with its interface in the specification without starting it (the
    paper's ClassInterfaceInfo check): its protocol roles (channel, protocol, initiator or
    participant, languages), a handler for everything its peers may send, and no send outside
    its roles; list what each role sends and receives. Exit 1 with one line per problem; exit
    2 for a specification that does not load."""
    from services.spec.model import SpecError
    from services.spec_check.code_check import verify_code_report

    try:
        ok, text = verify_code_report(_spec_path(spec))
    except SpecError as exc:
        raise fail(str(exc), code=2) from None
    typer.echo(text)
    if not ok:
        raise typer.Exit(1)


@spec_app.command("init", short_help="Write a new system's folder: specification, package, agents, a test.")
def spec_init(
    name: Annotated[
        str, typer.Argument(metavar="NAME", help="the system's package name: lower-case, e.g. cell")
    ],
    folder: Annotated[Path, typer.Argument(metavar="DIR", help="a new or empty folder to write it in")],
) -> None:
    """Write a new system designed with the paper's method into DIR: NAME.toml (requirements,
    one decomposition step, two agents, a channel, the system's own content language), the
    package NAME/ (its terms, its names module, an interface agent that plays the person's role
    and a worker) and tests/test_NAME.py (docs/method.md). `roco spec check`, `verify-code`,
    `roco up --spec`, `roco send` and `roco spec verify` pass on it at once. Exit 1, nothing
    written, for a name that cannot be a package's or a folder that is not empty."""
    from services.spec.model import SpecError
    from services.spec_check.new_system import write_system

    try:
        written = write_system(name, folder)
    except SpecError as exc:
        raise fail(str(exc)) from None
    spec = folder / f"{name}.toml"
    typer.echo(f"roco: wrote {len(written)} files in {folder}; next: roco spec check --spec {spec}")


@spec_app.command("names", short_help="Write services/spec/names.py from the specification, or check it.")
def spec_names(
    check: CheckOnly = False,
    file: Annotated[
        Path | None,
        typer.Option(
            help="the names module [default: the specification's `names` module: services/spec/names.py "
            "for roco's, cell/names.py beside cell.toml for a system of package cell]",
            show_default=False,
        ),
    ] = None,
    spec: SpecFile = None,
) -> None:
    """Write the names module the specification gives: its channels, interaction protocols and
    content languages as string enums with an alias per name (`C5`, `FIPA_REQUEST`, `L_EX`),
    which the agents declare their roles with (services/spec/render_names.py). With --check,
    write nothing: exit 0 when the file is what the specification gives, 1 (one line saying
    how it differs) when not; exit 2 for a specification or file that cannot be read."""
    from services.spec.model import SpecError, load
    from services.spec.render_names import check as check_file
    from services.spec.render_names import names_file, typed_names, write

    try:
        system = load(_spec_path(spec))
        path = file or names_file(_spec_path(spec), system)
        name = shown(path)
        if check:
            problem = check_file(path, system, name)
            if problem is not None:
                raise fail(problem)
            typer.echo(f"roco: {name} is what the specification gives")
            return
        changed = write(path, system)
        typed = typed_names(system)
    except SpecError as exc:
        raise fail(str(exc), code=2) from None
    counts = (
        f"{len(typed.channels)} channels, {len(typed.protocols)} protocols, {len(typed.languages)} languages"
    )
    typer.echo(f"roco: wrote {name} ({counts})" if changed else f"roco: {name} is up to date ({counts})")


@spec_app.command("new-agent", short_help="Write a new agent's folder from the specification.")
def spec_new_agent(
    name: Annotated[str, typer.Argument(metavar="NAME", help="the agent, as [[agents]] names it")],
    spec: SpecFile = None,
    root: Annotated[
        Path | None,
        typer.Option(
            help="the folder the implementation's package path starts in [default: this checkout for "
            "roco's specification, else the specification's folder]",
            show_default=False,
        ),
    ] = None,
) -> None:
    """Write the folder of agent NAME from the specification: its protocol roles and one
    handler per performative its peers may send, each raising NotImplementedError until
    written, importing its names from the system's names module; render that module again
    (`roco spec names`), and deploy/compose.yaml with a service for it and
    deploy/compose.netfault.yaml where they exist (docs/spec.md, "Walk-through: adding an
    agent"). Exit 1, nothing written, when the file exists, the specification has no such
    agent, or a file cannot be rendered."""
    from services.deploy.compose import ComposeError
    from services.deploy.layout import LayoutError
    from services.deploy.new_agent import add_agent
    from services.spec.model import DEFAULT_SPEC, SpecError

    try:
        scaffold = add_agent(spec or DEFAULT_SPEC, name, root, lambda line: typer.echo(f"roco: {line}"))
    except (SpecError, FileExistsError, ComposeError, LayoutError) as exc:
        raise fail(str(exc)) from None
    timer = f" and what {scaffold.timer} opens" if scaffold.timer else ""
    typer.echo(f"roco: fill in {', '.join(scaffold.handlers)}{timer}; then: roco spec verify-code")
