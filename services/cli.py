"""Run the Robot Companion, talk to a running fleet, and read its run folders.

Examples:

    roco doctor                              what this machine offers roco
    roco run "pour the jar into the bowl"    the whole system, to the task's end
    roco scenario urgent_mid_pour            several commands, each one checked
    roco up; roco send "stop"; roco down     a fleet that keeps running
    roco view runs/<timestamp>               a run's Rerun recording

Each command's own --help gives its details. Every failure prints one line starting
with "roco:" and exits non-zero. Shell completion: roco --install-completion.
"""

from __future__ import annotations

import contextlib
import os
import queue
import signal
import sys
import threading
import time
import uuid
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Literal

import msgspec
import typer

from services.deploy.cli import CheckOnly, SpecFile, deploy_app, file_option, shown
from services.fault.cli import fault_app
from services.fleet.launcher import AGENT_ORDER, GATEWAY, Fleet, LaunchError
from services.hosts.cli import hosts_app
from services.runtime import keys
from services.runtime.human import FINAL_REPORTS, HumanInput, HumanReport
from services.runtime.reports import MissedOutcomes, ReportFilter, follow_reports, next_report
from services.runtime.run_folder import (
    RunFolderError,
    RunInfo,
    check_run_folder,
    new_run_dir,
    write_run_info,
)
from services.runtime.session import (
    SessionRefused,
    alive_agents,
    listening,
    open_client,
    open_operator,
    port_in_use,
)
from services.security.context import register
from services.spec.model import default_spec
from shared.settings import Settings

if TYPE_CHECKING:
    import zenoh

    from services.hosts.link import Shaping
    from services.live.watch import LiveWatch
    from services.recorder.flags import FlagsReply
    from services.report.model import CoverageSummary
    from services.runtime.counters import CountersReport
    from services.scenario.model import Scenario
    from services.scenario.runner import Hosting
    from services.spec.model import SystemSpec
    from services.spec_check.coverage import Coverage

MARKUP: Literal["markdown"] = "markdown"
"""Help texts are Markdown (typer's ``rich_markup_mode``): `code`, lists, indented examples."""
app = typer.Typer(no_args_is_help=True, help=__doc__, rich_markup_mode=MARKUP)
app.add_typer(fault_app, name="fault")
app.add_typer(deploy_app, name="deploy")
app.add_typer(hosts_app, name="hosts")
app.add_typer(__import__("services.bench.cli", fromlist=["bench_app"]).bench_app, name="bench")
FLEET_FILE = ".fleet.json"
AclOption = Annotated[
    bool | None,
    typer.Option(
        "--acl/--no-acl",
        help="authenticate every process and enforce the access control generated from the "
        "specification (docs/security.md); --no-acl for experiments [default: on, unless ROCO_ACL=0]",
        show_default=False,
    ),
]
TlsOption = Annotated[
    bool | None,
    typer.Option(
        "--tls/--no-tls",
        help="with access control, mutual TLS and direct links between agents; --no-tls: passwords "
        "over TCP, every communicate through the router [default: on, unless ROCO_TLS=0]",
        show_default=False,
    ),
]


CredentialsOption = Annotated[
    Path | None,
    typer.Option(
        "--credentials",
        help="the deployment's credentials folder (`roco deploy certs`) for a router with access "
        "control; the tool authenticates as `operator` (ROCO_IDENTITY) [default: ROCO_SECURITY, "
        "else the fleet of 'roco up']",
        show_default=False,
    ),
]
RunsDirMade = Annotated[
    Path,
    typer.Option("--runs-dir", help="where this run's folder is made (named by the date and time it starts)"),
]
RouterOption = Annotated[
    str | None,
    typer.Option(
        help="the router to reach, e.g. tcp/HOST:7447 [default: the fleet of 'roco up', else ROCO_ROUTER]",
        show_default=False,
    ),
]
FleetRunsDir = Annotated[
    Path,
    typer.Option(
        "--runs-dir", help="where 'roco up' keeps its fleet state: the fleet's router, unless --router"
    ),
]
RecordOption = Annotated[
    bool,
    typer.Option("--record/--no-record", help="record robot, scene and traffic in RUN/recording.rrd (Rerun)"),
]
ViewOption = Annotated[
    bool, typer.Option("--view/--no-view", help="also show the recording live in a Rerun viewer")
]
GatewayOption = Annotated[
    int | None,
    typer.Option(
        "--gateway",
        min=1,
        max=65535,
        metavar="PORT",
        help="also run the ACL gateway (`roco gateway --port PORT`, docs/gateway.md) as a process of "
        "the fleet: agents of other FIPA platforms post to 127.0.0.1:PORT [default: no gateway]",
        show_default=False,
    ),
]
LiveOption = Annotated[
    bool | None,
    typer.Option(
        "--live/--no-live",
        help="a live view under the event lines: plan, step, agents, time, loop overruns "
        "[default: on a terminal, unless --quiet]",
        show_default=False,
    ),
]


def _live_watch(title: str, live: bool | None, quiet: bool) -> LiveWatch | None:
    """The live view (services/live/) when asked, or by default when stdout is a terminal and
    not ``quiet``; None: plain lines."""
    from rich.console import Console

    from services.live.watch import LiveWatch
    from services.spec.notices import notice_protocols

    console = Console(highlight=False)
    if live is False or (live is None and (quiet or not console.is_terminal)):
        return None
    return LiveWatch(title, AGENT_ORDER, console=console, notice_protocols=notice_protocols(default_spec()))


def _security(acl: bool | None, tls: bool | None) -> None:
    """Set the switches the launcher reads (``ROCO_ACL``, ``ROCO_TLS``;
    services/security/context.py) for this process and the processes it starts; None leaves
    the environment's choice."""
    if tls is not None:
        os.environ[Settings.env_name("tls")] = "1" if tls else "0"
    if acl is not None:
        os.environ[Settings.env_name("acl")] = "1" if acl else "0"
    if tls:
        os.environ[Settings.env_name("acl")] = "1"


class FleetState(msgspec.Struct):
    """What ``roco up`` leaves for ``roco down``/``send``/``status``: endpoint and PIDs."""

    endpoint: str
    run_dir: str
    pids: dict[str, int]


def fail(message: str, code: int = 1) -> typer.Exit:
    typer.echo(f"roco: {message}", err=True)
    return typer.Exit(code)


INTERRUPTED = 130
"""The exit status of a command ended by Ctrl-C (SIGINT), SIGTERM or SIGHUP: 128 + SIGINT."""


def _new_run_dir(runs_dir: Path) -> Path:
    """A new run folder under ``runs_dir`` (services/runtime/run_folder.py ``new_run_dir``);
    one line and exit 2 when none can be made there."""
    try:
        return new_run_dir(runs_dir)
    except RunFolderError as exc:
        raise fail(str(exc), code=2) from None


def _run_folder(path: Path) -> Path:
    """``path`` when it is a run folder (``run.json`` or ``traffic.jsonl`` in it); one line and
    exit 2 otherwise, before anything is read or written."""
    try:
        check_run_folder(path)
    except RunFolderError as exc:
        raise fail(str(exc), code=2) from None
    return path


def _port_free(port: int, option: str, host: str = "127.0.0.1") -> None:
    """One line and exit 2 when something listens on ``host:port`` already, naming ``option``
    to choose another."""
    if listening(f"tcp/{host}:{port}"):
        raise fail(port_in_use(host, port, option), code=2)


def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


def _stop_on_signals() -> None:
    """SIGTERM and SIGHUP (the terminal closed) end a run as Ctrl-C does: the fleet it started
    is stopped, none of its processes is left behind."""
    signal.signal(signal.SIGTERM, _interrupt)
    signal.signal(signal.SIGHUP, _interrupt)


def _clock(t0: float) -> str:
    return f"[{time.time() - t0:7.1f} s]"


def _send_command(session: object, text: str, request_id: str) -> None:
    session.put(keys.HUMAN_IN, msgspec.json.encode(HumanInput(text=text, request_id=request_id)))  # type: ignore[attr-defined]


