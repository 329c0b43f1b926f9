"""``roco fault``: inject faults into a running fleet (docs/faults.md).

    roco fault kill|stop|start|pause|unpause|restart SERVICE
    roco fault net SERVICE [--delay S] [--loss P] [--partition|--heal]
    roco fault msg CHANNEL [--drop P] [--duplicate P] [--delay S [--delay-p P]] [--reorder P]
                           [--corrupt P] [--seed N]
    roco fault clear [SERVICE|CHANNEL]
    roco fault show

Local fleet (``roco up``): process faults by PID, network and message faults through the
agents' fault layer over Zenoh. Compose (``--compose``, ``ROCO_COMPOSE_PROJECT`` set, or no
local fleet and one compose fleet running): process faults with ``docker compose``, network
faults with ``docker network`` and ``tc netem``; message faults still over Zenoh
(``--router``). The agents, services and channels are those of the fleet's specification:
``--spec`` (``ROCO_SPEC``), else the one a local fleet's run folder keeps, else the shipped
one. Bad input: one line, exit 2.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer
import zenoh

from services.cli_common import (
    MARKUP,
    CredentialsOption,
    RouterOption,
    SpecFile,
    chosen_spec,
    fail,
    fleet_system,
)
from services.deploy.engine import ComposeFleet, running_fleets
from services.fault import process
from services.fault.compose import DEFAULT_FILE, Compose, compose_services, joined_services
from services.fault.process import ACTIONS, FaultError, UpFleet, local_services
from services.fleet_state import FLEET_FILE
from services.runtime.faults import (
    ANY_CHANNEL,
    FaultEvent,
    FaultReport,
    FaultUpdate,
    MessageFaults,
    NetFaults,
)
from shared.settings import Settings

if TYPE_CHECKING:
    from services.spec.model import SystemSpec

fault_app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    rich_markup_mode=MARKUP,
    help="Inject faults into a running fleet: processes, network, messages (docs/faults.md).",
)

PROJECT_ENV = Settings.env_name("compose_project")
RunsDir = Annotated[Path, typer.Option(help="where 'roco up' keeps its fleet state")]
ComposeFlag = Annotated[
    bool | None,
    typer.Option(
        "--compose/--local",
        help=f"a Docker Compose deployment (default: compose when ${PROJECT_ENV} is set, or when no "
        "local fleet is up and one compose fleet runs)",
    ),
]
Project = Annotated[
    str | None, typer.Option(help=f"compose project name (default: ${PROJECT_ENV}, else the one running)")
]
ComposeFile = Annotated[
    Path | None, typer.Option(help=f"the compose file [default: the running fleet's, else {DEFAULT_FILE}]")
]


def _compose(flag: bool | None, project: str | None, file: Path | None, runs_dir: Path) -> Compose | None:
    """The compose fleet a fault command acts on, None for the local fleet of ``roco up``.
    Without ``--compose/--local`` (``flag`` None) and ``ROCO_COMPOSE_PROJECT``: the local fleet
    when ``runs_dir`` holds one, else the compose fleet that runs (several: exit 2 asking for
    ``--project``; none: local, whose error says to start one or add ``--compose``)."""
    named = project or Settings.from_env(only=("compose_project",)).compose_project
    if _local(flag, named, runs_dir):
        return None
    if named is not None:
        return Compose(file=file or DEFAULT_FILE, project=named, state_dir=runs_dir)
    running = _the_running_fleet()
    if running is not None:
        return _compose_of(running, file, runs_dir)
    return Compose(file=file or DEFAULT_FILE, state_dir=runs_dir) if flag else None


def _fleet(
    flag: bool | None,
    project: str | None,
    file: Path | None,
    runs_dir: Path,
    router: str | None,
    spec: Path | None,
) -> tuple[Compose | None, SystemSpec]:
    """The fleet a fault command acts on (:func:`_compose`: None for the local one) and its
    specification: ``spec`` (``--spec``), else the one the local fleet's run folder keeps, else
    the shipped one; a compose fleet's services are that specification's."""
    dc = _compose(flag, project, file, runs_dir)
    if dc is None:
        return None, fleet_system(spec, runs_dir, router)
    from services.spec.model import load

    system = load(chosen_spec(spec))
    return dataclasses.replace(dc, services=compose_services(system), joined=joined_services(system)), system


def _local(flag: bool | None, named: str | None, runs_dir: Path) -> bool:
    """Whether the local fleet is meant: ``--local``, or neither flag nor project given and
    ``runs_dir`` holds the state of ``roco up``'s fleet."""
    return flag is False or (flag is None and named is None and (runs_dir / FLEET_FILE).exists())


