"""Process faults on a local fleet: kill, stop, start, pause, unpause, restart one service.

A fleet is either a :class:`~services.fleet.launcher.Fleet` this process started (``roco
run``, ``roco scenario``, tests; its ``processes`` are updated) or the fleet of ``roco up``,
known by its state file (:class:`UpFleet`; its PIDs are updated in ``runs/.fleet.json`` and
``run.json``). Every function returns the :class:`~services.runtime.faults.FaultEvent` it
applied (``agent="roco"``) and raises :class:`FaultError` (one line) when it cannot.

- ``kill``: SIGKILL to the service's process group (ag_ex's control-loop process included);
- ``stop``: SIGTERM to the service (and SIGCONT, should it be paused), SIGKILL to its group
  after ``timeout`` s;
- ``start``: start it again as the launcher did (same arguments, same environment: the run
  folder's ``launch_env.json``), then wait until it holds its liveliness token (the router:
  until it listens; the world: until it names a new link in the run folder);
- ``pause`` / ``unpause``: SIGSTOP / SIGCONT to its process group (like ``docker pause``:
  its liveliness token stays until the Zenoh lease, 10 s, expires);
- ``restart``: stop, then start.

The world (velma/world/, the robot's hardware side) is the robot's power: restarted, its
kitchen starts anew and its time from 0; ag_ex attaches to it by itself
(services/agents/executor/agent.py).

Only processes of the fleet are signalled, by PID: a PID whose command line is not the
service's (it ended and the PID was reused) counts as not running.
"""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
import time
from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any

import msgspec
import zenoh

from services.fleet.launcher import (
    Fleet,
    LaunchError,
    process_environ,
    service_args,
    spawn_process,
)
from services.fleet.processes import proc_state
from services.fleet_state import FLEET_FILE
from services.recorder import sync
from services.runtime.faults import FaultEvent
from services.runtime.run_folder import load_launch_env, read_run_info, spec_of_run, write_run_info
from services.runtime.session import alive_agents, open_client
from services.security.context import register
from services.spec.model import DEFAULT_SPEC, SpecError, SystemSpec, load
from velma.world.files import link_name
from velma.world.mode import WORLD_SERVICE

ACTIONS = ("kill", "stop", "start", "pause", "unpause", "restart")
INJECTOR = sync.INJECTOR
"""The ``agent`` of the fault events of ``roco fault`` and ``roco chaos``."""


class FaultError(RuntimeError):
    """A fault could not be applied; the message is one line for the person."""


def local_services(system: SystemSpec) -> tuple[str, ...]:
    """The services of a local fleet of ``system``: the router, the recorder, the world when an
    agent plays the robot (it runs unless ``ROCO_WORLD=loop``, velma/world/mode.py) and the
    agents in their start order (a compose deployment adds ``viewer``)."""
    world = (WORLD_SERVICE,) if system.playing("robot") is not None else ()
    return ("router", "recorder", *world, *system.launch_order)