@app.command(short_help="Run the whole system on one command, to the end of the task.")
def run(
    command: Annotated[str, typer.Argument(help="what the person says, e.g. 'pour the jar into the bowl'")],
    runs_dir: RunsDirMade = Path("runs"),
    realtime: Annotated[bool, typer.Option(help="pace the simulation to wall time")] = False,
    timeout: Annotated[float, typer.Option(help="give up after this many seconds")] = 900.0,
    quiet: Annotated[bool, typer.Option(help="print only the outcome")] = False,
    seed: Annotated[int, typer.Option(min=0, help="jitter of the jar content's start positions")] = 0,
    pose_seed: Annotated[
        int | None, typer.Option(min=0, help="randomise the jar and bowl poses (±2 cm, ±10°) with this seed")
    ] = None,
    record: RecordOption = True,
    view: ViewOption = False,
    acl: AclOption = None,
    tls: TlsOption = None,
    live: LiveOption = None,
    gateway: GatewayOption = None,
) -> None:
    """Start router, recorder and one process per agent (and the ACL gateway with
    `--gateway`); give a_hi the command; wait for the outcome; stop everything; write the run
    folder's report. Exit 0 only on success with no requirement flagged violated during the
    run (docs/spec.md, the live monitor), 130 when interrupted (Ctrl-C: the fleet is
    stopped, the report written)."""
    from services.scenario.model import Scenario, Step

    _security(acl, tls)
    scenario = Scenario(
        name="", steps=(Step(say=command),), seed=seed, pose_seed=pose_seed, timeout_s=timeout
    )
    watch = _live_watch("roco run", live, quiet)
    _run_scenario(
        scenario,
        runs_dir,
        realtime=realtime,
        quiet=quiet,
        record=record,
        view=view,
        watch=watch,
        gateway=gateway,
    )


@app.command(short_help="Run a scripted session and check every command's outcome.")
def scenario(
    name: Annotated[
        str | None, typer.Argument(help="a scenario file, or the name of one in the library")
    ] = None,
    runs_dir: RunsDirMade = Path("runs"),
    realtime: Annotated[bool, typer.Option(help="pace the simulation to wall time")] = False,
    quiet: Annotated[bool, typer.Option(help="print only the outcome")] = False,
    list_: Annotated[bool, typer.Option("--list", help="list the library's scenarios")] = False,
    record: RecordOption = True,
    view: ViewOption = False,
    acl: AclOption = None,
    tls: TlsOption = None,
    live: LiveOption = None,
    gateway: GatewayOption = None,
) -> None:
    """Run a scenario (several commands, interruptions, disturbances, restarts; see
    services/scenario/model.py) headless, check every command's outcome against what the
    scenario expects, and write the report. Exit 0 only when everything went as expected and
    no requirement was flagged violated during the run (docs/spec.md, the live monitor), 130
    when interrupted."""
    from services.scenario.model import ScenarioError, library, load_scenario

    _security(acl, tls)
    if list_:
        for stem, sc in library().items():
            typer.echo(f"{stem:24s} {sc.name}: {sc.description}")
        return
    if name is None:
        raise fail("name a scenario file or a library scenario (roco scenario --list)", code=2)
    try:
        sc = load_scenario(name)
    except ScenarioError as exc:
        raise fail(str(exc), code=2) from None
    watch = _live_watch(f"roco scenario {sc.name}", live, quiet)
    _run_scenario(
        sc, runs_dir, realtime=realtime, quiet=quiet, record=record, view=view, watch=watch, gateway=gateway
    )


_CHAOS_DEFAULT = ",".join(default_spec().agent_names)


def _check_chaos_hosting(hosts: bool, acl: bool | None, tls: bool | None, link: tuple[object, ...]) -> None:
    """Exit 2 when `roco chaos --hosts` cannot make two hosts here or is asked to run without
    access control or TLS, or when the ``link`` options (--delay-ms, --jitter-ms, --loss-pct,
    --cut) come without --hosts; without --hosts, the security options are checked."""
    if hosts:
        from services.hosts.netns import unavailable

        why = unavailable()
        if why:
            raise fail(f"--hosts cannot make two hosts here: {why}", code=2)
        if acl is False or tls is False:
            raise fail("--hosts always runs with access control and mutual TLS", code=2)
        return
    if any(v is not None for v in link):
        raise fail("--delay-ms, --jitter-ms, --loss-pct and --cut shape and cut the link of --hosts", code=2)
    _security(acl, tls)


def _chaos_scenario(
    seed: int,
    gap_s: tuple[float, float],
    services: str,
    count: int | None,
    kinds: str,
    command: str,
    hosts: bool,
    cut_s: tuple[float, float],
) -> Scenario:
    """The chaos scenario of `roco chaos`'s options (services/scenario/chaos.py); exit 2 when
    they are wrong, or when ag_ex is faulted while the kitchen lives in it."""
    from services.scenario.chaos import HOSTS_DEFAULT, chaos_scenario

    try:
        sc = chaos_scenario(
            seed,
            gap_s=gap_s,
            services=HOSTS_DEFAULT if hosts and services == _CHAOS_DEFAULT else _listed(services),
            count=count,
            kinds=_listed(kinds),
            command=command,
            hosts=hosts,
            cut_s=cut_s,
        )
    except ValueError as exc:
        raise fail(str(exc), code=2) from None
    if any(s.fault is not None and s.fault.service == "ag_ex" for s in sc.steps) and not _world_apart():
        world = Settings.env_name("world")
        raise fail(f"{world}=loop keeps the kitchen in ag_ex, which a fault starts anew: unset it", code=2)
    return sc


def _listed(text: str) -> tuple[str, ...]:
    """The non-empty items of a comma-separated option, stripped."""
    return tuple(s.strip() for s in text.split(",") if s.strip())


def _chaos_shaping(delay_ms: float | None, jitter_ms: float | None, loss_pct: float | None) -> Shaping:
    """The link of `roco chaos --hosts` (20 ± 5 ms, 1 % loss unless told); exit 2 when wrong."""
    from services.hosts.link import Shaping

    try:
        return Shaping(
            20.0 if delay_ms is None else delay_ms,
            5.0 if jitter_ms is None else jitter_ms,
            1.0 if loss_pct is None else loss_pct,
        )
    except ValueError as exc:
        raise fail(str(exc), code=2) from None


def _two_hosts(run_dir: Path, shaping: Shaping, env: dict[str, str]) -> Hosting:
    """The fleet on two hosts joined by a ``shaping`` link, for the scenario runner."""
    from services.hosts.fleet import TwoHosts, TwoHostsHosting

    return TwoHostsHosting(TwoHosts(run_dir, shaping, env=env))


_CHAOS_ALWAYS = ("fault", "back after", "up again after")
"""What `roco chaos --quiet` still says: the lines of the faults and of the services back."""


def _chaos_echo(say: Callable[[str], None], quiet: bool) -> Callable[[str], None]:
    """The runner's progress lines to ``say`` (with ``quiet``: only the faults')."""
    return lambda line: say(line) if not quiet or any(w in line for w in _CHAOS_ALWAYS) else None