def _the_running_fleet() -> ComposeFleet | None:
    """The one compose fleet that runs (services/deploy/engine.py), None when none does; exit
    2 asking for ``--project`` when several do."""
    fleets = running_fleets()
    if len(fleets) > 1:
        names = ", ".join(f.project for f in fleets)
        raise fail(f"compose fleets {names} run: say which with --compose --project NAME", code=2)
    return fleets[0] if fleets else None


def _compose_of(fleet: ComposeFleet, file: Path | None, runs_dir: Path) -> Compose:
    """The running ``fleet``: its project, and the first of its compose files that is on this
    host unless ``file`` is given."""
    return Compose(file=file or fleet.file() or DEFAULT_FILE, project=fleet.project, state_dir=runs_dir)


def _endpoint(router: str | None, runs_dir: Path, credentials: Path | None = None) -> str:
    """The router endpoint (``router``, the fleet of ``roco up``, ``ROCO_ROUTER``), with
    ``credentials`` registered for it when given (services/security/context.py)."""
    from services.security.context import register

    if router:
        endpoint = router
    else:
        try:
            endpoint = UpFleet.load(runs_dir).endpoint
        except FaultError:
            endpoint = ",".join(Settings.from_env(only=("router",)).router)
    if credentials is not None:
        if not credentials.is_dir():
            raise fail(f"{credentials}: no such credentials folder", code=2)
        register(endpoint, credentials)
    return endpoint


@contextlib.contextmanager
def _session(endpoint: str) -> Iterator[zenoh.Session]:
    """The operator's client session with the router at ``endpoint``, closed on leaving; one
    line (no router, refused for want of credentials, …) and exit 1 when it cannot open."""
    from services.runtime.session import SessionRefused, open_operator

    try:
        session = open_operator(endpoint)
    except SessionRefused as exc:
        raise fail(str(exc)) from None
    try:
        yield session
    finally:
        session.close()


def _record(endpoint: str, events: list[FaultEvent]) -> None:
    """Hand the events to the traffic recorder; a warning (not a failure) when it cannot."""
    from services.runtime.session import SessionRefused, alive_agents, open_operator

    try:
        session = open_operator(endpoint)
    except SessionRefused as exc:
        typer.echo(f"roco: (fault not recorded: {exc})", err=True)
        return
    try:
        if "recorder" not in alive_agents(session, timeout=0.5):
            typer.echo("roco: (fault not recorded: the traffic recorder is not alive)", err=True)
            return
        if not process.record_events(session, events):
            typer.echo("roco: (the traffic recorder did not confirm the fault event)", err=True)
    finally:
        session.close()


def _compose_faults(endpoint: str, apply: Callable[[list[FaultEvent]], None]) -> None:
    """Run ``apply`` (it appends the events of the container faults it applies), tell what
    was applied and hand the events to the traffic recorder; a :class:`FaultError`: one line,
    exit 1."""
    events: list[FaultEvent] = []
    try:
        apply(events)
    except FaultError as exc:
        raise fail(str(exc)) from None
    for ev in events:
        typer.echo(f"roco: {ev.target}: {ev.kind} {ev.detail}")
    _record(endpoint, events)


# ---- process faults ----------------------------------------------------------------------
SERVICE_HELP = (
    "the router, the recorder or an agent of the fleet's specification (locally also world, "
    "when an agent plays the robot; compose: viewer)"
)
_PAST = {
    "kill": "killed",
    "stop": "stopped",
    "start": "started",
    "pause": "paused",
    "unpause": "unpaused",
    "restart": "restarted",
}