@dataclass
class UpFleet:
    """The fleet of ``roco up``: its state file ``runs_dir/.fleet.json`` (``FleetState`` of
    services/fleet_state.py), router endpoint, run folder and PID per service."""

    runs_dir: Path
    endpoint: str
    run_dir: Path
    pids: dict[str, int]
    spec: Path | None = None
    """The specification the fleet runs (``--spec``); None: the one its run folder keeps
    (``launch_env.json``), else the shipped one."""

    def __post_init__(self) -> None:
        # the fleet's credentials (docs/security.md): this process's sessions to it use them
        if (self.run_dir / "security").is_dir():
            register(self.endpoint, self.run_dir / "security")

    @cached_property
    def system(self) -> SystemSpec:
        """The loaded :attr:`spec` (else the run folder's, else the shipped one); FaultError
        when it does not load."""
        try:
            return load(self.spec or spec_of_run(self.run_dir) or DEFAULT_SPEC)
        except SpecError as exc:
            raise FaultError(str(exc)) from None

    @property
    def agents(self) -> tuple[str, ...]:
        """The agents of :attr:`system`, in their start order."""
        return self.system.launch_order

    @classmethod
    def load(cls, runs_dir: Path, spec: Path | None = None) -> UpFleet:
        """The fleet up in ``runs_dir``, running ``spec`` (None: the one its run folder keeps);
        raises FaultError when no fleet is up there."""
        path = runs_dir / FLEET_FILE
        try:
            state = msgspec.json.decode(path.read_bytes())
            return cls(runs_dir, str(state["endpoint"]), Path(state["run_dir"]), dict(state["pids"]), spec)
        except FileNotFoundError:
            raise FaultError(
                f"no fleet is up (no {path}); start one with 'roco up' (a compose fleet: add --compose)"
            ) from None
        except (msgspec.DecodeError, KeyError, TypeError, ValueError) as exc:
            raise FaultError(f"{path} is unreadable: {exc}") from None

    @classmethod
    def from_state(cls, runs_dir: Path, state: Any) -> UpFleet:
        """From a ``FleetState`` of services/fleet_state.py (``endpoint``, ``run_dir``, ``pids``)
        already read from ``runs_dir``."""
        return cls(runs_dir, state.endpoint, Path(state.run_dir), dict(state.pids))

    def save(self) -> None:
        """Write the PIDs back into the state file (other fields kept) and ``run.json``."""
        path = self.runs_dir / FLEET_FILE
        state: dict[str, Any] = msgspec.json.decode(path.read_bytes())
        state["pids"] = dict(self.pids)
        tmp = path.with_name(path.name + ".tmp")
        tmp.write_bytes(msgspec.json.encode(state))
        tmp.replace(path)
        with contextlib.suppress(FileNotFoundError, msgspec.DecodeError):
            info = read_run_info(self.run_dir)
            info.processes = dict(self.pids)
            write_run_info(self.run_dir, info)


LocalFleet = Fleet | UpFleet


def _check_service(fleet: LocalFleet, service: str) -> None:
    if isinstance(fleet, Fleet) and service in fleet.processes:
        return  # e.g. the routers of the two hosts (services/hosts/fleet.py)
    known = local_services(fleet.system)
    if service not in known:
        raise FaultError(f"no service {service!r} in a local fleet (services: {', '.join(known)})")


def _cmdline(pid: int) -> list[str] | None:
    try:
        raw = Path(f"/proc/{pid}/cmdline").read_bytes()
    except OSError:
        return None
    return [a.decode(errors="replace") for a in raw.split(b"\0") if a]


def _reap(pid: int) -> None:
    """Collect ``pid``'s exit status if it is a child of this process that ended."""
    with contextlib.suppress(ChildProcessError, OSError):
        os.waitpid(pid, os.WNOHANG)


def is_service_process(pid: int, service: str, endpoint: str) -> bool:
    """``pid`` runs and its command line is the one the launcher gives ``service``."""
    _reap(pid)
    if proc_state(pid) in (None, "Z", "X"):
        return False
    cmd = _cmdline(pid)
    want = service_args(service, endpoint)
    return cmd is not None and cmd[-len(want) :] == want


def running_pid(fleet: LocalFleet, service: str) -> int | None:
    """The PID of ``service`` when it runs (paused included), else None."""
    _check_service(fleet, service)
    if isinstance(fleet, Fleet):
        proc = fleet.processes.get(service)
        return proc.pid if proc is not None and proc.poll() is None else None
    pid = fleet.pids.get(service)
    return pid if pid is not None and is_service_process(pid, service, fleet.endpoint) else None


def is_paused(fleet: LocalFleet, service: str) -> bool:
    pid = running_pid(fleet, service)
    return pid is not None and proc_state(pid) == "T"


def _require(fleet: LocalFleet, service: str) -> int:
    pid = running_pid(fleet, service)
    if pid is None:
        raise FaultError(f"{service} is not running")
    return pid


def _signal_group(pid: int, sig: signal.Signals) -> None:
    """``sig`` to the process group ``pid`` leads (the launcher starts every service in a
    session of its own), else to ``pid`` alone."""
    try:
        if os.getpgid(pid) == pid:
            os.killpg(pid, sig)
        else:
            os.kill(pid, sig)
    except ProcessLookupError:
        pass


def _gone(fleet: LocalFleet, service: str, pid: int) -> bool:
    if isinstance(fleet, Fleet):
        proc = fleet.processes.get(service)
        return proc is None or proc.pid != pid or proc.poll() is not None
    _reap(pid)
    return proc_state(pid) in (None, "Z", "X")


