"""The fleet on two hosts (docs/deploy.md, "Two hosts on one machine"): the brain (router,
recorder, a_km, a_pl, a_co, a_hi) and the robot (router, ag_ex, a_ta), each in its network
namespace (services/hosts/netns.py), joined only by their routers over the shaped link. Whatever
the specification, every agent but ag_ex and a_ta runs on the brain (:func:`placement`).

Every process talks to the router of its own host at ``tls/127.0.0.1:7447`` (its own
loopback). The routers mesh over mutual TLS with identities of their own (``router_brain``,
``router_robot``: certificates from the run's CA naming their link addresses), both apply the
ACL to their own clients, and trust each other (services/spec_check/acl.py ``with_routers``).
The robot's router connects to ``tls/<brain's link address>:7447``: the brain's router itself
where the link is shaped by netem, else the delaying relay in front of it (services/hosts/
relay.py). The operator (``roco send``/``status``, the tests) reaches the brain's router over
the uplink at :attr:`TwoHosts.endpoint`.
"""

from __future__ import annotations

import json
import os
import queue
import time
import uuid
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import msgspec
import zenoh

from services.deploy.deploy import issue_router
from services.fault import process
from services.fleet.launcher import Fleet, LaunchError
from services.hosts import link
from services.hosts.link import Shaping
from services.hosts.netns import HostPair, HostsError, netns_exec
from services.recorder.record import HOSTS_JSON, LINK_BYTES_JSONL
from services.runtime import keys
from services.runtime.faults import FaultEvent
from services.runtime.human import FINAL_REPORTS, HumanInput, HumanReport
from services.runtime.reports import follow_reports
from services.runtime.session import open_client
from services.security.context import register
from services.spec.model import load, spec_path
from shared.settings import ROUTER_PORT, Settings

PORT = ROUTER_PORT
ROBOT = ("ag_ex", "a_ta")
"""The robot's services (besides its router); every other agent and the recorder are the brain's."""
ROUTERS = ("router_brain", "router_robot")
"""The process names of the two hosts' routers."""
LEASE_MS = 30_000
"""The routers' transport lease: a link silent this long is given up (Zenoh's default: 10 s).
Longer than the partitions the mesh should ride out without its links being closed and its
liveliness tokens lost (docs/deploy.md)."""


def host_of(name: str) -> str:
    """``robot`` for ag_ex, a_ta and the robot's router, else ``brain``."""
    return "robot" if name in ROBOT or name in ("router_robot",) else "brain"


def placement(agents: Sequence[str]) -> dict[str, list[str]]:
    """The services besides the routers each host runs for a fleet of ``agents`` (its
    specification's, in start order): the recorder and the agents of :func:`host_of`."""
    return {host: [n for n in ("recorder", *agents) if host_of(n) == host] for host in ("brain", "robot")}