@app.command(short_help="Fault services at random during a task; check that nothing is lost.")
def chaos(
    seed: Annotated[
        int, typer.Option(min=0, help="draws the order, kinds, times and lengths of the faults")
    ] = 0,
    count: Annotated[
        int | None, typer.Option(min=1, help="this many random faults instead of each service once")
    ] = None,
    services: Annotated[
        str,
        typer.Option(
            help="comma-separated services to fault (agents, recorder, router; with --hosts "
            "router_brain, router_robot, link instead of router), or all",
            show_default="every agent; with --hosts also both routers and the link",
        ),
    ] = _CHAOS_DEFAULT,
    kinds: Annotated[str, typer.Option(help="comma-separated fault kinds: kill, pause, restart")] = (
        "kill,pause,restart"
    ),
    command: Annotated[str, typer.Option(help="what the person asks for")] = "pour the jar into the bowl",
    gap: Annotated[str, typer.Option(help="MIN,MAX seconds between faults (uniform)")] = "3,8",
    runs_dir: RunsDirMade = Path("runs"),
    realtime: Annotated[bool, typer.Option(help="pace the simulation to wall time")] = False,
    quiet: Annotated[bool, typer.Option(help="print only the faults and the verdict")] = False,
    record: RecordOption = False,
    acl: AclOption = None,
    tls: TlsOption = None,
    live: LiveOption = None,
    hosts: Annotated[
        bool,
        typer.Option(
            "--hosts",
            help="on two hosts of this machine (brain, robot; root): fault both hosts' services, "
            "their routers (router_brain, router_robot) and the link between them (link: cut 2-6 s)",
        ),
    ] = False,
    delay_ms: Annotated[
        float | None,
        typer.Option(min=0, help="with --hosts: one-way delay of the link (ms)", show_default="20"),
    ] = None,
    jitter_ms: Annotated[
        float | None, typer.Option(min=0, help="with --hosts: ± this much (ms)", show_default="5")
    ] = None,
    loss_pct: Annotated[
        float | None,
        typer.Option(min=0, max=99, help="with --hosts: packets lost each way (%)", show_default="1"),
    ] = None,
    cut: Annotated[
        str | None,
        typer.Option(
            help="with --hosts: MIN,MAX seconds a cut of the link lasts (uniform; over the routers' "
            "30 s lease the mesh is closed and made again)",
            show_default="2,6",
        ),
    ] = None,
) -> None:
    """Kill, pause or restart services at random times while the robot carries out a command
    (each service once by default), then say whether the task was done, no command was lost,
    nothing was executed twice, no object was dropped, the traffic record is intact and no
    agent raised (RUN/chaos.md). Exit 0 only if all six hold. With `--hosts` the fleet runs on the two
    hosts of `roco hosts` (link 20 ± 5 ms, 1 % loss unless told; mutual TLS between the
    routers, access control on) and the link is cut as well. On compose use `roco fault`
    (docs/recovery.md)."""
    from services.scenario.chaos import verdict, write_chaos_report
    from services.scenario.runner import ScenarioRunner

    _check_chaos_hosting(hosts, acl, tls, (delay_ms, jitter_ms, loss_pct, cut))
    low, high = _span("--gap", gap)
    cut_s = _span("--cut", cut) if cut is not None else (2.0, 6.0)
    sc = _chaos_scenario(seed, (low, high), services, count, kinds, command, hosts, cut_s)
    shaping = _chaos_shaping(delay_ms, jitter_ms, loss_pct) if hosts else None
    scene = _scene_env(realtime, 0, None)
    run_dir = _new_run_dir(runs_dir)
    env = scene | _viewer_env(record, False)
    info = RunInfo(started=time.time(), realtime=realtime, seed=0, scenario=sc.name)
    _stop_on_signals()
    hosting = _two_hosts(run_dir, shaping, env) if shaping is not None else None
    watch = _live_watch(f"roco chaos --seed {seed}", live, quiet)
    with watch if watch is not None else contextlib.nullcontext():
        runner = ScenarioRunner(
            sc,
            run_dir,
            env=env,
            echo=_chaos_echo(watch.line if watch is not None else typer.echo, quiet),
            info=info,
            on_session=watch.attach if watch is not None else None,
            hosting=hosting,
        )
        outcome = runner.run()
    _finish_report(run_dir, info, interrupted=outcome.interrupted)
    v = verdict(run_dir, outcome)
    path = write_chaos_report(run_dir, sc, outcome, v)
    typer.echo(path.read_text())
    if not v.ok:
        raise fail(f"the chaos run did not keep everything (see {path})")


def _span(option: str, value: str) -> tuple[float, float]:
    """``MIN,MAX`` seconds of ``option``; a clear error (exit 2) unless 0 <= MIN <= MAX <= 3600."""
    try:
        low, high = (float(x) for x in value.split(","))
    except ValueError:
        raise fail(f"{option} takes MIN,MAX seconds, not {value!r}", code=2) from None
    if not 0 <= low <= high <= 3600:
        raise fail(f"{option} needs 0 <= MIN <= MAX <= 3600, not {value!r}", code=2)
    return low, high


def _viewer_env(record: bool, view: bool) -> dict[str, str]:
    """Rerun recording on or off for every process; with ``view``, a viewer started now that
    the fleet streams to as well (its URL printed)."""
    rerun = Settings.env_name("rerun")
    if not (record or view):
        return {rerun: "0"}
    env = {rerun: "1"}
    if view:
        from services.viewer.view import start_viewer

        try:
            viewer = start_viewer(None)
        except Exception as exc:  # the run goes on without the live view
            typer.echo(f"roco: no live viewer ({exc}); the run is still recorded", err=True)
            return env
        env[Settings.env_name("rerun_connect")] = viewer.grpc_url
        typer.echo(f"roco: Rerun viewer {viewer.web_url or 'opened'} (pid {viewer.pid})")
    return env


def _run_echo(say: Callable[[str], None], quiet: bool) -> Callable[[str], None]:
    """The runner's progress lines to ``say`` (with ``quiet``: only a_hi's to the person)."""
    return lambda line: say(line) if not quiet or "a_hi → person" in line else None


def _run_scenario(
    sc: object,
    runs_dir: Path,
    *,
    realtime: bool,
    quiet: bool,
    record: bool = True,
    view: bool = False,
    watch: LiveWatch | None = None,
    gateway: int | None = None,
) -> None:
    from services.monitor import progress_line
    from services.scenario.model import Scenario
    from services.scenario.runner import ScenarioRunner

    assert isinstance(sc, Scenario)
    if gateway is not None:
        _port_free(gateway, "--gateway")
    scene = _scene_env(realtime, sc.seed, sc.pose_seed)
    run_dir = _new_run_dir(runs_dir)
    env = scene | _viewer_env(record, view)
    info = RunInfo(
        started=time.time(),
        realtime=realtime,
        seed=sc.seed,
        pose_seed=sc.pose_seed,
        scenario=sc.name,
    )
    _stop_on_signals()
    with watch if watch is not None else contextlib.nullcontext():
        runner = ScenarioRunner(
            sc,
            run_dir,
            env=env,
            echo=_run_echo(watch.line if watch is not None else typer.echo, quiet),
            traffic_lines=None if quiet else progress_line,
            info=info,
            on_session=watch.attach if watch is not None else None,
            gateway=gateway,
        )
        outcome = runner.run()
    _finish_report(run_dir, info, interrupted=outcome.interrupted)
    if sc.name:
        typer.echo(outcome.summary())
    _exit_on_failure(sc.name, outcome.ok, info.detail, run_dir, outcome.raised_line())


def _exit_on_failure(name: str, ok: bool, detail: str, run_dir: Path, raised: str = "") -> None:
    """Exit 1 with one line when the run failed (scenario ``name``, or ``roco run`` when
    empty), a requirement was flagged violated during it (:func:`_violated`) or an agent raised
    (``raised``: services/runtime/raised.py ``raised_text``, "" when none did)."""
    violated = _violated(run_dir)
    also = "; ".join(x for x in (violated, raised and f"agents raised: {raised}") if x)
    if not ok:
        what = "the task failed" if not name else f"scenario “{name}” did not go as expected"
        raise fail(f"{what}: {detail}{also and '; ' + also} (run folder {run_dir})")
    if also:
        raise fail(f"{also} (run folder {run_dir})")


def _violated(run_dir: Path) -> str:
    """``requirement R3.3 violated during the run: …`` for the requirements the live monitor
    flagged in ``run_dir`` (services/recorder/flags.py), the first one's flag in words; empty
    when none was flagged."""
    from services.recorder.flags import read_flags

    try:
        flags = read_flags(run_dir)
    except OSError as exc:
        return f"the live requirement flags cannot be read: {exc}"
    if not flags:
        return ""
    ids = sorted({f.requirement for f in flags})
    which = f"requirement{'s' if len(ids) > 1 else ''} {', '.join(ids)}"
    return f"{which} violated during the run: {flags[0].line()}"


def _flag_lines(reply: FlagsReply | None) -> list[str]:
    """`roco status`'s lines of the requirements the live monitor flagged violated, from the
    traffic recorder's ``reply`` (services/recorder/flags.py ``ask_flags``): one per flag,
    ``violated  R3.3 “…”: <event> at <time> (<what it came before>)``, then how many more the
    recorder holds when it sent only the first; one line saying the recorder did not answer
    when ``reply`` is None; none without a flag."""
    if reply is None:
        return [f"{'flags':9s} (the recorder did not answer: live requirement flags unknown)"]
    lines = [f"{'violated':9s} {f.line()}" for f in reply.flags]
    if reply.total > len(reply.flags):
        lines.append(
            f"{'violated':9s} (and {reply.total - len(reply.flags)} more in the run folder's flags.jsonl)"
        )
    return lines


def _check_perception() -> None:
    """Refuse a bad ``ROCO_PERCEPTION``, or ``camera`` where the head camera cannot render, with
    one line (exit 2); say once when the robot perceives with the ground truth because this
    machine has no off-screen GL library (velma/executor/capture.py ``perception_mode``)."""
    from velma.executor.capture import camera_unavailable, perception_mode

    try:
        perception_mode()
    except ValueError as exc:
        raise fail(str(exc), code=2) from None
    why = camera_unavailable()
    asked = Settings.from_env(only=("perception",)).perception
    if why is not None and asked == "camera":
        raise fail(f"{Settings.env_name('perception')}=camera, but {why}", code=2)
    if why is not None and asked is None:
        typer.echo(f"roco: the robot perceives with the physics' ground truth: {why}", err=True)


def _scene_env(realtime: bool, seed: int, pose_seed: int | None) -> dict[str, str]:
    """The environment that tells ag_ex its pacing and scene (services/agents/executor/agent.py).
    Checks the perception first (``_check_perception``)."""
    _check_perception()
    env = {Settings.env_name("realtime"): "1" if realtime else "0", Settings.env_name("seed"): str(seed)}
    if pose_seed is not None:
        env[Settings.env_name("pose_seed")] = str(pose_seed)
    return env