def _group_gone(pid: int) -> bool:
    try:
        os.killpg(pid, 0)
    except (ProcessLookupError, PermissionError):
        return True
    return False


def _wait_until(done: Callable[[], bool], timeout: float) -> bool:
    deadline = time.monotonic() + timeout
    while not done():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.02)
    return True


def _event(action: str, service: str, detail: str) -> FaultEvent:
    return FaultEvent(t=time.time(), agent=INJECTOR, kind=action, target=service, detail=detail)


def kill(fleet: LocalFleet, service: str, timeout: float = 10.0) -> FaultEvent:
    """SIGKILL ``service`` (its whole process group) and wait until it is gone."""
    pid = _require(fleet, service)
    _signal_group(pid, signal.SIGKILL)
    if not _wait_until(lambda: _gone(fleet, service, pid), timeout):
        raise FaultError(f"{service} (pid {pid}) still runs {timeout:.0f} s after SIGKILL")
    return _event("kill", service, f"pid {pid}")


def stop(fleet: LocalFleet, service: str, timeout: float = 10.0) -> FaultEvent:
    """SIGTERM ``service``, wait up to ``timeout`` s, then SIGKILL its process group."""
    pid = _require(fleet, service)
    with contextlib.suppress(ProcessLookupError):
        os.kill(pid, signal.SIGTERM)
    _signal_group(pid, signal.SIGCONT)  # a paused process must run to act on SIGTERM
    how = "SIGTERM"
    if not _wait_until(lambda: _gone(fleet, service, pid), timeout):
        _signal_group(pid, signal.SIGKILL)
        how = f"SIGKILL after {timeout:g} s"
        if not _wait_until(lambda: _gone(fleet, service, pid), timeout):
            raise FaultError(f"{service} (pid {pid}) still runs after SIGKILL")
    # what the service started itself (ag_ex's loop process) ends with it; SIGKILL stragglers
    if not _wait_until(lambda: _group_gone(pid), 2.0):
        _signal_group(pid, signal.SIGKILL)
    return _event("stop", service, f"pid {pid} ({how})")


def pause(fleet: LocalFleet, service: str) -> FaultEvent:
    """SIGSTOP ``service``'s process group."""
    pid = _require(fleet, service)
    _signal_group(pid, signal.SIGSTOP)
    _wait_until(lambda: proc_state(pid) in ("T", None), 5.0)
    return _event("pause", service, f"pid {pid}")


def unpause(fleet: LocalFleet, service: str) -> FaultEvent:
    """SIGCONT ``service``'s process group."""
    pid = _require(fleet, service)
    _signal_group(pid, signal.SIGCONT)
    _wait_until(lambda: proc_state(pid) != "T", 5.0)
    return _event("unpause", service, f"pid {pid}")


def _relaunch(fleet: Fleet, service: str, timeout: float) -> subprocess.Popen[bytes]:
    """Start ``service`` of the fleet this process launched, as its launcher does. Raises
    FaultError."""
    try:
        if service == "router":
            fleet.start_router(timeout)
        elif service == "recorder":
            fleet.start_recorder()
        elif service in fleet.agents:
            fleet.start_agents([service])
        else:
            fleet.respawn(service)
    except LaunchError as exc:
        raise FaultError(str(exc)) from None
    return fleet.processes[service]


def _respawn(fleet: UpFleet, service: str, timeout: float) -> subprocess.Popen[bytes]:
    """Start ``service`` of a fleet of `roco up` with its launch environment, noting its pid;
    the router: once it listens."""
    env = load_launch_env(fleet.run_dir) or process_environ(fleet.run_dir, fleet.endpoint, {})
    (fleet.run_dir / "logs").mkdir(parents=True, exist_ok=True)
    proc = spawn_process(fleet.run_dir, service, service_args(service, fleet.endpoint), env)
    fleet.pids[service] = proc.pid
    fleet.save()
    if service == "router":
        _wait_listening(fleet.endpoint, proc, timeout)
    return proc


