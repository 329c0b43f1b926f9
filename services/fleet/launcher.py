"""The local launcher: a Zenoh router, the traffic recorder and one OS process per agent.

Processes are started with ``subprocess`` (fork + immediate exec of a fresh interpreter, i.e.
spawn semantics: no Zenoh state is inherited; a child forked after a Zenoh session exists
hangs). Each process gets its
configuration through the environment (``services.runtime.main``). The launcher ends only the
processes it started, by their PID. The environment it gives them is kept in the run folder
(``launch_env.json``: every ``ROCO_*`` variable and the fleet's extra environment) so that a
service can be started again the same way later (``roco fault start``, services/fault/).

Access control is on by default (docs/security.md): a fleet issues fresh credentials and the
router's ACL into ``<run>/security/`` (~50 ms) before it starts anything, its processes get
``ROCO_SECURITY`` and authenticate as themselves, and the tools of this process find the folder
by the fleet's endpoint (services/security/context.py). ``ROCO_ACL=0`` (or ``Fleet(acl=False)``)
turns it off. With it, the router listens on mutual TLS (``tls/127.0.0.1:PORT``), and the
agents link to each other directly (services/runtime/transport.py, one hop); ``ROCO_TLS=0`` (or
``Fleet(tls=False)``) keeps user/password over TCP and every communicate through the router.
"""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path

import zenoh

from services.runtime.run_folder import LAUNCH_ENV
from services.runtime.session import alive_agents
from services.security.context import ENV_SECURITY, acl_on, register, tls_on
from services.spec.model import DEFAULT_SPEC, SystemSpec, default_spec, load, spec_path
from shared.settings import PREFIX, Settings
from velma.world.mode import WORLD_SERVICE, world_in_process

AGENT_ORDER = default_spec().launch_order
"""The order the Robot Companion's agents are started in: its specification's ``start_order``
(servers before their clients, a_hi last: it accepts the human's command). A fleet of another
specification starts its own (:attr:`Fleet.agents`)."""


GATEWAY = "gateway"  # services/gateway/bridge.py: GATEWAY
"""The ACL gateway's process name, which is also its identity (``roco gateway``)."""
ROS2 = "ros2"  # services/ros2/face.py: ROS2
"""The ROS 2 face's process name, which is also its identity (``roco ros2``)."""


class LaunchError(RuntimeError):
    """A process of the fleet did not start or did not come alive in time."""


class NotUp(Exception):
    """A fleet kept running (``roco up``, ``roco hosts up``) did not come up: ``why`` (its
    LaunchError's words, or "interrupted" by Ctrl-C), stopped, its report written."""

    def __init__(self, why: str, interrupted: bool) -> None:
        super().__init__(why)
        self.why = why
        self.interrupted = interrupted

    @classmethod
    def of(cls, exc: BaseException) -> NotUp:
        """The NotUp of what stopped the fleet coming up: ``exc``, a KeyboardInterrupt or not."""
        interrupted = isinstance(exc, KeyboardInterrupt)
        return cls("interrupted" if interrupted else str(exc), interrupted)