def _finish_report(run_dir: Path, info: RunInfo, *, interrupted: bool = False) -> None:
    """Write the run's report and say in one line how the run went; when ``interrupted``
    (Ctrl-C, SIGTERM, SIGHUP: the runner stopped the fleet), say only that, and exit 130."""
    from services.report import build_report, write_report
    from services.spec_check.trace import report_rows

    try:
        path = write_report(run_dir, coverage=_coverage_summary(run_dir), tracer=report_rows)
        report = build_report(run_dir)
    except Exception as exc:  # the run's outcome stands even if its report cannot be made
        if interrupted:
            raise fail(f"interrupted; the fleet is stopped; run folder {run_dir}", INTERRUPTED) from None
        typer.echo(f"roco: report not written: {exc}", err=True)
        return
    if interrupted:
        raise fail(f"interrupted; the fleet is stopped; report {path}", INTERRUPTED)
    c = report.content
    poured = any("pour" in text for text in info.commands)
    share = f"{c.inside} of {c.total} spheres in the {c.container}" if c.observed else "content not observed"
    share = share if poured else f"{len(info.commands)} command(s)"
    typer.echo(
        f"roco: {'succeeded' if info.succeeded else 'failed'} in {info.ended - info.started:.1f} s wall; "  # type: ignore[operator]
        f"{_raised_clause(info)}{report.sizes.count} communicates; {share}; report {path}"
    )


def _raised_clause(info: RunInfo) -> str:
    """``2 handler errors in a_ta: see logs/a_ta.log; `` (what the agents raised during the run,
    services/runtime/raised.py, and a separator), or "" when none did."""
    from services.runtime.raised import raised_text

    text = raised_text(info.raised, info.crashed)
    return f"{text}; " if text else ""


@app.command(short_help="Start a fleet that keeps running: router, recorder, agents.")
def up(
    port: Annotated[int, typer.Option(min=1, max=65535, help="router TCP port on 127.0.0.1")] = 7447,
    runs_dir: Annotated[
        Path,
        typer.Option(
            "--runs-dir",
            help="where the fleet's run folder is made and its state kept for 'roco down', 'send', 'status'",
        ),
    ] = Path("runs"),
    realtime: Annotated[bool, typer.Option(help="pace the simulation to wall time")] = True,
    seed: Annotated[int, typer.Option(min=0, help="jitter of the jar content's start positions")] = 0,
    pose_seed: Annotated[
        int | None, typer.Option(min=0, help="randomise the jar and bowl poses (±2 cm, ±10°) with this seed")
    ] = None,
    record: Annotated[
        bool, typer.Option(help="record robot, scene and traffic in the run folder's recording.rrd (Rerun)")
    ] = False,
    acl: AclOption = None,
    tls: TlsOption = None,
    gateway: GatewayOption = None,
) -> None:
    """Start router, recorder and all agents (and the ACL gateway with `--gateway`) in the
    background; they keep running until `roco down`, which writes the run's report. A port in
    use, or a runs folder that cannot be written, is refused before anything starts; a fleet
    that does not come up is stopped (its report written)."""
    _security(acl, tls)
    state_file = runs_dir / FLEET_FILE
    if state_file.exists():
        raise fail(f"a fleet is already up ({state_file}); run 'roco down' first")
    _port_free(port, "--port")
    if gateway is not None:
        _port_free(gateway, "--gateway")
    scene = _scene_env(realtime, seed, pose_seed)
    run_dir = _new_run_dir(runs_dir)
    env = scene | _viewer_env(record, False)
    info = RunInfo(started=time.time(), realtime=realtime, seed=seed, pose_seed=pose_seed)
    _stop_on_signals()
    fleet = Fleet(run_dir, f"tcp/127.0.0.1:{port}", env=env)
    info.router = endpoint = fleet.endpoint  # tls/… when the router listens on TLS
    write_run_info(run_dir, info)
    session: zenoh.Session | None = None
    try:
        fleet.start_router()
        session = open_client(endpoint)
        fleet.start_recorder()
        fleet.wait_alive(session, ["recorder"], timeout=60)
        fleet.start_agents()
        waited = fleet.wait_alive(session, AGENT_ORDER, timeout=120)
        if gateway is not None:
            fleet.start_gateway(gateway)
            fleet.wait_alive(session, [GATEWAY], timeout=60)
    except (LaunchError, KeyboardInterrupt) as exc:
        if session is not None:
            session.close()
        fleet.stop()
        why = "interrupted" if isinstance(exc, KeyboardInterrupt) else str(exc)
        info.processes = fleet.pids()
        write_run_info(run_dir, info)
        _report_fleet_end(run_dir, failure=why)
        code = INTERRUPTED if isinstance(exc, KeyboardInterrupt) else 1
        raise fail(f"{why}; nothing of the fleet is left running; run folder {run_dir}", code) from None
    session.close()
    info.processes = fleet.pids()
    write_run_info(run_dir, info)
    state_file.write_bytes(msgspec.json.encode(FleetState(endpoint, str(run_dir), fleet.pids())))
    served = f"; gateway http://127.0.0.1:{gateway}/acc" if gateway is not None else ""
    typer.echo(f"roco: fleet up on {endpoint} in {waited:.1f} s{served}; run folder {run_dir}")


def _report_fleet_end(run_dir: Path, failure: str = "") -> str:
    """Record the commands a fleet of `roco up` was given and their outcomes in its run.json,
    write its report (services/report/ending.py) and return the words that say so."""
    from services.report.ending import end
    from services.spec_check.coverage_figure import report_summary
    from services.spec_check.trace import report_rows

    return end(
        run_dir, ended=time.time(), failure=failure, tracer=report_rows, coverage=report_summary
    ).line()


def _fleet_state(runs_dir: Path) -> FleetState | None:
    path = runs_dir / FLEET_FILE
    if not path.exists():
        return None
    try:
        return msgspec.json.decode(path.read_bytes(), type=FleetState)
    except (msgspec.DecodeError, msgspec.ValidationError, OSError) as exc:
        why = (str(exc).splitlines() or [type(exc).__name__])[0]
        raise fail(f"{path}: not a fleet state file: {why}", code=2) from None


@app.command(short_help="Stop the fleet that roco up started and write its report.")
def down(
    runs_dir: Annotated[
        Path, typer.Option("--runs-dir", help="where 'roco up' keeps the state of the fleet to stop")
    ] = Path("runs"),
    compose: Annotated[
        bool, typer.Option("--compose", help="stop the compose fleet (docs/deploy.md) and write its report")
    ] = False,
    project: Annotated[
        str | None,
        typer.Option(help="compose: the project [default: $ROCO_COMPOSE_PROJECT, else the one running]"),
    ] = None,
    compose_file: Annotated[
        Path | None, typer.Option(help="compose: the compose file [default: the running fleet's]")
    ] = None,
    volumes: Annotated[
        bool, typer.Option("--volumes", "-v", help="compose: delete the named volumes too (down -v)")
    ] = False,
    router: Annotated[
        str, typer.Option(help="compose: the router, for the agents' counters")
    ] = "tls/127.0.0.1:7447",
    credentials: Annotated[
        Path | None,
        typer.Option(
            help="compose: the operator's credentials [default: deploy/certs beside the compose file]"
        ),
    ] = None,
) -> None:
    """Stop the fleet `roco up` started (only the processes it started, by PID), naming each
    as it stops: the agents (their counters kept first: what they raised is said and in the
    report), the recorder once it confirmed the traffic record complete, the router. Then
    record in the run's run.json the commands the fleet was given and their outcomes (from its
    C2 traffic) and write its report. A fleet of `roco hosts up` is
    stopped as `roco hosts down` does.

    With --compose, the compose fleet: its agents' counters kept (when the router answers
    with the operator's credentials), `docker compose down` (or `docker-compose`), then
    run.json and the report of its run folder on the host, as above (writing there needs the
    right to: the containers make its files as root)."""
    from services.hosts.cli import HOSTS_FILE
    from services.hosts.cli import down as hosts_down
    from services.recorder.sync import sync_fleet, sync_words

    if compose:
        _compose_down(project, compose_file, volumes, router, credentials)
        return
    if (runs_dir / HOSTS_FILE).exists():
        hosts_down(runs_dir)
        return
    state = _fleet_state(runs_dir)
    if state is None:
        raise fail(f"no fleet is up (no {runs_dir / FLEET_FILE})")
    raised = _save_fleet_counters(state)
    typer.echo("roco: stopping", nl=False)
    _stop_pids({n: p for n, p in state.pids.items() if n not in ("recorder", "router")})
    # everything the agents sent before they stopped is in the traffic record before it closes
    if "recorder" in state.pids:
        synced = sync_fleet(state.endpoint, Path(state.run_dir) / "security")
        typer.echo(f"; recorder: {sync_words(synced)}", nl=False)
        _stop_pids({"recorder": state.pids["recorder"]}, named=False)
    if "router" in state.pids:
        typer.echo("; router", nl=False)
        _stop_pids({"router": state.pids["router"]}, named=False)
    typer.echo("")
    (runs_dir / FLEET_FILE).unlink()
    typer.echo(f"roco: fleet stopped {_report_fleet_end(Path(state.run_dir))}")
    if raised:
        typer.echo(f"roco: agents raised: {raised}")