def start(fleet: LocalFleet, service: str, timeout: float = 60.0, wait: bool = True) -> FaultEvent:
    """Start ``service`` again as the launcher did; with ``wait``, return once it holds its
    liveliness token (the router: once it listens). Raises FaultError when it runs already,
    exits, or does not come alive within ``timeout`` s."""
    old = running_pid(fleet, service)
    if old is not None:
        raise FaultError(f"{service} is running already (pid {old})")
    link_before = link_name(fleet.run_dir)  # a killed world leaves its link's name behind
    proc = (
        _relaunch(fleet, service, timeout) if isinstance(fleet, Fleet) else _respawn(fleet, service, timeout)
    )
    if wait and service == WORLD_SERVICE:
        _wait_world(fleet.run_dir, link_before, proc, timeout)
    elif wait and service != "router":
        _wait_alive(fleet.endpoint, service, proc, timeout)
    return _event("start", service, f"pid {proc.pid}")


def restart(fleet: LocalFleet, service: str, timeout: float = 60.0) -> FaultEvent:
    """Stop ``service`` (when it runs), then start it again."""
    before = stop(fleet, service, min(timeout, 10.0)).detail if running_pid(fleet, service) else "not running"
    after = start(fleet, service, timeout)
    return _event("restart", service, f"{before} → {after.detail}")


def apply(fleet: LocalFleet, action: str, service: str, timeout: float = 60.0) -> FaultEvent:
    """Apply process fault ``action`` (one of :data:`ACTIONS`) to ``service``."""
    if action == "kill":
        return kill(fleet, service, min(timeout, 10.0))
    if action == "stop":
        return stop(fleet, service, min(timeout, 10.0))
    if action == "start":
        return start(fleet, service, timeout)
    if action == "pause":
        return pause(fleet, service)
    if action == "unpause":
        return unpause(fleet, service)
    if action == "restart":
        return restart(fleet, service, timeout)
    raise FaultError(f"unknown process fault {action!r} (faults: {', '.join(ACTIONS)})")


def _wait_listening(endpoint: str, proc: subprocess.Popen[bytes], timeout: float) -> None:
    host, port = endpoint.split("/", 1)[1].rsplit(":", 1)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            raise FaultError(f"router exited with code {proc.returncode}")
        try:
            with socket.create_connection((host, int(port)), timeout=0.2):
                return
        except OSError:
            time.sleep(0.05)
    raise FaultError(f"router did not listen on {endpoint} within {timeout:.0f} s")


def _wait_world(run_dir: Path, before: str | None, proc: subprocess.Popen[bytes], timeout: float) -> None:
    """Wait until the world started as ``proc`` names its link in ``run_dir`` (another name than
    ``before``: velma/world/files.py ``link_name``). Raises FaultError when it exits first or
    names none within ``timeout`` s."""
    deadline = time.monotonic() + timeout
    while link_name(run_dir) in (None, before):
        if proc.poll() is not None:
            raise FaultError(f"{WORLD_SERVICE} exited with code {proc.returncode}")
        if time.monotonic() > deadline:
            raise FaultError(f"{WORLD_SERVICE} (pid {proc.pid}) named no link after {timeout:.0f} s")
        time.sleep(0.05)


def _wait_alive(endpoint: str, service: str, proc: subprocess.Popen[bytes], timeout: float) -> None:
    deadline = time.monotonic() + timeout
    try:
        session = open_client(endpoint)
    except zenoh.ZError:
        raise FaultError(f"{service} started (pid {proc.pid}) but no router answers at {endpoint}") from None
    try:
        while service not in alive_agents(session, timeout=0.5):
            if proc.poll() is not None:
                raise FaultError(f"{service} exited with code {proc.returncode}")
            if time.monotonic() > deadline:
                raise FaultError(f"{service} (pid {proc.pid}) not alive after {timeout:.0f} s")
            time.sleep(0.05)
    finally:
        session.close()


def record_events(session: zenoh.Session, events: list[FaultEvent], sync_timeout: float = 15.0) -> bool:
    """Have the traffic recorder write ``events`` (of agent :data:`INJECTOR`) to the run
    folder's ``faults.jsonl``; True once it confirmed they are written, False when it did not
    within ``sync_timeout`` s. The events travel inside the recorder's sync, sent again until
    answered (services/recorder/sync.py ``record``): a put of its own could be lost or
    overtaken by the sync (after a router restart both sessions reconnect in their own time)."""
    return sync.record(session, events, sync_timeout)
