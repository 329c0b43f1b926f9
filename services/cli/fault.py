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
one. Bad input: one line, exit 2. The faults themselves: services/fault/.
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

from services.cli.common import (
    MARKUP,
    CredentialsOption,
    RouterOption,
    SpecFile,
    chosen_spec,
    fail,
    fleet_system,
)
from services.fault import process
from services.fault.compose import DEFAULT_FILE, Compose, compose_services, joined_services
from services.fault.control import NetChange, clear_update
from services.fault.process import ACTIONS, FaultError, UpFleet, local_services
from services.fault.target import SeveralFleets, compose_target, record, router_endpoint
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


def _fleet(
    flag: bool | None,
    project: str | None,
    file: Path | None,
    runs_dir: Path,
    router: str | None,
    spec: Path | None,
) -> tuple[Compose | None, SystemSpec]:
    """The fleet a fault command acts on (services/fault/target.py ``compose_target``: None
    for the local one; several compose fleets running and none named: exit 2) and its
    specification: ``spec`` (``--spec``), else the one the local fleet's run folder keeps, else
    the shipped one; a compose fleet's services are that specification's."""
    try:
        dc = compose_target(flag, project, file, runs_dir)
    except SeveralFleets as exc:
        raise fail(str(exc), code=2) from None
    if dc is None:
        return None, fleet_system(spec, runs_dir, router)
    from services.spec.model import load

    system = load(chosen_spec(spec))
    return dataclasses.replace(dc, services=compose_services(system), joined=joined_services(system)), system


def _endpoint(router: str | None, runs_dir: Path, credentials: Path | None = None) -> str:
    """The router endpoint (services/fault/target.py ``router_endpoint``: ``router``, the fleet
    of ``roco up``, ``ROCO_ROUTER``), with ``credentials`` registered for it when given
    (services/security/context.py)."""
    from services.security.context import register

    endpoint = router_endpoint(router, runs_dir)
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
    """Hand the events to the traffic recorder (services/fault/target.py ``record``); a warning
    (not a failure) when it cannot."""
    warning = record(endpoint, events)
    if warning is not None:
        typer.echo(f"roco: {warning}", err=True)


def _compose_faults(endpoint: str, apply: Callable[[], list[FaultEvent]]) -> None:
    """Run ``apply`` (it applies container faults and returns their events), tell what was
    applied and hand the events to the traffic recorder; a :class:`FaultError`: one line,
    exit 1."""
    try:
        events = apply()
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
        _compose_faults(endpoint, lambda: dc.net(service, delay, loss, partition, dev))
        return
    _agent_net(endpoint, service, NetChange(delay, loss, partition), system.launch_order)


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
def _check_target(target: str | None, system: SystemSpec) -> None:
    """Exit 2 unless ``target`` is None, a channel of ``system``, '*' or a service."""
    channels = _channels(system)
    if target is not None and target not in (*channels, ANY_CHANNEL, *compose_services(system)):
        raise fail(f"{target!r} is neither a channel ({', '.join(channels)}) nor a service", code=2)


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
        _compose_faults(endpoint, lambda: dc.clear(target, dev))
    from services.fault.control import send_update

    clearing = clear_update(target, system)
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