def _compose_target(project: str | None, file: Path | None) -> tuple[str, Path]:
    """The compose fleet `roco down --compose` stops: ``project`` (else ``ROCO_COMPOSE_PROJECT``,
    else the one running) and its compose ``file`` (else the running fleet's, else the
    project's deploy/compose.yaml); exit 2 when no fleet, or several, run and none is named."""
    from services.deploy import engine
    from services.deploy.compose import COMPOSE_FILE

    project = project or Settings.from_env(only=("compose_project",)).compose_project
    if project is not None:
        return project, file or COMPOSE_FILE
    fleets = engine.running_fleets(engine.run_command)
    if len(fleets) != 1:
        running = ", ".join(f.project for f in fleets)
        which = f"compose fleets {running} run" if fleets else "no compose fleet runs"
        raise fail(f"{which}: say which with --project NAME", code=2)
    return fleets[0].project, file or fleets[0].file() or COMPOSE_FILE


def _compose_down(
    project: str | None, file: Path | None, volumes: bool, router: str, credentials: Path | None
) -> None:
    """`roco down --compose`: find the fleet (services/deploy/engine.py), keep its agents'
    counters, stop it, then conclude its run folder and write the report (:func:`_report_fleet_end`);
    one line and exit 1 (2 for a choice to make) when any step cannot be done."""
    from services.deploy import engine

    project, file = _compose_target(project, file)
    try:
        base = engine.base_command(file, project, engine.run_command)
        name = engine.run_name(base, engine.run_command)
        runs = engine.runs_folder(base, engine.run_command)
        run_dir = runs / name if runs is not None and name is not None else None
        kept = _save_compose_counters(router, credentials or file.parent / "certs", run_dir)
        engine.down(base, volumes, engine.run_command)
    except engine.ComposeFailed as exc:
        raise fail(str(exc)) from None
    typer.echo(f"roco: compose project {project} stopped{kept}")
    if run_dir is None:
        raise fail(f"no report: the run of compose project {project} is not known (was it running?)")
    ended = _report_fleet_end(run_dir)
    typer.echo(f"roco: run {run_dir} {ended}")
    if "report not written" in ended:
        raise typer.Exit(1)


def _save_compose_counters(router: str, credentials: Path, run_dir: Path | None) -> str:
    """Keep a compose fleet's agents' counters in its run folder (the report's "Agents raised");
    the words that say whether they were kept."""
    from services.runtime.counters import ask_counters, save_counters

    if run_dir is None:
        return ""
    try:
        session = open_operator(router, credentials=credentials if credentials.is_dir() else None)
    except SessionRefused as exc:
        return f" (agents' counters not kept: {exc})"
    try:
        counters = ask_counters(session, AGENT_ORDER, timeout=5.0)
    finally:
        session.close()
    try:
        save_counters(run_dir, counters)
    except OSError as exc:
        return f" (agents' counters not kept: {exc.strerror or exc})"
    return f" (counters of {', '.join(sorted(counters)) or 'no agent'} kept)"


def _save_fleet_counters(state: FleetState) -> str:
    """Before `roco down` stops a fleet: its agents' counters into the run folder's
    counters.json (the report's "Agents raised" reads them) and what they raised, in words
    (services/runtime/raised.py; "" when nothing). Nothing is saved when no router answers."""
    from services.runtime.counters import ask_counters, save_counters
    from services.runtime.raised import raised_by_agent, raised_text

    try:
        session = open_operator(_fleet_endpoint(state))
    except SessionRefused:
        return ""
    try:
        counters = ask_counters(session, [n for n in state.pids if n in AGENT_ORDER], timeout=5.0)
    finally:
        session.close()
    save_counters(Path(state.run_dir), counters)
    return raised_text(raised_by_agent({a: r.counters for a, r in counters.items()}), {})