def _process_fault(action: str) -> None:
    def command(
        service: Annotated[str, typer.Argument(help=SERVICE_HELP)],
        runs_dir: RunsDir = Path("runs"),
        compose: ComposeFlag = None,
        project: Project = None,
        compose_file: ComposeFile = None,
        router: RouterOption = None,
        credentials: CredentialsOption = None,
        timeout: Annotated[float, typer.Option(help="seconds to wait for the service")] = 60.0,
        spec: SpecFile = None,
    ) -> None:
        dc, system = _fleet(compose, project, compose_file, runs_dir, router, spec)
        try:
            if dc is not None:
                event = dc.process(action, service)
                endpoint = _endpoint(router, runs_dir, credentials)
            else:
                _check_local(service, system)
                fleet = UpFleet.load(runs_dir, spec)
                event = process.apply(fleet, action, service, timeout)
                endpoint = fleet.endpoint
        except FaultError as exc:
            raise fail(str(exc)) from None
        typer.echo(f"roco: {_PAST[action]} {service} ({event.detail})")
        _record(endpoint, [event])

    command.__doc__ = {
        "kill": "Kill SERVICE (SIGKILL; compose: docker compose kill).",
        "stop": "Stop SERVICE (SIGTERM, SIGKILL after 10 s; compose: docker compose stop).",
        "start": "Start SERVICE again as the launcher did and wait until it is alive.",
        "pause": "Freeze SERVICE (SIGSTOP; compose: docker compose pause).",
        "unpause": "Let a paused SERVICE run again (SIGCONT).",
        "restart": "Stop SERVICE, then start it again.",
    }[action]
    fault_app.command(action)(command)


def _check_local(service: str, system: SystemSpec) -> None:
    """Exit 2 unless ``service`` is one of a local fleet of ``system``."""
    known = local_services(system)
    if service not in known:
        raise fail(f"no service {service!r} in a local fleet (services: {', '.join(known)})", code=2)


for _action in ACTIONS:
    _process_fault(_action)


# ---- network faults ----------------------------------------------------------------------
def _probability(name: str, value: float | None) -> None:
    if value is not None and not (0.0 <= value <= 1.0):
        raise fail(f"{name} must be a probability in [0, 1], not {value:g}", code=2)


def _seconds(name: str, value: float | None) -> None:
    if value is not None and not (math.isfinite(value) and 0.0 <= value <= 3600.0):
        raise fail(f"{name} must be seconds in [0, 3600], not {value:g}", code=2)


def _net_text(net: NetFaults) -> str:
    parts = []
    if net.delay_s:
        parts.append(f"delay {net.delay_s:g} s")
    if net.loss:
        parts.append(f"loss {net.loss:g}")
    if net.partition:
        parts.append("partitioned")
    return ", ".join(parts) or "none"


@fault_app.command()
def net(
    service: Annotated[str, typer.Argument(help="the service whose network is disturbed")],
    delay: Annotated[float | None, typer.Option(help="seconds added to everything it sends")] = None,
    loss: Annotated[float | None, typer.Option(help="probability that something it sends is lost")] = None,
    partition: Annotated[
        bool | None, typer.Option("--partition/--heal", help="cut it off (in and out) / connect it again")
    ] = None,
    dev: Annotated[str, typer.Option(help="compose: the container's interface for tc netem")] = "eth0",
    runs_dir: RunsDir = Path("runs"),
    compose: ComposeFlag = None,
    project: Project = None,
    compose_file: ComposeFile = None,
    router: RouterOption = None,
    credentials: CredentialsOption = None,
    spec: SpecFile = None,
) -> None:
    """Network faults of one service: delay, loss, partition.

    Options not given keep their current value; --delay 0 --loss 0 remove them."""
    _seconds("--delay", delay)
    _probability("--loss", loss)
    if delay is None and loss is None and partition is None:
        raise fail("nothing to change: give --delay, --loss, --partition or --heal", code=2)
    dc, system = _fleet(compose, project, compose_file, runs_dir, router, spec)
    endpoint = _endpoint(router, runs_dir, credentials)
    if dc is not None:
        _compose_faults(endpoint, _container_net(dc, service, delay, loss, partition, dev))
        return
    _agent_net(endpoint, service, NetChange(delay, loss, partition), system.launch_order)


