"""The two-host fleet's start and end (``roco hosts up``, ``roco hosts down`` and ``roco down``
of it): the hosts made and the fleet started across them, their state left for the other
commands; then its processes stopped in order, the hosts removed and the state cleared."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from services.fleet_state import FLEET_FILE
from services.hosts.state import HOSTS_FILE, HostsState, write_state

if TYPE_CHECKING:
    from services.hosts.fleet import TwoHosts
    from services.hosts.link import Shaping
    from services.runtime.run_folder import RunInfo


def start_two_hosts(
    run_dir: Path, runs_dir: Path, shaping: Shaping, env: dict[str, str], info: RunInfo
) -> tuple[TwoHosts, float]:
    """Make the brain and robot hosts joined by a ``shaping`` link and start the fleet of
    ``run_dir`` across them with the environment ``env``; note its processes in ``info``
    (run.json) and leave its state in ``runs_dir`` (``.hosts.json`` and ``roco up``'s fleet
    file, which ``roco send`` and ``status`` read). The hosts and the seconds the fleet took.
    Raises NotUp (services/fleet/launcher.py) when it does not come up: its hosts are removed
    then, and its report written."""
    from services.fleet.launcher import LaunchError, NotUp
    from services.hosts.fleet import TwoHosts
    from services.hosts.netns import HostsError
    from services.runtime.run_folder import write_run_info
    from services.spec_check.run_report import fleet_end

    write_run_info(run_dir, info)
    hosts = TwoHosts(run_dir, shaping, env=env)
    try:
        waited = hosts.start()  # stops what it started and removes the hosts when it fails
    except (HostsError, LaunchError, KeyboardInterrupt) as exc:
        not_up = NotUp.of(exc)
        if hosts.fleet is not None:
            info.processes = hosts.fleet.pids()
            write_run_info(run_dir, info)
        fleet_end(run_dir, failure=not_up.why)
        raise not_up from None
    assert hosts.pair is not None and hosts.fleet is not None
    pids = hosts.fleet.pids()
    info.router, info.processes = hosts.endpoint, pids
    write_run_info(run_dir, info)
    p = hosts.pair
    write_state(
        runs_dir, HostsState(p.tag, p.subnet, p.maker, str(run_dir), hosts.endpoint, str(shaping), hosts.how)
    )
    fleet = {"endpoint": hosts.endpoint, "run_dir": str(run_dir), "pids": pids}
    (runs_dir / FLEET_FILE).write_text(json.dumps(fleet))
    return hosts, waited


def stop_two_hosts(runs_dir: Path, state: HostsState, say: Callable[[str], None]) -> None:
    """Stop the two-host fleet of ``state`` (only its processes) in ``runs_dir``, saying to
    ``say`` (one line, no line end) what it stops as it stops it: the agents, the recorder once
    it confirmed the traffic record (the recorder-sync barrier, as `roco down`), the routers;
    record the link's counters, remove both namespaces and their links, clear the state."""
    from services.hosts.link import record_counters
    from services.hosts.netns import end_processes
    from services.recorder.sync import sync_fleet, sync_words

    pair, run_dir = state.pair(), Path(state.run_dir)
    fleet_file = runs_dir / FLEET_FILE
    try:
        pids = {str(n): int(p) for n, p in json.loads(fleet_file.read_text()).get("pids", {}).items()}
    except (OSError, ValueError, AttributeError):
        pids = {}
    agents = {n: p for n, p in pids.items() if not n.startswith("router") and n not in ("recorder", "relay")}
    end_processes(list(agents.values()), 10.0)
    say("".join(f" {n}" for n in agents))
    if "recorder" in pids:
        # everything the agents sent before they stopped is in the traffic record before it closes
        synced = sync_fleet(state.endpoint, run_dir / "security")
        say(f"; recorder: {sync_words(synced)}")
    end_processes([pids[n] for n in ("recorder", "relay") if n in pids], 10.0)
    say("; routers")
    record_counters(pair, run_dir)
    pair.destroy()  # ends what is left (the routers) and removes the namespaces
    say("; both hosts removed")
    fleet_file.unlink(missing_ok=True)
    (runs_dir / HOSTS_FILE).unlink(missing_ok=True)
