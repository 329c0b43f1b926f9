"""``roco hosts``: the fleet on two hosts made on this machine (docs/deploy.md, "Two hosts on
one machine"; root, iproute2, nftables).

    roco hosts up [--delay-ms 20 --jitter-ms 5 --loss-pct 1]   brain + robot, link shaped, fleet up
    roco hosts partition [SECONDS]     cut the link (for SECONDS, else until 'heal')
    roco hosts heal                    mend it
    roco hosts status                  hosts, addresses, shaping, link up or down
    roco hosts down                    stop the fleet, remove the namespaces, write the report
    roco hosts clean                   remove the host pairs that runs left behind

While up, ``roco send``/``status`` reach the brain's router as for ``roco up`` (``runs/.fleet.json``).
Bad input or a machine that cannot make namespaces: one line starting with ``roco:``, exit 2.
"""

from __future__ import annotations

import json
import signal
import time
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import msgspec
import typer

from services.cli_common import INTERRUPTED, MARKUP, SpecFile, chosen_spec, fail, interrupt, new_run_folder
from services.fleet_state import FLEET_FILE
from shared.settings import Settings

if TYPE_CHECKING:
    from services.hosts.fleet import TwoHosts
    from services.hosts.link import Shaping
    from services.hosts.netns import HostPair
    from services.runtime.run_folder import RunInfo

hosts_app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    rich_markup_mode=MARKUP,
    help="The fleet on two hosts made on this machine: brain and robot, a shaped link (docs/deploy.md).",
    short_help="The fleet on two hosts of this machine, joined by a shaped link.",
)
HOSTS_FILE = ".hosts.json"
RunsDir = Annotated[
    Path, typer.Option("--runs-dir", help="where 'roco hosts up' keeps the state of the two hosts")
]
UpRunsDir = Annotated[
    Path,
    typer.Option(
        "--runs-dir",
        help="where the fleet's run folder is made and the state of the two hosts kept for the "
        "other 'roco hosts' commands and 'roco send', 'status'",
    ),
]


class HostsState(msgspec.Struct):
    """What ``roco hosts up`` leaves for the other ``roco hosts`` commands."""

    tag: str
    subnet: int
    maker: int
    run_dir: str
    endpoint: str
    shaping: str
    how: str


def _state(runs_dir: Path) -> HostsState:
    path = runs_dir / HOSTS_FILE
    try:
        return msgspec.json.decode(path.read_bytes(), type=HostsState)
    except FileNotFoundError:
        raise fail(f"no two-host fleet is up (no {path}); 'roco hosts up' first", 2) from None
    except (OSError, msgspec.DecodeError, msgspec.ValidationError) as exc:
        raise fail(f"{path}: not a hosts state file: {str(exc).splitlines()[0]}", 2) from None


def _pair(state: HostsState) -> HostPair:
    from services.hosts.netns import HostPair

    return HostPair(state.tag, state.subnet, state.maker)


def _up_shaping(runs_dir: Path, delay_ms: float, jitter_ms: float, loss_pct: float) -> Shaping:
    """The link's shaping for `roco hosts up`; exits when a fleet is up in ``runs_dir`` already,
    the shaping is wrong or two hosts cannot be made here."""
    from services.hosts.link import Shaping
    from services.hosts.netns import unavailable

    if (runs_dir / HOSTS_FILE).exists() or (runs_dir / FLEET_FILE).exists():
        raise fail(f"a fleet is already up in {runs_dir}; 'roco hosts down' (or 'roco down') first", 2)
    try:
        shaping = Shaping(delay_ms, jitter_ms, loss_pct)
    except ValueError as exc:
        raise fail(str(exc), 2) from None
    why = unavailable()
    if why:
        raise fail(f"cannot make two hosts here: {why}", 2)
    return shaping


def _not_up(hosts: TwoHosts, exc: BaseException, run_dir: Path, info: RunInfo) -> typer.Exit:
    """The exit of a fleet that did not come up (``exc``; its hosts are removed already), once
    its processes are noted and its report written."""
    from services.runtime.run_folder import write_run_info
    from services.spec_check.report_cli import fleet_end

    interrupted = isinstance(exc, KeyboardInterrupt)
    why = "interrupted" if interrupted else str(exc)
    if hosts.fleet is not None:
        info.processes = hosts.fleet.pids()
        write_run_info(run_dir, info)
    fleet_end(run_dir, failure=why)
    code = INTERRUPTED if interrupted else 1
    return fail(f"{why}; nothing of the fleet is left running; run folder {run_dir}", code)