def _container_net(
    dc: Compose, service: str, delay: float | None, loss: float | None, partition: bool | None, dev: str
) -> Callable[[list[FaultEvent]], None]:
    """What `roco fault net` applies to a compose fleet's container: netem when the delay or
    loss is given, then a partition or its healing."""

    def apply(events: list[FaultEvent]) -> None:
        if delay is not None or loss is not None:
            events.append(dc.netem(service, delay or 0.0, loss or 0.0, dev))
        if partition is True:
            events.append(dc.partition(service))
        elif partition is False:
            events.append(dc.heal(service))

    return apply


@dataclasses.dataclass(frozen=True)
class NetChange:
    """What `roco fault net` changes of an agent's network faults (None: kept as it is)."""

    delay: float | None
    loss: float | None
    partition: bool | None

    def applied_to(self, now: NetFaults) -> NetFaults:
        return NetFaults(
            delay_s=now.delay_s if self.delay is None else self.delay,
            loss=now.loss if self.loss is None else self.loss,
            partition=now.partition if self.partition is None else self.partition,
        )


def _agent_net(endpoint: str, service: str, change: NetChange, agents: tuple[str, ...]) -> None:
    """`roco fault net` on a local fleet whose agents are ``agents``: the agent's fault layer
    changes the options given, keeping the others; one line says the agent's network faults now."""
    if service not in agents:
        raise fail(
            f"network faults of {service!r} need --compose (locally only the agents "
            f"{', '.join(agents)} have the fault layer)",
            code=2,
        )
    from services.fault.control import send_update

    with _session(endpoint) as session:
        current, missing = send_update(session, FaultUpdate(), service, agents=agents)
        if missing:
            raise fail(f"{service} did not answer at {endpoint}; is it running?")
        new = change.applied_to(current[service].net)
        got, missing = send_update(session, FaultUpdate(set_services={service: new}), service, agents=agents)
    if missing:
        raise fail(f"{service} did not confirm the change")
    typer.echo(f"roco: {service} network faults: {_net_text(got[service].net)}")


# ---- message faults ----------------------------------------------------------------------
def _channels(system: SystemSpec) -> list[str]:
    return [c.name for c in system.channels]


def _msg_text(mf: MessageFaults) -> str:
    parts = [
        f"{name} {value:g}"
        for name, value in (
            ("drop", mf.drop),
            ("duplicate", mf.duplicate),
            ("reorder", mf.reorder),
            ("corrupt", mf.corrupt),
        )
        if value
    ]
    if mf.delay and mf.delay_s:
        parts.insert(1, f"delay {mf.delay_s:g} s (p {mf.delay:g})")
    return ", ".join(parts) or "none"


def _check_channel(channel: str, system: SystemSpec) -> None:
    """Exit 2 unless ``channel`` is one of ``system``'s, or '*'."""
    known = _channels(system)
    if channel not in (*known, ANY_CHANNEL):
        raise fail(f"unknown channel {channel!r} (channels: {', '.join(known)}, or '*')", code=2)


