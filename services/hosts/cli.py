"""``roco hosts``: the fleet on two hosts made on this machine (docs/deploy.md, "Two hosts on
one machine"; root, iproute2, nftables).

    roco hosts up [--delay-ms 20 --jitter-ms 5 --loss-pct 1]   brain + robot, link shaped, fleet up
    roco hosts partition [SECONDS]     cut the link (for SECONDS, else until 'heal')
    roco hosts heal                    mend it
    roco hosts status                  hosts, addresses, shaping, link up or down
    roco hosts down                    stop the fleet, remove the namespaces
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

if TYPE_CHECKING:
    from services.hosts.netns import HostPair

hosts_app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    rich_markup_mode="markdown",
    help="The fleet on two hosts made on this machine: brain and robot, a shaped link (docs/deploy.md).",
    short_help="The fleet on two hosts of this machine, joined by a shaped link.",
)
HOSTS_FILE = ".hosts.json"
FLEET_FILE = ".fleet.json"  # services/cli.py: FLEET_FILE
RunsDir = Annotated[Path, typer.Option(help="where the run folder is made")]


class HostsState(msgspec.Struct):
    """What ``roco hosts up`` leaves for the other ``roco hosts`` commands."""

    tag: str
    subnet: int
    maker: int
    run_dir: str
    endpoint: str
    shaping: str
    how: str


def _fail(message: str, code: int = 2) -> typer.Exit:
    typer.echo(f"roco: {message}", err=True)
    return typer.Exit(code)


def _state(runs_dir: Path) -> HostsState:
    path = runs_dir / HOSTS_FILE
    try:
        return msgspec.json.decode(path.read_bytes(), type=HostsState)
    except FileNotFoundError:
        raise _fail(f"no two-host fleet is up (no {path}); 'roco hosts up' first") from None
    except (OSError, msgspec.DecodeError, msgspec.ValidationError) as exc:
        raise _fail(f"{path}: not a hosts state file: {str(exc).splitlines()[0]}") from None


def _pair(state: HostsState) -> HostPair:
    from services.hosts.netns import HostPair

    return HostPair(state.tag, state.subnet, state.maker)


def _interrupt(signum: int, frame: object) -> None:
    """SIGTERM ends a timed partition as Ctrl-C does: the link is mended first."""
    raise KeyboardInterrupt


@hosts_app.command(short_help="Make brain and robot, shape the link, start the fleet across them.")
def up(
    delay_ms: Annotated[float, typer.Option(min=0, help="one-way delay of the link, each direction")] = 20.0,
    jitter_ms: Annotated[float, typer.Option(min=0, help="± this much, uniform")] = 5.0,
    loss_pct: Annotated[float, typer.Option(min=0, max=99, help="packets lost, each direction (%)")] = 1.0,
    realtime: Annotated[bool, typer.Option(help="pace the simulation to wall time")] = True,
    runs_dir: RunsDir = Path("runs"),
) -> None:
    """Make the brain and robot hosts, shape the link, start the fleet across them (mutual TLS
    between the routers, access control on); it keeps running until `roco hosts down`."""
    from services.fleet.launcher import LaunchError
    from services.hosts.fleet import TwoHosts
    from services.hosts.link import Shaping
    from services.hosts.netns import HostsError
    from services.runtime.run_folder import RunInfo, new_run_dir, write_run_info

    if (runs_dir / HOSTS_FILE).exists() or (runs_dir / FLEET_FILE).exists():
        raise _fail(f"a fleet is already up in {runs_dir}; 'roco hosts down' (or 'roco down') first")
    try:
        shaping = Shaping(delay_ms, jitter_ms, loss_pct)
    except ValueError as exc:
        raise _fail(str(exc)) from None
    run_dir = new_run_dir(runs_dir)
    hosts = TwoHosts(run_dir, shaping, env={"ROCO_REALTIME": "1" if realtime else "0", "ROCO_RERUN": "0"})
    try:
        waited = hosts.start()
    except (HostsError, LaunchError) as exc:
        raise _fail(str(exc), 1) from None
    assert hosts.pair is not None and hosts.fleet is not None
    pids = hosts.fleet.pids()
    write_run_info(
        run_dir, RunInfo(started=time.time(), router=hosts.endpoint, processes=pids, realtime=realtime)
    )
    p = hosts.pair
    state = HostsState(p.tag, p.subnet, p.maker, str(run_dir), hosts.endpoint, str(shaping), hosts.how)
    (runs_dir / HOSTS_FILE).write_bytes(msgspec.json.encode(state))
    fleet = {"endpoint": hosts.endpoint, "run_dir": str(run_dir), "pids": pids}
    (runs_dir / FLEET_FILE).write_text(json.dumps(fleet))
    typer.echo(
        f"roco: two hosts up in {waited:.1f} s: "
        f"brain {p.netns('brain')} (router, recorder, a_km, a_pl, a_co, a_hi), "
        f"robot {p.netns('robot')} (router, ag_ex, a_ta); link {shaping} ({hosts.how}); "
        f"operator endpoint {hosts.endpoint}; run folder {run_dir}"
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
    signal.signal(signal.SIGTERM, _interrupt)
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
        raise _fail(f"the namespaces of {runs_dir / HOSTS_FILE} are gone; 'roco hosts down' clears it", 1)
    typer.echo(f"brain  {pair.netns('brain'):22s} link {pair.link_addr('brain')}  uplink {pair.uplink_addr}")
    typer.echo(f"robot  {pair.netns('robot'):22s} link {pair.link_addr('robot')}")
    typer.echo(f"link   {'DOWN (partitioned)' if link.is_cut(pair) else 'up'}; {state.shaping} ({state.how})")
    typer.echo(f"operator endpoint {state.endpoint}; run folder {state.run_dir}")


@hosts_app.command(short_help="Stop the fleet and remove both hosts.")
def down(runs_dir: RunsDir = Path("runs")) -> None:
    """Stop the fleet (only its processes) and remove both namespaces and their links."""
    from services.hosts.netns import end_processes

    state = _state(runs_dir)
    pair = _pair(state)
    fleet_file = runs_dir / FLEET_FILE
    try:
        pids = json.loads(fleet_file.read_text()).get("pids", {})
    except (OSError, ValueError):
        pids = {}
    agents = [int(p) for n, p in pids.items() if not str(n).startswith("router") and n != "recorder"]
    end_processes(agents, 10.0)
    end_processes([int(pids[n]) for n in ("recorder", "relay") if n in pids], 10.0)
    pair.destroy()  # ends what is left (the routers) and removes the namespaces
    fleet_file.unlink(missing_ok=True)
    (runs_dir / HOSTS_FILE).unlink(missing_ok=True)
    typer.echo(f"roco: two hosts down; run folder {state.run_dir}")


@hosts_app.command(short_help="Remove the host pairs that killed runs left behind.")
def clean() -> None:
    """Remove the host pairs that earlier runs left behind (their maker gone, nothing running
    in them)."""
    from services.hosts.netns import sweep, unavailable

    why = unavailable(link=False)
    if why:
        raise _fail(why)
    removed = sweep()
    typer.echo(f"roco: removed {len(removed)} host pair(s){': ' + ', '.join(removed) if removed else ''}")