def _running(pid: int) -> bool:
    """Whether process ``pid`` still runs (a zombie, ended but not yet reaped, does not)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except (OSError, IndexError):
        return True


def _stop_pids(pids: dict[str, int], grace_s: float = 10.0, *, named: bool = True) -> None:
    """SIGTERM every process of ``pids`` (service name → PID, as a fleet's state file names
    them) at once; echo each name (``named``) as its process ends, on the current line; SIGKILL
    what is left after ``grace_s`` ("NAME (killed)"). A process already gone is fine."""
    for pid in pids.values():
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, signal.SIGTERM)
    left = dict(pids)
    deadline = time.monotonic() + grace_s
    while left:
        for name in [n for n, pid in left.items() if not _running(pid)]:
            del left[name]
            if named:
                typer.echo(f" {name}", nl=False)
        if left and time.monotonic() > deadline:
            for name, pid in left.items():
                with contextlib.suppress(ProcessLookupError):
                    os.kill(pid, signal.SIGKILL)
                typer.echo(f" {name} (killed)", nl=False)
            return
        time.sleep(0.05)


def _open_operator_session(
    endpoint: str, credentials: Path | None = None, runs_dir: Path | None = None
) -> zenoh.Session:
    """The operator's session with the router at ``endpoint`` (its credentials from
    ``credentials``, ``ROCO_SECURITY`` or the fleet of ``roco up``); one line and exit 1 when
    it cannot be opened (services/runtime/session.py ``open_operator``). ``runs_dir``: where
    the endpoint was found (``roco up``'s state), named when that fleet is gone."""
    try:
        return open_operator(endpoint, credentials=credentials)
    except SessionRefused as exc:
        state = _fleet_state(runs_dir) if runs_dir is not None else None
        gone = state is not None and state.endpoint == endpoint and not listening(endpoint)
        if runs_dir is not None and gone:
            where = runs_dir / FLEET_FILE
            raise fail(
                f"no router answers at {endpoint}: the fleet {where} names is gone; "
                "'roco down' clears its state, then 'roco up' starts one"
            ) from None
        raise fail(str(exc)) from None


def _endpoint(router: str | None, runs_dir: Path) -> str:
    if router:
        return router
    state = _fleet_state(runs_dir)
    if state is None:
        return ",".join(Settings.from_env(only=("router",)).router)
    return _fleet_endpoint(state)


def _fleet_endpoint(state: FleetState) -> str:
    """The router endpoint of the fleet `roco up` left ``state`` of, its credentials registered
    for it when the fleet runs with access control (its run folder's ``security``)."""
    security = Path(state.run_dir) / "security"
    if security.is_dir():  # the fleet of `roco up --runs-dir …` runs with access control
        register(state.endpoint, security)
    return state.endpoint


def _show_notice(report: HumanReport) -> None:
    """What an agent told the person (a_hi's ``notice`` report), one line naming who said it."""
    typer.echo(report.notice_line)


@app.command(short_help="Give a running fleet a command and wait for its outcome.")
def send(
    command: Annotated[str, typer.Argument(help="what the person says")],
    router: RouterOption = None,
    runs_dir: FleetRunsDir = Path("runs"),
    timeout: Annotated[float, typer.Option(help="seconds to wait for the outcome")] = 900.0,
    priority: Annotated[int, typer.Option(help="larger is more urgent")] = 0,
    person: Annotated[
        str, typer.Option(help="who speaks: a_hi keeps a conversation per person ('it', questions back)")
    ] = "",
    credentials: CredentialsOption = None,
) -> None:
    """Give a running fleet a command and wait for a_hi's final report; what agents tell the
    person meanwhile (a_hi's notices) is shown with who said it. Reports a_hi gave
    while this session was cut off from it (the router restarted) come when it is back, each
    shown once; after 10 s without one, a_hi is asked for the outcome, which it keeps across
    its restarts (services/runtime/reports.py)."""
    endpoint = _endpoint(router, runs_dir)
    session = _open_operator_session(endpoint, credentials, None if router else runs_dir)
    reports: queue.SimpleQueue[HumanReport] = queue.SimpleQueue()
    follow_reports(session, reports.put)  # also what a_hi said while the router was away
    shown = ReportFilter()
    if "a_hi" not in alive_agents(session):
        session.close()
        raise fail(f"a_hi is not alive at {endpoint}")
    request_id = uuid.uuid4().hex[:8]
    said = HumanInput(text=command, request_id=request_id, priority=priority, person=person)
    session.put(keys.HUMAN_IN, msgspec.json.encode(said))
    deadline = time.monotonic() + timeout
    missed = MissedOutcomes(session)
    try:
        while (report := next_report(reports, request_id, shown, missed, deadline, _show_notice)) is not None:
            typer.echo(f"{report.kind.value}: {report.text}")
            if report.kind in FINAL_REPORTS:
                if not report.done_as_asked:
                    raise typer.Exit(1)
                return
        raise fail(f"no outcome within {timeout:.0f} s")
    finally:
        session.close()


@app.command(short_help="Move or tip over an object of the simulated kitchen.")
def disturb(
    obj: Annotated[str, typer.Argument(metavar="OBJECT", help="a free body of the kitchen: jar, bowl, cup")],
    dx: Annotated[float, typer.Option(help="metres along world x")] = 0.0,
    dy: Annotated[float, typer.Option(help="metres along world y")] = 0.0,
    dz: Annotated[float, typer.Option(help="metres along world z")] = 0.0,
    tilt: Annotated[float, typer.Option(help="radians about world x: tips the object over")] = 0.0,
    router: RouterOption = None,
    runs_dir: FleetRunsDir = Path("runs"),
    credentials: CredentialsOption = None,
) -> None:
    """Move or knock over an object of the simulated kitchen, as a person would (a disturbance
    of the world, not a robot command): ag_ex moves the body and its content and stops them."""
    import json

    from velma.executor.ground_truth import CONTAINERS

    if obj not in CONTAINERS:
        raise fail(f"cannot move {obj!r}: the kitchen's movable objects are {', '.join(CONTAINERS)}", code=2)
    endpoint = _endpoint(router, runs_dir)
    session = _open_operator_session(endpoint, credentials, None if router else runs_dir)
    try:
        if "ag_ex" not in alive_agents(session):
            raise fail(f"ag_ex is not alive at {endpoint}")
        session.put(keys.SIM_DISTURB, json.dumps({"object": obj, "delta": [dx, dy, dz], "tilt": tilt}))
    finally:
        session.close()
    turn = f", tilted {tilt:+.2f} rad" if tilt else ""
    typer.echo(f"roco: asked ag_ex to move the {obj} by ({dx:+.3f}, {dy:+.3f}, {dz:+.3f}) m{turn}")


def _web_viewer(web: bool | None, web_port: int | None) -> bool | None:
    """Whether `roco view` opens the web viewer (None: by display): --web-port implies --web,
    and exits 2 with --native."""
    if web_port is None:
        return web
    if web is False:
        raise fail("--web-port is the web viewer's port: not with --native", code=2)
    return True


def _check_recording(run_dir: Path | None) -> None:
    """Exit 1 when ``run_dir`` (a run folder or .rrd) does not exist or is not a run folder."""
    if run_dir is not None and not run_dir.exists():
        raise fail(f"{run_dir}: no such run folder or recording")
    if run_dir is not None and run_dir.is_dir():
        _run_folder(run_dir)


@app.command(short_help="Open a Rerun viewer on a run's recording or on a live fleet.")
def view(
    run_dir: Annotated[
        Path | None,
        typer.Argument(metavar="[RUN]", help="a run folder or .rrd (none: wait for a live fleet)"),
    ] = None,
    web: Annotated[
        bool | None,
        typer.Option(
            "--web/--native", help="web viewer on localhost or the native one (default: by display)"
        ),
    ] = None,
    web_port: Annotated[
        int | None,
        typer.Option(
            min=1,
            max=65535,
            help="the web viewer's port on 127.0.0.1 (implies --web) [default: a free one]",
            show_default=False,
        ),
    ] = None,
    grpc_port: Annotated[
        int | None,
        typer.Option(
            min=1,
            max=65535,
            help="the port logging SDKs (a live fleet) connect to [default: a free one]",
            show_default=False,
        ),
    ] = None,
) -> None:
    """Open a Rerun viewer on a past run's recording, or an empty one a live fleet streams to:
    the native viewer where a display exists, otherwise the web viewer served on localhost
    (its URL printed). A port asked for that is in use is refused before anything starts."""
    from services.viewer.view import PortInUse, start_viewer

    web = _web_viewer(web, web_port)
    _check_recording(run_dir)
    try:
        viewer = start_viewer(run_dir, web=web, web_port=web_port, grpc_port=grpc_port)
    except PortInUse as exc:
        option = "--web-port" if exc.port == web_port else "--grpc-port"
        raise fail(port_in_use("127.0.0.1", exc.port, option), code=2) from None
    except Exception as exc:
        raise fail(f"cannot start the viewer: {exc}") from None
    where = viewer.web_url or f"native viewer, SDKs connect to {viewer.grpc_url}"
    typer.echo(f"roco: Rerun viewer {where} (pid {viewer.pid}; stop it with: kill -- -{viewer.pid})")


@app.command(short_help="Print live communicates as they cross Zenoh (FIPA SC00070).")
def sniff(
    router: RouterOption = None,
    runs_dir: FleetRunsDir = Path("runs"),
    agent: Annotated[list[str] | None, typer.Option(help="only communicates from or to this agent")] = None,
    channel: Annotated[list[str] | None, typer.Option(help="only this channel (C1..C8)")] = None,
    performative: Annotated[list[str] | None, typer.Option(help="only this performative")] = None,
    conversation: Annotated[str | None, typer.Option(help="only this conversation-id")] = None,
    raw: Annotated[bool, typer.Option(help="print :content exactly as on the wire (SC00070)")] = False,
    credentials: CredentialsOption = None,
) -> None:
    """Print live communicates as they cross Zenoh, in FIPA SC00070 string form (like JADE's
    Sniffer), until interrupted. Content is shown as its decoded term unless --raw."""
    from services.sniff import parse_filters
    from services.sniff import sniff as run_sniff

    try:
        f = parse_filters(
            agents=agent, channels=channel, performatives=performative, conversation=conversation
        )
    except ValueError as exc:
        raise fail(str(exc), code=2) from None
    endpoint = _endpoint(router, runs_dir)
    stop = threading.Event()
    _stop_on_signals()
    session = _open_operator_session(endpoint, credentials, None if router else runs_dir)
    try:
        count = run_sniff(
            session,
            agents=f.agents,
            channels=f.channels,
            performatives=f.performatives,
            conversation=f.conversation,
            out=typer.echo,
            stop=stop,
            content=not raw,
        )
    except KeyboardInterrupt:
        stop.set()
        return
    finally:
        session.close()
    typer.echo(f"roco: {count} communicates")


@app.command(short_help="Bridge the fleet to other FIPA platforms (HTTP, SC00084).")
def gateway(
    router: RouterOption = None,
    runs_dir: FleetRunsDir = Path("runs"),
    host: Annotated[str, typer.Option(help="interface the HTTP transport listens on")] = "127.0.0.1",
    port: Annotated[int, typer.Option(min=1, max=65535, help="port of the HTTP transport")] = 7778,
    address: Annotated[
        str | None,
        typer.Option(help="the URL other platforms post to (default http://HOST:PORT/acc)"),
    ] = None,
    spec: Annotated[Path | None, typer.Option("--spec", help="a specification file")] = None,
    platform: Annotated[
        list[str] | None,
        typer.Option(
            help="PLATFORM=URL[,URL…]: answer every agent …@PLATFORM only at these addresses "
            "(repeatable; default: a name is bound to the peer that first used it)"
        ),
    ] = None,
) -> None:
    """Serve the FIPA HTTP message transport (FIPA SC00084, SC00085 XML envelope, SC00070
    string form) for agents of other FIPA platforms (JADE…): what they send to a roco agent
    the specification lets them address (its external role, x_fipa: a_hi on C8) is put on
    the fleet's Zenoh under their own names, and the answers are posted back to them; anything
    else is refused (FIPA refuse or not-understood) and counted. Runs until Ctrl-C
    (docs/gateway.md)."""
    from services.gateway.cli import GatewayConfig
    from services.gateway.cli import main as run_gateway
    from services.spec.model import DEFAULT_SPEC

    config = GatewayConfig(
        _endpoint(router, runs_dir), host, port, address, spec or DEFAULT_SPEC, tuple(platform or ())
    )
    code = run_gateway(config)
    if code:
        raise typer.Exit(code)


def _counters_text(name: str, alive: set[str], reports: dict[str, CountersReport]) -> str:
    """The tail of `roco status`'s line of ``name``: its counters (the gateway's: what came
    in, was refused, went out), or that an alive agent did not send them in time."""
    from services.runtime.counters import summary

    if name == "gateway" and name in reports:
        from services.gateway.bridge import summary as gateway_summary

        return f"  {gateway_summary(reports[name].counters)}"
    if name in reports:
        return f"  {summary(reports[name].counters)}"
    if name in alive and name != "recorder":  # (the gateway answers as agents do)
        return "  (no counters within the timeout: busy)"
    return ""


@app.command(short_help="Which agents are alive, with their counters of input.")
def status(
    router: RouterOption = None,
    runs_dir: FleetRunsDir = Path("runs"),
    counters_timeout: Annotated[
        float, typer.Option(min=0.0, help="seconds to wait for the agents' counters")
    ] = 2.0,
    credentials: CredentialsOption = None,
) -> None:
    """List the agents that hold a liveliness token, each alive agent with its counters of
    received and rejected input (by reason; docs/security.md) and the handler and behaviour
    errors it counted (when any), and what each router with
    access control refused, named (identity, message, key, when); each router is named by its
    host (brain, robot: `roco hosts`) or its endpoint; then one line per requirement property
    the live monitor found violated, as the traffic recorder answers over Zenoh (requirement,
    property, the communicate that violated it, when; docs/spec.md), or one line saying the
    recorder did not answer. Exit 1 if any agent is missing."""
    from services.recorder.flags import ask_flags
    from services.runtime.counters import ask_counters
    from services.runtime.refusals import RefusalReport, collect_reports
    from services.runtime.refusals import summary as refusal_summary

    endpoint = _endpoint(router, runs_dir)
    session = _open_operator_session(endpoint, credentials, None if router else runs_dir)
    refusals: list[RefusalReport] = []
    try:
        alive = alive_agents(session)
        with collect_reports(session, refusals):
            reports = ask_counters(session, alive & {*AGENT_ORDER, "gateway"}, timeout=counters_timeout)
        flags = ask_flags(session, timeout=counters_timeout)
        mine = {str(z) for z in session.info.routers_zid()}  # the router this session reached
    finally:
        session.close()
    names = _routers_named(runs_dir, endpoint, mine)
    for name in (*AGENT_ORDER, "recorder", *(["gateway"] if "gateway" in alive else [])):
        typer.echo(
            f"{name:9s} {'alive' if name in alive else 'absent'}{_counters_text(name, alive, reports)}"
        )
    for r in sorted(refusals, key=lambda r: names.get(r.router, r.router)):
        name = names.get(r.router, f"{r.router[:8]} (Zenoh id)")
        typer.echo(f"{'router':9s} {name}  {refusal_summary(r)}")
    for line in _flag_lines(flags):
        typer.echo(line)
    if not set(AGENT_ORDER) <= alive:
        raise typer.Exit(1)


ROUTER_LOG_LIMIT = 16 * 2**20
"""Bytes of a router's log read for the lines that name it (its start lines come first)."""


def _routers_named(runs_dir: Path, endpoint: str, mine: set[str]) -> dict[str, str]:
    """Zenoh id → a name of every router of the fleet in ``runs_dir`` (:func:`_router_names`),
    and of the routers ``mine`` this session reached (``at <endpoint>``) otherwise unnamed."""
    state = _fleet_state(runs_dir)
    names = _router_names(Path(state.run_dir) if state is not None else None)
    names.update({z: f"at {endpoint}" for z in mine if z not in names})
    return names


def _router_names(run_dir: Path | None) -> dict[str, str]:
    """Zenoh id → a name an operator knows, for every router the run folder's logs say started
    (``logs/router*.stderr``; services/runtime/router.py prints ``roco router ZID listening on
    ENDPOINTS`` at each start): ``brain`` and ``robot`` for the routers of `roco hosts`
    (router_brain, router_robot), else ``at`` its endpoints. Empty without a run folder."""
    names: dict[str, str] = {}
    if run_dir is None:
        return names
    for log in sorted((run_dir / "logs").glob("router*.stderr")):
        process = log.name.removesuffix(".stderr")
        try:
            with log.open("rb") as f:
                text = f.read(ROUTER_LOG_LIMIT).decode("utf-8", "replace")
        except OSError:
            continue
        for line in text.splitlines():
            if not line.startswith("roco router ") or " listening on " not in line:
                continue
            zid, _, rest = line.removeprefix("roco router ").partition(" listening on ")
            host = process.removeprefix("router_") if process.startswith("router_") else ""
            names[zid.strip()] = host or f"at {rest.split(';')[0].strip()}"
    return names


# ---- roco replay: one agent of a recorded run again (services/replay) ----------------------


@app.command(short_help="Replay one agent of a recorded run and compare what it sends.")
def replay(
    run_dir: Annotated[Path, typer.Argument(metavar="RUN", help="a run folder")],
    agent: Annotated[
        str | None,
        typer.Option("--agent", help="the agent to replay, as the specification names it (default: each)"),
    ] = None,
    most: Annotated[int, typer.Option(min=1, help="differences printed at most")] = 50,
    log: Annotated[bool, typer.Option("--log", help="print the replayed agent's log on stderr")] = False,
    spec: SpecFile = None,
) -> None:
    """Feed a fresh instance of AGENT, in this process, the communicates it received in the run,
    in causal order (an answer after what it answers, an answer to the agent after the agent has
    sent what it answers) and at their recorded times, with every other agent a stub of the
    record, and compare what it sends with what it sent there: equal up to conversation-ids,
    reply-withs, times and fields read from a clock. One line per difference (the recorded
    communicate, the field, recorded and replayed). Without --agent, each agent of the
    specification in turn, one line each (an agent that cannot be replayed says why; one with a
    communicate of its own missing from the record says so). Exit 0 when equal, 1 with
    differences or a communicate missing, 2 when no replay can be made."""
    import logging

    from services.replay.driver import ReplayError, render
    from services.replay.driver import replay as replay_agent
    from services.spec.model import SpecError, load

    if log:
        logging.basicConfig(
            level=logging.INFO, stream=sys.stderr, format="%(name)s %(levelname)s %(message)s"
        )
    try:
        system = load(spec) if spec is not None else None
        if agent is None:
            _replay_each(_run_folder(run_dir), system)
            return
        result = replay_agent(_run_folder(run_dir), agent, system)
    except (ReplayError, SpecError) as exc:
        raise fail(str(exc), code=2) from None
    typer.echo(render(result, most))
    if not result.equal:
        raise typer.Exit(1)


def _replay_each(run_dir: Path, spec: SystemSpec | None) -> None:
    """``roco replay RUN``: each agent of ``spec`` replayed, one line each; exit 1 when one
    differs, 2 when none could be replayed."""
    from services.replay.driver import ReplayError, one_line
    from services.replay.driver import replay as replay_agent

    made = equal = 0
    for a in (spec or default_spec()).agents:
        try:
            result = replay_agent(run_dir, a.name, spec)
        except ReplayError as exc:
            typer.echo(f"{a.name}: not replayed: {exc}")
            continue
        made, equal = made + 1, equal + result.equal
        typer.echo(one_line(result))
    if not made:
        raise fail(f"no agent of {run_dir} could be replayed", code=2)
    if equal < made:
        raise typer.Exit(1)


spec_app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    rich_markup_mode=MARKUP,
    help="The specification (services/spec/robot_companion.toml): show it, check it, verify code and runs.",
    short_help="The specification: show it, check it, verify code and runs.",
)
app.add_typer(spec_app, name="spec")