@hosts_app.command(short_help="Make brain and robot, shape the link, start the fleet across them.")
def up(
    delay_ms: Annotated[float, typer.Option(min=0, help="one-way delay of the link, each direction")] = 20.0,
    jitter_ms: Annotated[float, typer.Option(min=0, help="± this much, uniform")] = 5.0,
    loss_pct: Annotated[float, typer.Option(min=0, max=99, help="packets lost, each direction (%)")] = 1.0,
    realtime: Annotated[bool, typer.Option(help="pace the simulation to wall time")] = True,
    runs_dir: UpRunsDir = Path("runs"),
    spec: SpecFile = None,
) -> None:
    """Make the brain and robot hosts, shape the link, start the fleet of the specification
    across them (the robot's host runs ag_ex and a_ta, the brain every other agent; mutual TLS
    between the routers, access control on); it keeps running until `roco hosts down`, which
    writes the run's report. A fleet that does not come up is stopped, its hosts removed and
    its report written."""
    from services.fleet.launcher import LaunchError, spec_env
    from services.hosts.fleet import TwoHosts
    from services.hosts.netns import HostsError
    from services.runtime.run_folder import RunInfo, write_run_info

    spec_file = chosen_spec(spec)
    shaping = _up_shaping(runs_dir, delay_ms, jitter_ms, loss_pct)
    run_dir = new_run_folder(runs_dir)
    info = RunInfo(started=time.time(), realtime=realtime)
    write_run_info(run_dir, info)
    signal.signal(signal.SIGTERM, interrupt)
    env = {Settings.env_name("realtime"): "1" if realtime else "0", Settings.env_name("rerun"): "0"}
    hosts = TwoHosts(run_dir, shaping, env=env | spec_env(spec_file))
    try:
        waited = hosts.start()  # stops what it started and removes the hosts when it fails
    except (HostsError, LaunchError, KeyboardInterrupt) as exc:
        raise _not_up(hosts, exc, run_dir, info) from None
    assert hosts.pair is not None and hosts.fleet is not None
    pids = hosts.fleet.pids()
    info.router, info.processes = hosts.endpoint, pids
    write_run_info(run_dir, info)
    p = hosts.pair
    state = HostsState(p.tag, p.subnet, p.maker, str(run_dir), hosts.endpoint, str(shaping), hosts.how)
    (runs_dir / HOSTS_FILE).write_bytes(msgspec.json.encode(state))
    fleet = {"endpoint": hosts.endpoint, "run_dir": str(run_dir), "pids": pids}
    (runs_dir / FLEET_FILE).write_text(json.dumps(fleet))
    typer.echo(
        f"roco: two hosts up in {waited:.1f} s: {_placed(hosts)}; link {shaping} ({hosts.how}); "
        f"operator endpoint {hosts.endpoint}; run folder {run_dir}"
    )


def _placed(hosts: TwoHosts) -> str:
    """``brain NS (router, recorder, …), robot NS (router, …)``: what each host of ``hosts``
    runs (services/hosts/fleet.py ``placement``)."""
    from services.hosts.fleet import placement

    assert hosts.pair is not None and hosts.fleet is not None
    placed = placement(hosts.fleet.agents)
    return ", ".join(
        f"{host} {hosts.pair.netns(host)} ({', '.join(['router', *placed[host]])})" for host in placed
    )


@hosts_app.command(short_help="Cut the link (for SECONDS, else until heal).")
def partition(
    seconds: Annotated[float | None, typer.Argument(min=0.1, help="mend the link after this long")] = None,
    runs_dir: RunsDir = Path("runs"),
) -> None:
    """Cut the link between the hosts (recorded in the run folder's link.jsonl); with SECONDS,
    wait that long and mend it (Ctrl-C mends it at once)."""
    from services.hosts import link

    state = _state(runs_dir)
    pair, run_dir = _pair(state), Path(state.run_dir)
    link.partition(pair, run_dir, None)
    if seconds is None:
        typer.echo("roco: link down; 'roco hosts heal' mends it")
        return
    signal.signal(signal.SIGTERM, interrupt)
    typer.echo(f"roco: link down for {seconds:g} s")
    try:
        time.sleep(seconds)
    except KeyboardInterrupt:
        pass
    finally:
        link.heal(pair, run_dir)
    typer.echo("roco: link up")


