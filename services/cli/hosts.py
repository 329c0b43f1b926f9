"""``roco hosts``: the fleet on two hosts made on this machine (docs/deploy.md, "Two hosts on
one machine"; root, iproute2, nftables; services/hosts/).

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

import signal
import time
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from services.cli.common import INTERRUPTED, MARKUP, SpecFile, chosen_spec, fail, interrupt, new_run_folder
from services.fleet_state import FLEET_FILE
from services.hosts.state import HOSTS_FILE, HostsState, HostsStateError, read_state
from shared.settings import Settings

if TYPE_CHECKING:
    from services.hosts.fleet import TwoHosts
    from services.hosts.link import Shaping

hosts_app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    rich_markup_mode=MARKUP,
    help="The fleet on two hosts made on this machine: brain and robot, a shaped link (docs/deploy.md).",
    short_help="The fleet on two hosts of this machine, joined by a shaped link.",
)
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


def _state(runs_dir: Path) -> HostsState:
    """The state of the two hosts up in ``runs_dir``; one line and exit 2 when there is none."""
    try:
        return read_state(runs_dir)
    except HostsStateError as exc:
        raise fail(str(exc), 2) from None


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
    from services.fleet.launcher import NotUp, spec_env
    from services.hosts.lifecycle import start_two_hosts
    from services.runtime.run_folder import RunInfo

    spec_file = chosen_spec(spec)
    shaping = _up_shaping(runs_dir, delay_ms, jitter_ms, loss_pct)
    run_dir = new_run_folder(runs_dir)
    info = RunInfo(started=time.time(), realtime=realtime)
    signal.signal(signal.SIGTERM, interrupt)
    env = {Settings.env_name("realtime"): "1" if realtime else "0", Settings.env_name("rerun"): "0"}
    try:
        hosts, waited = start_two_hosts(run_dir, runs_dir, shaping, env | spec_env(spec_file), info)
    except NotUp as exc:
        code = INTERRUPTED if exc.interrupted else 1
        raise fail(f"{exc.why}; nothing of the fleet is left running; run folder {run_dir}", code) from None
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
    pair, run_dir = state.pair(), Path(state.run_dir)
    link.partition(pair, run_dir, None)
    if seconds is None:
        typer.echo("roco: link down; 'roco hosts heal' mends it")
        return
    signal.signal(signal.SIGTERM, interrupt)
    typer.echo(f"roco: link down for {seconds:g} s")
    try:
        time.sleep(seconds)  # the cut's length the user asked for
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
    link.heal(state.pair(), Path(state.run_dir))
    typer.echo("roco: link up")


@hosts_app.command(short_help="The hosts, their addresses, the link's shaping and state.")
def status(runs_dir: RunsDir = Path("runs")) -> None:
    """The hosts, their addresses, the link's shaping and whether it is cut."""
    from services.hosts import link

    state = _state(runs_dir)
    pair = state.pair()
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
    from services.hosts.lifecycle import stop_two_hosts
    from services.spec_check.run_report import fleet_end

    state = _state(runs_dir)
    typer.echo("roco: stopping", nl=False)
    stop_two_hosts(runs_dir, state, lambda words: typer.echo(words, nl=False))
    typer.echo("")
    typer.echo(f"roco: two hosts down {fleet_end(Path(state.run_dir))}")


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