def _spec_path(path: Path | None) -> Path:
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
    to SC00036 and coordinate) instead. Exit 1 when one is found."""
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
        str, typer.Option(help="the agent whose host carries the traffic recorder, or none")
    ] = "a_hi",
    spec: SpecFile = None,
) -> None:
    """From a run's record, what a placement of the agents would put on each link between
    hosts (per channel, mean and peak kbps), the sizes against the specification's estimates,
    the round trips each conversation's critical path would cross and the reply-by deadlines an
    RTT would break; or what merged agents take off Zenoh (docs/spec.md). Exit 1 when a
    deadline breaks at --rtt; exit 2 for an option that does not read or a folder that is not
    a run folder."""
    from services.spec.model import SpecError
    from services.spec_check.placement import PlacementError
    from services.spec_check.whatif_text import what_if_report

    try:
        ok, text = what_if_report(
            _run_folder(run_dir), hosts=hosts, merges=merge or (), rtt=rtt, recorder_with=recorder_with,
            spec_path=spec,
        )  # fmt: skip
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

    ok, text = verify_report(_run_folder(run_dir), spec and _readable_spec(spec))
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

    folders = [_run_folder(r) for r in runs]
    tapped = _tap_folder(tap) if tests else None
    if not folders and tapped is None:
        raise fail("nothing to count: give run folders, or --tests", 2)
    try:
        return coverage_of(folders, tapped, spec)
    except (SpecError, ValueError) as exc:
        raise fail(str(exc), 2) from None
    except FileNotFoundError as exc:
        raise fail(f"{exc.filename or exc}: no such folder", 2) from None


def _coverage_summary(run_dir: Path) -> CoverageSummary | None:
    """The run's specification coverage for its report (services/spec_check/coverage_figure.py);
    None, with one line saying why, when it cannot be counted: the report is written all the same."""
    from services.spec_check.coverage_figure import report_summary

    try:
        return report_summary(run_dir)
    except Exception as exc:  # the report stands without it
        typer.echo(f"roco: specification coverage not counted: {exc}", err=True)
        return None


@spec_app.command("trace", short_help="The requirement tree with the evidence that each requirement holds.")
def spec_trace(
    run_dirs: Annotated[list[Path], typer.Argument(metavar="RUN…", help="run folders")],
    spec: SpecFile = None,
    require_shown: Annotated[
        bool, typer.Option("--require-shown", help="exit 1 also when a leaf requirement is not exercised")
    ] = False,
) -> None:
    """The requirement tree (paper Figure 5) with, for each leaf requirement, the steps and
    channels that serve it, the tests that name it (`@pytest.mark.requirement("R1.2")` in
    tests/, read without running them), its `properties` in the specification evaluated over
    each RUN's communicates in causal order (what must have happened, in order and linked by
    conversation-id and in-reply-to) and a verdict: *shown* (every property held in one run),
    *violated* (a conformance violation on a channel serving it, a failed command for a
    requirement with `task = true`, or a property whose situation happened and whose rest did
    not follow) or *not exercised*. Exit 0 when no leaf is violated; 1 when a leaf is
    violated, and with --require-shown also when one is not exercised; 2 for a specification,
    run folder or marker that cannot be read (docs/spec.md, "Requirements traced to
    evidence")."""
    from services.spec_check.trace import TraceError, trace_report

    try:
        code, text = trace_report(
            [_run_folder(r) for r in run_dirs], _spec_path(spec), require_shown=require_shown
        )
    except TraceError as exc:
        raise fail(str(exc), code=2) from None
    typer.echo(text)
    if code:
        raise typer.Exit(code)


@spec_app.command("new-agent", short_help="Write a new agent's folder from the specification.")
def spec_new_agent(
    name: Annotated[str, typer.Argument(metavar="NAME", help="the agent, as [[agents]] names it")],
    spec: SpecFile = None,
    root: Annotated[
        Path | None,
        typer.Option(help="the folder the implementation's package path starts in (default: the project)"),
    ] = None,
) -> None:
    """Write the folder of agent NAME from the specification: its protocol roles and one
    handler per performative its peers may send, each raising NotImplementedError until
    written; render services/spec/names.py again with the names of its channels (`roco spec
    names`), deploy/compose.yaml with a service for it and deploy/compose.netfault.yaml
    (docs/spec.md, "Walk-through: adding an agent"). Exit 1 when the file exists or the
    specification has no such agent."""
    from services.deploy import netfault
    from services.deploy.compose import ComposeError, bring_up_to_date
    from services.spec import render_names
    from services.spec.model import SpecError, load
    from services.spec_check.new_agent import PROJECT, write_agent

    try:
        system = load(_spec_path(spec))
        scaffold = write_agent(system, name, root or PROJECT)
        typer.echo(f"roco: wrote {scaffold.module}")
        typer.echo(f"roco: {render_names.bring_up_to_date(root or PROJECT, system)}")
        typer.echo(f"roco: {bring_up_to_date(root or PROJECT, system)}")
        typer.echo(f"roco: {netfault.bring_up_to_date(root or PROJECT, system)}")
    except (SpecError, FileExistsError, ComposeError) as exc:
        raise fail(str(exc)) from None
    timer = f" and what {scaffold.timer} opens" if scaffold.timer else ""
    typer.echo(f"roco: fill in {', '.join(scaffold.handlers)}{timer}; then: roco spec verify-code")


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


@spec_app.command("names", short_help="Write services/spec/names.py from the specification, or check it.")
def spec_names(
    check: CheckOnly = False,
    file: Annotated[Path | None, file_option("names module", "services/spec/names.py")] = None,
    spec: SpecFile = None,
) -> None:
    """Write the names module the specification gives: its channels, interaction protocols and
    content languages as string enums with an alias per name (`C5`, `FIPA_REQUEST`, `L_EX`),
    which the agents declare their roles with (services/spec/render_names.py). With --check,
    write nothing: exit 0 when the file is what the specification gives, 1 (one line saying
    how it differs) when not; exit 2 for a specification or file that cannot be read."""
    from services.spec.model import SpecError, load
    from services.spec.render_names import NAMES_FILE, typed_names, write
    from services.spec.render_names import check as check_file

    path = file or NAMES_FILE
    name = shown(path)
    try:
        system = load(_spec_path(spec))
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


def _world_apart() -> bool:
    """The kitchen is a world process of its own (velma/world/mode.py); a bad ROCO_WORLD is
    refused with one line."""
    from velma.world.mode import world_in_process

    try:
        return world_in_process()
    except ValueError as exc:
        raise fail(str(exc), code=2) from None


@app.command(short_help="Check what this machine offers roco, and how to get what is missing.")
def doctor(
    runs_dir: Annotated[Path, typer.Option(help="where 'roco up' keeps its fleet state")] = Path("runs"),
    compose: Annotated[
        bool, typer.Option("--compose", help="only what the compose fleet needs (docs/deploy.md)")
    ] = False,
) -> None:
    """Check, item by item, what roco can use on this machine: Python and the libraries,
    the compiled control law, a free loopback port, EGL or OSMesa for the head camera,
    SCHED_FIFO and CPU pinning for `--realtime`, the compose fleet's prerequisites (below),
    Chromium for the viewer's screenshot, and the credentials of the
    fleet `roco up` left under `runs/`. Then every `ROCO_*` setting (docs/settings.md): its
    value here, its default and what it sets; a value that does not parse is a failed item.

    Each item says found or not found and how to get it. Exit 0 when everything `roco run`
    needs is there (with the head camera perceiving, the default where libEGL or libOSMesa is
    installed, an off-screen GL context that opens), 1 otherwise. Takes a few seconds: MuJoCo's
    GL is tried in a child process, Docker is asked with time limits.

    With --compose, only the compose fleet's prerequisites (docs/deploy.md): the docker client
    (Debian's docker.io), an engine that answers it, Compose (`docker compose` or Debian's
    `docker-compose`), roco's image and, until it is built, debootstrap and the wheelhouse of
    scripts/build_image.sh; each one missing is named with how to get it, and the exit is 1."""
    from rich.console import Console

    from services.doctor import run_checks
    from services.doctor.model import run_ready
    from services.doctor.render import compose_verdict, show, verdict
    from services.doctor.settings import readings
    from velma.executor.capture import perception_mode

    if compose:
        from services.doctor.tools import docker_checks

        found = docker_checks()
        show(found, Console(highlight=False))
        typer.echo(compose_verdict(found))
        if any(c.missing for c in found):
            raise typer.Exit(1)
        return
    checks = run_checks(runs_dir)
    try:
        camera = perception_mode() == "camera"
    except ValueError:  # a bad ROCO_PERCEPTION: roco run refuses it; judge as the default
        camera = True
    fallback = not camera and Settings.from_env(only=("perception",)).perception is None
    show(checks, Console(highlight=False), readings())
    typer.echo(verdict(checks, camera, truth_by_default=fallback))
    if not run_ready(checks, camera):
        raise typer.Exit(1)


@app.command(short_help="Write RUN/report.md from a run folder.")
def report(run_dir: Annotated[Path, typer.Argument(metavar="RUN", help="a run folder")]) -> None:
    """Write RUN/report.md from the run's traffic record and run.json, with the requirement
    tree traced to the run (`roco spec trace RUN`). A folder that is not a run folder
    (neither run.json nor traffic.jsonl in it) is refused, exit 2, nothing written."""
    from services.report import write_report
    from services.spec_check.trace import report_rows

    try:
        typer.echo(
            str(write_report(_run_folder(run_dir), coverage=_coverage_summary(run_dir), tracer=report_rows))
        )
    except OSError as exc:
        raise fail(f"cannot write the report in {run_dir}: {exc.strerror or exc}") from None


def main() -> None:
    try:
        app()
    except KeyboardInterrupt:
        sys.exit(130)


if __name__ == "__main__":
    main()