@dataclass
class TwoHosts:
    """Make the two hosts, shape the link, start the fleet on them (:meth:`start`); stop it and
    remove the hosts (:meth:`stop`, always safe to call). ``env``: extra environment of every
    process (ag_ex's pacing and scene)."""

    run_dir: Path
    shaping: Shaping = field(default_factory=Shaping)
    env: dict[str, str] = field(default_factory=dict)
    lease_ms: int = LEASE_MS
    pair: HostPair | None = None
    fleet: Fleet | None = None
    how: str = ""
    services: bool = True
    """False: the routers (and relay) only, no recorder or agents (benchmarks of the link)."""

    @property
    def endpoint(self) -> str:
        """Where the operator reaches the brain's router (over the uplink)."""
        assert self.pair is not None
        return f"tls/{self.pair.uplink_addr}:{PORT}"

    def start(self, timeout: float = 120.0) -> float:
        """Everything up; returns the seconds until every agent held its liveliness token.
        Raises HostsError or LaunchError (having stopped and removed what it made)."""
        try:
            return self._start(timeout)
        except BaseException:
            self.stop()
            raise

    def _start(self, timeout: float) -> float:
        spec = load(spec_path(self.env, os.environ))
        self.pair = pair = HostPair.create()
        brain, robot = pair.netns("brain"), pair.netns("robot")
        wrap = {
            n: netns_exec(robot if host_of(n) == "robot" else brain)
            for n in (*spec.launch_order, "recorder", "relay")
        }
        wrap["router_brain"], wrap["router_robot"] = netns_exec(brain), netns_exec(robot)
        local = f"tls/127.0.0.1:{PORT}"
        # each host's agents reach the others through the routers: a peer listens on its own
        # host's loopback, which the other host cannot reach (services/runtime/transport.py)
        env = {**self.env, Settings.env_name("links"): "router"}
        self.fleet = fleet = Fleet(self.run_dir, local, env=env, acl=True, tls=True, wrap=wrap)
        assert fleet.security is not None
        brain_link = pair.link_addr("brain")
        issue_router(fleet.security, spec, "router_brain", [], [brain_link, pair.uplink_addr])
        issue_router(fleet.security, spec, "router_robot", [], [pair.link_addr("robot")])
        register(self.endpoint, fleet.security)
        netem = link.netem_available(pair)
        self.how = link.shape(pair, self.shaping, netem=netem)
        link.record_shaping(self.run_dir, self.shaping, self.how)
        self._write_hosts(brain_link)
        router = ["-m", "services.runtime.router", "--lease-ms", str(self.lease_ms)]
        listen = [local, self.endpoint] + ([f"tls/{brain_link}:{PORT}"] if netem else [])
        fleet.start_service(
            "router_brain", [*router, "--identity", "router_brain", *_each("--listen", listen)]
        )
        if not netem:
            delay = ["--delay-ms", str(self.shaping.delay_ms), "--jitter-ms", str(self.shaping.jitter_ms)]
            relay = [
                "-m",
                "services.hosts.relay",
                "--listen",
                f"{brain_link}:{PORT}",
                "--to",
                f"127.0.0.1:{PORT}",
                "--count",
                str(self.run_dir / LINK_BYTES_JSONL),
            ]
            fleet.start_service("relay", [*relay, *delay])
        fleet.start_service("router_robot", [*router, "--identity", "router_robot", "--listen", local,
                                             "--connect", f"tls/{brain_link}:{PORT}"])  # fmt: skip
        session = self._operator(timeout=10.0)
        try:
            if not self.services:
                return 0.0
            fleet.start_recorder()
            fleet.wait_alive(session, ["recorder"], timeout=60)
            fleet.start_agents()
            return fleet.wait_alive(session, fleet.agents, timeout=timeout)
        finally:
            session.close()

    def _write_hosts(self, brain_link: str) -> None:
        """The run folder's ``hosts.json``: each host's namespace, addresses and processes, the
        link's devices and the routers' lease (what a reader of the run needs to place a log)."""
        assert self.pair is not None and self.fleet is not None
        p = self.pair
        placed = placement(self.fleet.agents)
        hosts = {
            host: {
                "netns": p.netns(host),
                "link_addr": p.link_addr(host),
                "link_dev": p.link_dev[host],
                "processes": [f"router_{host}", *placed[host]],
            }
            for host in ("brain", "robot")
        }
        hosts["brain"]["uplink_addr"] = p.uplink_addr
        doc = {"hosts": hosts, "operator_endpoint": self.endpoint, "mesh": f"tls/{brain_link}:{PORT}",
               "lease_ms": self.lease_ms}  # fmt: skip
        (self.run_dir / HOSTS_JSON).write_text(json.dumps(doc, indent=1))

    def _operator(self, timeout: float) -> zenoh.Session:
        """An operator session to the brain's router, retried until it listens."""
        assert self.fleet is not None
        deadline = time.monotonic() + timeout
        while True:
            self.fleet._check_alive(["router_brain", "router_robot", "relay"])
            try:
                return open_client(self.endpoint)
            except zenoh.ZError:
                if time.monotonic() > deadline:
                    raise LaunchError(f"the brain's router did not answer at {self.endpoint}") from None
                time.sleep(0.1)

    def say(
        self, text: str, on_progress: dict[str, Callable[[], object]] | None = None, timeout: float = 600.0
    ) -> HumanReport:
        """Say ``text`` to the brain's a_hi from the operator's side of the uplink (as ``roco
        send`` does) and return a_hi's final report. ``on_progress``: {text fragment:
        callable}, each called at the first report containing its fragment and then taken out
        of the dict (e.g. a partition at a step). Raises queue.Empty after ``timeout`` s."""
        session = open_client(self.endpoint)
        reports: queue.SimpleQueue[HumanReport] = queue.SimpleQueue()
        follow_reports(session, reports.put)  # also what a_hi said while the uplink was cut
        rid = uuid.uuid4().hex[:8]
        pending = on_progress if on_progress is not None else {}
        try:
            session.put(keys.HUMAN_IN, msgspec.json.encode(HumanInput(text=text, request_id=rid)))
            deadline = time.monotonic() + timeout
            while True:
                report = reports.get(timeout=max(0.1, deadline - time.monotonic()))
                for fragment in [f for f in pending if f in report.text]:
                    pending.pop(fragment)()
                if report.request_id == rid and report.kind in FINAL_REPORTS:
                    return report
        finally:
            session.close()

    def partition(self, seconds: float | None) -> None:
        """Cut the link (for ``seconds``, healed from a timer; None: until :meth:`heal`)."""
        assert self.pair is not None
        link.partition(self.pair, self.run_dir, seconds)

    def heal(self) -> None:
        assert self.pair is not None
        link.heal(self.pair, self.run_dir)

    def stop(self) -> None:
        """Stop every process (agents, recorder, relay, routers) and remove the hosts."""
        if self.fleet is not None:
            self.fleet.stop()
        if self.pair is not None:
            link.record_counters(self.pair, self.run_dir)
            self.pair.destroy()
        if self.fleet is not None:
            register(self.fleet.endpoint, None)
            if self.pair is not None:
                register(self.endpoint, None)

    def __enter__(self) -> TwoHosts:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


