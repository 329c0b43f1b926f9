"""Start a fleet that keeps running on this machine (``roco up``): router, recorder, agents and
the faces asked for, each waited for alive, its run.json and the state ``roco down``, ``send``
and ``status`` find it by; a fleet that does not come up is stopped and its report written."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from services.fleet.launcher import GATEWAY, ROS2, Fleet, LaunchError, NotUp
from services.fleet_state import FleetState, write_state
from services.runtime.run_folder import RunInfo, write_run_info
from services.runtime.session import open_client

if TYPE_CHECKING:
    import zenoh


@dataclass(frozen=True)
class Started:
    """A fleet up: its router's ``endpoint``, the seconds its agents took to come alive
    (``waited``) and the words that name the faces it serves (``served``, "" when none)."""

    endpoint: str
    waited: float
    served: str


def start_fleet(
    run_dir: Path,
    runs_dir: Path,
    router: str,
    env: dict[str, str],
    info: RunInfo,
    gateway: int | None,
    ros2: tuple[str, ...] | None,
) -> Started:
    """Start the fleet of ``run_dir`` with its router at ``router`` and the environment ``env``
    (and the ACL gateway on port ``gateway``, the ROS 2 face with the arguments ``ros2``; None:
    none), wait for each part, note its processes in ``info`` (run.json) and leave its state in
    ``runs_dir``. Raises :class:`NotUp` when it does not come up (a LaunchError, Ctrl-C): then
    nothing of it is left running and its report is written."""
    from services.spec_check.run_report import fleet_end

    fleet = Fleet(run_dir, router, env=env)
    info.router = endpoint = fleet.endpoint  # tls/… when the router listens on TLS
    write_run_info(run_dir, info)
    session: zenoh.Session | None = None
    try:
        fleet.start_router()
        session = open_client(endpoint)
        fleet.start_recorder()
        fleet.wait_alive(session, ["recorder"], timeout=60)
        fleet.start_agents()
        waited = fleet.wait_alive(session, fleet.agents, timeout=120)
        served = start_faces(fleet, session, gateway, ros2)
    except (LaunchError, KeyboardInterrupt) as exc:
        if session is not None:
            session.close()
        fleet.stop()
        not_up = NotUp.of(exc)
        info.processes = fleet.pids()
        write_run_info(run_dir, info)
        fleet_end(run_dir, failure=not_up.why)
        raise not_up from None
    session.close()
    info.processes = fleet.pids()
    write_run_info(run_dir, info)
    write_state(runs_dir, FleetState(endpoint, str(run_dir), fleet.pids()))
    return Started(endpoint, waited, served)


def start_faces(
    fleet: Fleet, session: zenoh.Session, gateway: int | None, ros2: tuple[str, ...] | None
) -> str:
    """Start the ACL gateway on port ``gateway`` (None: none) and the ROS 2 face (``roco ros2``
    with the arguments ``ros2``; None: none) and wait for their tokens; the tail of `roco up`'s
    line that names them. Raises LaunchError."""
    served = ""
    if gateway is not None:
        fleet.start_gateway(gateway)
        fleet.wait_alive(session, [GATEWAY], timeout=60)
        served += f"; gateway http://127.0.0.1:{gateway}/acc"
    if ros2 is not None:
        fleet.start_ros2(ros2)
        fleet.wait_alive(session, [ROS2], timeout=60)
        served += f"; ROS 2 node /roco (roco ros2 {' '.join(ros2)})"
    return served