def _message_faults(
    drop: float,
    duplicate: float,
    delay: float | None,
    delay_p: float | None,
    reorder: float,
    hold: float,
    corrupt: float,
) -> MessageFaults:
    """The message faults of `roco fault msg`'s options (a delay without ``delay_p``: every
    communicate); exit 2 when a probability or a time is out of range, or ``delay_p`` comes
    without ``delay``."""
    for name, p in (
        ("--drop", drop),
        ("--duplicate", duplicate),
        ("--delay-p", delay_p),
        ("--reorder", reorder),
        ("--corrupt", corrupt),
    ):
        _probability(name, p)
    _seconds("--delay", delay)
    _seconds("--hold", hold)
    if delay_p is not None and delay is None:
        raise fail("--delay-p needs --delay S", code=2)
    return MessageFaults(
        drop=drop,
        duplicate=duplicate,
        delay=(1.0 if delay_p is None else delay_p) if delay else 0.0,
        delay_s=delay or 0.0,
        reorder=reorder,
        hold_s=hold,
        corrupt=corrupt,
    )


@fault_app.command()
def msg(
    channel: Annotated[
        str, typer.Argument(help="a channel of the fleet's specification, or '*' for every one")
    ],
    drop: Annotated[float, typer.Option(help="probability a communicate is dropped")] = 0.0,
    duplicate: Annotated[float, typer.Option(help="probability it is sent twice")] = 0.0,
    delay: Annotated[float | None, typer.Option(help="seconds a delayed communicate is late")] = None,
    delay_p: Annotated[
        float | None, typer.Option(help="probability it is delayed (default 1 with --delay)")
    ] = None,
    reorder: Annotated[float, typer.Option(help="probability it is held and sent after the next one")] = 0.0,
    hold: Annotated[float, typer.Option(help="the longest a reordered communicate is held (s)")] = 1.0,
    corrupt: Annotated[float, typer.Option(help="probability 1–3 of its bytes are flipped")] = 0.0,
    seed: Annotated[int | None, typer.Option(help="reseed every agent's fault RNG")] = None,
    runs_dir: RunsDir = Path("runs"),
    router: RouterOption = None,
    credentials: CredentialsOption = None,
    spec: SpecFile = None,
) -> None:
    """Message faults on one channel: drop, duplicate, delay, reorder, corrupt.

    Applied by the sending agent's transport, replacing the channel's previous ones; works
    on local and compose fleets alike (over Zenoh)."""
    system = fleet_system(spec, runs_dir, router)
    _check_channel(channel, system)
    mf = _message_faults(drop, duplicate, delay, delay_p, reorder, hold, corrupt)
    if not mf.active() and seed is None:
        raise fail(f"no fault given (use 'roco fault clear {channel}' to remove {channel}'s faults)", code=2)
    from services.fault.control import send_update

    endpoint = _endpoint(router, runs_dir, credentials)
    update = FaultUpdate(set_channels={channel: mf} if mf.active() else {}, seed=seed)
    with _session(endpoint) as session:
        got, missing = send_update(session, update, agents=system.agent_names)
    if not got:
        raise fail(f"no agent answered at {endpoint}; is the fleet up?")
    if missing:
        typer.echo(f"roco: no answer from {', '.join(missing)}", err=True)
    typer.echo(f"roco: {channel}: {_msg_text(mf)} on {', '.join(sorted(got))}")
    if missing:
        raise typer.Exit(1)


# ---- clear and show ----------------------------------------------------------------------
def _container_clear(dc: Compose, target: str | None, dev: str) -> Callable[[list[FaultEvent]], None]:
    """What `roco fault clear` applies to a compose fleet's containers (``target``, or every
    service): a partition healed, netem removed (every service: where it can be)."""

    def apply(events: list[FaultEvent]) -> None:
        for service in [target] if target else dc.services:
            if service in dc.partitioned():
                events.append(dc.heal(service))
            if target is not None:
                events.append(dc.netem(service, 0.0, 0.0, dev))
            else:
                # not running, or no tc in its image: nothing to clear there
                with contextlib.suppress(FaultError):
                    events.append(dc.netem(service, 0.0, 0.0, dev))

    return apply


def _check_target(target: str | None, system: SystemSpec) -> None:
    """Exit 2 unless ``target`` is None, a channel of ``system``, '*' or a service."""
    channels = _channels(system)
    if target is not None and target not in (*channels, ANY_CHANNEL, *compose_services(system)):
        raise fail(f"{target!r} is neither a channel ({', '.join(channels)}) nor a service", code=2)