@dataclass
class TwoHostsHosting:
    """The two hosts as where a scenario runs (services/scenario/runner.py ``Hosting``;
    ``roco chaos --hosts``): :meth:`start_routers` makes the hosts, shapes the link and starts
    the routers (``TwoHosts`` without its services: the runner starts the recorder and the
    agents, each on its host by the fleet's ``wrap``); a router started again after a fault is
    back once the agents behind it are seen alive again from the operator's side."""

    hosts: TwoHosts

    @property
    def fleet(self) -> Fleet:
        if self.hosts.fleet is None:
            raise LaunchError("the two hosts are not up")
        return self.hosts.fleet

    @property
    def endpoint(self) -> str:
        return self.hosts.endpoint

    def start_routers(self) -> None:
        self.hosts.services = False
        try:
            self.hosts.start()
        except HostsError as exc:
            raise LaunchError(str(exc)) from None

    def start_again(self, session: zenoh.Session, service: str, timeout: float) -> FaultEvent:
        """Start ``service`` again on its host; wait until it (for the robot's router: ag_ex and
        a_ta; for the brain's: every agent and the recorder) holds its liveliness token as seen
        through the brain's router. Raises FaultError."""
        event = process.start(self.fleet, service, timeout, wait=False)
        behind = {
            "router_brain": ["recorder", *self.fleet.agents],  # the robot's through the mesh again
            "router_robot": list(ROBOT),
        }
        try:
            self.fleet.wait_alive(session, behind.get(service, [service]), timeout)
        except LaunchError as exc:
            raise process.FaultError(f"{service} started again, but {exc}") from None
        return event

    def host(self, service: str) -> str | None:
        return host_of(service)

    def partition(self, seconds: float | None) -> None:
        try:
            self.hosts.partition(seconds)
        except HostsError as exc:
            raise LaunchError(f"the link was not cut: {exc}") from None

    def heal(self) -> None:
        self.hosts.heal()

    def stop(self) -> None:
        self.hosts.stop()


def _each(flag: str, values: list[str]) -> list[str]:
    return [x for v in values for x in (flag, v)]