def free_port() -> int:
    """A TCP port on 127.0.0.1 that is free now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@dataclass
class Fleet:
    """A running set of processes: router (optional), recorder, agents.

    ``endpoint``: the router endpoint clients connect to; ``run_dir``: where logs and traffic
    go; ``env``: extra environment for every process (e.g. ``ROCO_REALTIME``); ``acl``: with
    authentication and access control (default: on unless ``ROCO_ACL=0``); ``tls``: with
    ``acl``, the router listens on mutual TLS (default: on unless ``ROCO_TLS=0``; a ``tcp/``
    endpoint becomes ``tls/`` on the same address). ``security``: the credentials folder, or None.
    """

    run_dir: Path
    endpoint: str
    env: dict[str, str] = field(default_factory=dict)
    processes: dict[str, subprocess.Popen[bytes]] = field(default_factory=dict)
    acl: bool = field(default_factory=acl_on)
    tls: bool = field(default_factory=tls_on)
    security: Path | None = None
    wrap: dict[str, list[str]] = field(default_factory=dict)
    """Command prefix per process name (e.g. ``ip netns exec NS`` for a process on another host
    of services/hosts/); a process not named runs as it is."""
    args: dict[str, list[str]] = field(default_factory=dict)
    """The interpreter arguments each process was started with (:meth:`respawn`)."""
    spec: Path = field(init=False)
    """The specification the fleet runs (``ROCO_SPEC`` of ``env``, else of this process, else
    the shipped one): every process is given it, and the run folder keeps it."""
    system: SystemSpec = field(init=False, repr=False)
    """The loaded :attr:`spec`. Raises SpecError from the constructor when it cannot be loaded."""

    def __post_init__(self) -> None:
        if self.tls and self.acl and self.endpoint.startswith("tcp/"):
            self.endpoint = "tls/" + self.endpoint.removeprefix("tcp/")
        self.env = dict(self.env)
        self.spec = spec_path(self.env, os.environ).resolve()
        self.env.update(spec_env(self.spec))  # the run folder's launch_env.json keeps it
        self.system = load(self.spec)
        if self.acl:
            from services.deploy.deploy import ensure

            self.security = ensure(self.run_dir / "security", self.system, tls=self.tls)
            register(self.endpoint, self.security)

    @property
    def agents(self) -> tuple[str, ...]:
        """The agents of :attr:`spec`, in the order they are started (``launch_order``)."""
        return self.system.launch_order

    def _environ(self) -> dict[str, str]:
        env = process_environ(self.run_dir, self.endpoint, self.env)
        if self.security is not None:
            env[ENV_SECURITY] = str(self.security)
        else:
            env.pop(ENV_SECURITY, None)
        return env

    def _spawn(self, name: str, args: list[str]) -> None:
        env = self._environ()
        save_launch_env(self.run_dir, env, self.env)
        self.args[name] = args
        self.processes[name] = spawn_process(self.run_dir, name, args, env, prefix=self.wrap.get(name, []))

    def start_service(self, name: str, args: list[str]) -> None:
        """Start ``python args…`` as process ``name`` of this fleet (its environment, its
        ``wrap``); used for services the fleet does not know, e.g. a second router."""
        self._spawn(name, args)

    def respawn(self, name: str) -> None:
        """Start process ``name`` again with the arguments it was first started with (e.g. a
        second router of services/hosts/ after a fault). Raises KeyError for a process this
        fleet never started."""
        self._spawn(name, self.args[name])

    def start_router(self, timeout: float = 10.0) -> None:
        """Start the embedded router on ``endpoint`` and wait until it accepts connections."""
        self._spawn("router", service_args("router", self.endpoint))
        host, port = self.endpoint.split("/", 1)[1].rsplit(":", 1)
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            self._check_alive(["router"])
            try:
                with socket.create_connection((host, int(port)), timeout=0.2):
                    return
            except OSError:
                time.sleep(0.05)
        raise LaunchError(f"router did not listen on {self.endpoint} within {timeout:.0f} s")

    def start_recorder(self) -> None:
        self._spawn("recorder", service_args("recorder", self.endpoint))

    def start_agents(self, names: Iterable[str] | None = None) -> None:
        """Start the agents ``names`` (None: :attr:`agents`), and before the agent that plays the
        robot (``role = "robot"``: ag_ex) the world process unless it runs or ``ROCO_WORLD=loop``
        (velma/world/mode.py): it outlives ag_ex's restarts. A system without a robot has no
        world process."""
        robot = self.system.playing("robot")
        for name in self.agents if names is None else names:
            if name == robot and world_in_process(self._environ()):
                world = self.processes.get(WORLD_SERVICE)
                if world is None or world.poll() is not None:
                    self._spawn(WORLD_SERVICE, service_args(WORLD_SERVICE, self.endpoint))
            self._spawn(name, service_args(name, self.endpoint))

    def start_gateway(self, port: int) -> None:
        """Start ``roco gateway`` (services/cli/gateway.py) on ``127.0.0.1:port`` for this
        fleet's router as process :data:`GATEWAY`: it authenticates as ``gateway`` when the
        fleet has access control and is stopped with the agents. Its liveliness token comes
        once it serves HTTP (:meth:`wait_alive`)."""
        self._spawn(
            GATEWAY, ["-m", "services.cli", "gateway", "--router", self.endpoint, "--port", str(port)]
        )

    def start_ros2(self, args: Iterable[str] = ("--all",)) -> None:
        """Start ``roco ros2 args…`` (services/cli/ros2.py) for this fleet's router as
        process :data:`ROS2`: it authenticates as ``ros2`` when the fleet has access control
        and is stopped with the agents. Its liveliness token comes once its node is declared
        (:meth:`wait_alive`)."""
        self._spawn(ROS2, ["-m", "services.cli", "ros2", "--router", self.endpoint, *args])

    def _check_alive(self, names: Iterable[str]) -> None:
        for name in names:
            proc = self.processes.get(name)
            if proc is not None and proc.poll() is not None:
                log = self.run_dir / "logs" / f"{name}.stderr"
                tail = log.read_text(errors="replace").strip().splitlines()[-1:] if log.exists() else []
                raise LaunchError(
                    f"{name} exited with code {proc.returncode}" + (f": {tail[0]}" if tail else "")
                )

    def wait_alive(self, session: zenoh.Session, names: Iterable[str], timeout: float = 60.0) -> float:
        """Block until every name in ``names`` has a liveliness token; returns seconds waited.
        Raises LaunchError naming the missing ones, or a process that exited."""
        wanted = set(names)
        t0 = time.monotonic()
        while True:
            alive = alive_agents(session)
            missing = wanted - alive
            if not missing:
                return time.monotonic() - t0
            self._check_alive(wanted)
            if time.monotonic() - t0 > timeout:
                raise LaunchError(f"not alive after {timeout:.0f} s: {', '.join(sorted(missing))}")
            time.sleep(0.1)

    def dead(self) -> list[str]:
        """Names of processes that have exited."""
        return [n for n, p in self.processes.items() if p.poll() is not None]

    def _stop_order(self) -> list[tuple[str, bool]]:
        """The processes in the order they are stopped (agents, the recorder, the routers), each
        with whether its end is awaited before the next (the recorder's and the routers')."""
        routers = [n for n in self.processes if n.startswith("router")]
        agents = [n for n in self.processes if n != "recorder" and n not in routers]
        return [(n, False) for n in agents] + [(n, True) for n in ("recorder", *routers)]

    def stop(self, timeout: float = 10.0) -> None:
        """SIGTERM every started process (agents first, router last), then SIGKILL stragglers."""
        for name, wait in self._stop_order():
            proc = self.processes.get(name)
            if proc is None or proc.poll() is not None:
                continue
            proc.send_signal(signal.SIGTERM)
            if wait:
                _wait(proc, timeout)
        deadline = time.monotonic() + timeout
        for proc in self.processes.values():
            _wait(proc, max(0.1, deadline - time.monotonic()))

    def stop_agents(self, timeout: float = 10.0) -> None:
        """SIGTERM every started agent of the specification, leaving the recorder, the routers
        and the rest (the world, a link's relay) running, and wait for their ends (SIGKILL
        after ``timeout`` s): what they sent is then all on its way to the recorder, and the
        record of a fleet whose agents never fall silent (a standing watch) can be read whole."""
        agents = [n for n in self.system.launch_order if n in self.processes]
        for name in agents:
            proc = self.processes[name]
            if proc.poll() is None:
                proc.send_signal(signal.SIGTERM)
        deadline = time.monotonic() + timeout
        for name in agents:
            _wait(self.processes[name], max(0.1, deadline - time.monotonic()))

    def restart(self, name: str, timeout: float = 10.0) -> int:
        """Stop process ``name`` (SIGTERM, then SIGKILL after ``timeout`` s) and start it again;
        returns the new PID. Raises KeyError for a process this fleet did not start."""
        proc = self.processes[name]
        if proc.poll() is None:
            proc.send_signal(signal.SIGTERM)
            _wait(proc, timeout)
        if name == "recorder":
            self.start_recorder()
        elif name == "router":
            raise LaunchError("the router is not restarted by a scenario")
        elif name == WORLD_SERVICE:
            raise LaunchError("the world is the robot's hardware: it is not restarted")
        else:
            self.start_agents([name])
        return self.processes[name].pid

    def pids(self) -> dict[str, int]:
        return {n: p.pid for n, p in self.processes.items()}


def spec_env(path: Path) -> dict[str, str]:
    """The environment that gives a fleet's processes the specification ``path``: ``ROCO_SPEC``,
    unless it is the shipped one (then nothing: a run folder then names no file of a checkout)."""
    if path.resolve() == DEFAULT_SPEC.resolve():
        return {}
    return {Settings.env_name("spec"): str(path.resolve())}


def process_environ(run_dir: Path, endpoint: str, extra: dict[str, str]) -> dict[str, str]:
    """The environment of a fleet's process: this one's, ``extra``, router and run folder."""
    env = dict(os.environ)
    env.update(extra)
    env[Settings.env_name("router")] = endpoint
    env[Settings.env_name("run_dir")] = str(run_dir)
    env.setdefault("PYTHONUNBUFFERED", "1")
    return env


def service_args(name: str, endpoint: str) -> list[str]:
    """The interpreter arguments that run service ``name`` of a local fleet."""
    if name == "router":
        return ["-m", "services.runtime.router", "--listen", endpoint]
    if name == "recorder":
        return ["-m", "services.recorder.recorder"]
    if name == WORLD_SERVICE:
        return ["-m", "velma.world"]
    return ["-m", "services.runtime.main", name]


def spawn_process(
    run_dir: Path, name: str, args: list[str], env: dict[str, str], *, prefix: list[str] | None = None
) -> subprocess.Popen[bytes]:
    """Start ``python args…`` (after the command ``prefix``, which must exec it) as service
    ``name`` in a session of its own (its PID is its process group), output appended to
    ``run_dir/logs/<name>.stderr``."""
    log = (run_dir / "logs" / f"{name}.stderr").open("ab")
    return subprocess.Popen(
        [*(prefix or []), sys.executable, *args],
        env=env,
        stdout=log,
        stderr=subprocess.STDOUT,
        stdin=subprocess.DEVNULL,
        start_new_session=True,
    )


def save_launch_env(run_dir: Path, env: dict[str, str], extra: dict[str, str]) -> None:
    """Record in ``run_dir/launch_env.json`` the part of ``env`` a fleet's process depends on:
    every ``ROCO_*`` variable, ``PYTHONUNBUFFERED`` and the fleet's ``extra`` environment."""
    kept = {k: v for k, v in env.items() if k.startswith(PREFIX) or k in extra or k == "PYTHONUNBUFFERED"}
    tmp = run_dir / (LAUNCH_ENV + ".tmp")
    tmp.write_text(json.dumps(kept, indent=1, sort_keys=True))
    tmp.replace(run_dir / LAUNCH_ENV)


def _wait(proc: subprocess.Popen[bytes], timeout: float) -> None:
    try:
        proc.wait(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()