def _clear_update(target: str | None, system: SystemSpec) -> tuple[FaultUpdate, str | None] | None:
    """The update that clears ``target``'s faults in the fault layers of ``system``'s agents,
    and the agent it goes to (None: every agent); None when ``target`` is a service without one."""
    channels = _channels(system)
    if target in system.agent_names:
        return FaultUpdate(clear_services=[target]), target
    if target is None:
        return FaultUpdate(clear_channels=["*"], clear_services=["*"]), None
    if target in (*channels, ANY_CHANNEL):
        return FaultUpdate(clear_channels=[target]), None
    return None


@fault_app.command()
def clear(
    target: Annotated[str | None, typer.Argument(help="a service or a channel (none: every fault)")] = None,
    dev: Annotated[str, typer.Option(help="compose: the containers' interface for tc netem")] = "eth0",
    runs_dir: RunsDir = Path("runs"),
    compose: ComposeFlag = None,
    project: Project = None,
    compose_file: ComposeFile = None,
    router: RouterOption = None,
    credentials: CredentialsOption = None,
    spec: SpecFile = None,
) -> None:
    """Remove message and network faults of a channel, a service, or all.

    Processes stopped or paused stay so: start or unpause them."""
    dc, system = _fleet(compose, project, compose_file, runs_dir, router, spec)
    _check_target(target, system)
    endpoint = _endpoint(router, runs_dir, credentials)
    if dc is not None and (target is None or target in dc.services):
        _compose_faults(endpoint, _container_clear(dc, target, dev))
    from services.fault.control import send_update

    clearing = _clear_update(target, system)
    if clearing is None:
        if dc is None:
            raise fail(f"{target} has no fault layer locally: nothing to clear", code=2)
        return
    update, to = clearing
    with _session(endpoint) as session:
        got, missing = send_update(session, update, to, agents=system.agent_names)
    if not got:
        raise fail(f"no agent answered at {endpoint}")
    typer.echo(f"roco: faults of {target or 'every channel and service'} cleared on {', '.join(sorted(got))}")
    if missing:
        raise fail(f"no answer from {', '.join(missing)}")


def _report_line(r: FaultReport) -> str:
    chans = "; ".join(f"{c} {_msg_text(mf)}" for c, mf in sorted(r.channels.items())) or "none"
    applied = ", ".join(f"{k} {v}" for k, v in sorted(r.applied.items())) or "none"
    return f"{r.agent:6s} net: {_net_text(r.net)} | channels: {chans} | applied: {applied} | seed {r.seed}"


@fault_app.command()
def show(
    dev: Annotated[str, typer.Option(help="compose: the containers' interface for tc netem")] = "eth0",
    runs_dir: RunsDir = Path("runs"),
    compose: ComposeFlag = None,
    project: Project = None,
    compose_file: ComposeFile = None,
    router: RouterOption = None,
    credentials: CredentialsOption = None,
    spec: SpecFile = None,
) -> None:
    """Each agent's fault settings and the faults it applied so far.

    With --compose also each container's tc qdisc and the partitions."""
    from services.fault.control import send_update

    dc, system = _fleet(compose, project, compose_file, runs_dir, router, spec)
    order = system.launch_order
    endpoint = _endpoint(router, runs_dir, credentials)
    with _session(endpoint) as session:
        got, missing = send_update(session, FaultUpdate(), agents=order)
    for name in sorted(got, key=lambda n: order.index(n) if n in order else len(order)):
        typer.echo(_report_line(got[name]))
    for name in missing:
        typer.echo(f"{name:6s} no answer")
    if dc is not None:
        typer.echo(f"partitioned (compose): {', '.join(dc.partitioned()) or 'none'}")
        for service in dc.services:
            try:
                typer.echo(f"{service:8s} tc: {dc.tc_show(service, dev)}")
            except FaultError as exc:
                typer.echo(f"{service:8s} {exc}")
    if not got and dc is None:
        raise fail(f"no agent answered at {endpoint}")