@hosts_app.command(short_help="Mend the link.")
def heal(runs_dir: RunsDir = Path("runs")) -> None:
    """Mend the link."""
    from services.hosts import link

    state = _state(runs_dir)
    link.heal(_pair(state), Path(state.run_dir))
    typer.echo("roco: link up")


@hosts_app.command(short_help="The hosts, their addresses, the link's shaping and state.")
def status(runs_dir: RunsDir = Path("runs")) -> None:
    """The hosts, their addresses, the link's shaping and whether it is cut."""
    from services.hosts import link

    state = _state(runs_dir)
    pair = _pair(state)
    if not pair.exists():
        raise fail(f"the namespaces of {runs_dir / HOSTS_FILE} are gone; 'roco hosts down' clears it", 1)
    typer.echo(f"brain  {pair.netns('brain'):22s} link {pair.link_addr('brain')}  uplink {pair.uplink_addr}")
    typer.echo(f"robot  {pair.netns('robot'):22s} link {pair.link_addr('robot')}")
    typer.echo(f"link   {'DOWN (partitioned)' if link.is_cut(pair) else 'up'}; {state.shaping} ({state.how})")
    typer.echo(f"operator endpoint {state.endpoint}; run folder {state.run_dir}")


@hosts_app.command(short_help="Stop the fleet, remove both hosts, write the run's report.")
def down(runs_dir: RunsDir = Path("runs")) -> None:
    """Stop the fleet (only its processes), saying what it stops as it stops it: the agents,
    the recorder once it confirmed the traffic record (the recorder-sync barrier, as `roco
    down`), the routers; remove both namespaces and their links; then record in the run's
    run.json the commands the fleet was given and their outcomes (from its C2 traffic) and
    write its report."""
    from services.hosts.link import record_counters
    from services.hosts.netns import end_processes
    from services.recorder.sync import sync_fleet, sync_words
    from services.spec_check.report_cli import fleet_end

    state = _state(runs_dir)
    pair, run_dir = _pair(state), Path(state.run_dir)
    fleet_file = runs_dir / FLEET_FILE
    try:
        pids = {str(n): int(p) for n, p in json.loads(fleet_file.read_text()).get("pids", {}).items()}
    except (OSError, ValueError, AttributeError):
        pids = {}
    agents = {n: p for n, p in pids.items() if not n.startswith("router") and n not in ("recorder", "relay")}
    typer.echo("roco: stopping", nl=False)
    end_processes(list(agents.values()), 10.0)
    typer.echo("".join(f" {n}" for n in agents), nl=False)
    if "recorder" in pids:
        # everything the agents sent before they stopped is in the traffic record before it closes
        synced = sync_fleet(state.endpoint, run_dir / "security")
        typer.echo(f"; recorder: {sync_words(synced)}", nl=False)
    end_processes([pids[n] for n in ("recorder", "relay") if n in pids], 10.0)
    typer.echo("; routers", nl=False)
    record_counters(pair, run_dir)
    pair.destroy()  # ends what is left (the routers) and removes the namespaces
    typer.echo("; both hosts removed")
    fleet_file.unlink(missing_ok=True)
    (runs_dir / HOSTS_FILE).unlink(missing_ok=True)
    typer.echo(f"roco: two hosts down {fleet_end(run_dir)}")


@hosts_app.command(short_help="Remove the host pairs that killed runs left behind.")
def clean() -> None:
    """Remove the host pairs that earlier runs left behind (their maker gone, nothing running
    in them)."""
    from services.hosts.netns import sweep, unavailable

    why = unavailable(link=False)
    if why:
        raise fail(why, 2)
    removed = sweep()
    typer.echo(f"roco: removed {len(removed)} host pair(s){': ' + ', '.join(removed) if removed else ''}")
