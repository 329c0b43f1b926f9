"""Two hosts on one machine: Linux network namespaces joined by veth pairs (iproute2, as root).

    root namespace ──uplink──  brain  ══link══  robot

* ``brain`` and ``robot`` are namespaces ``roco-<tag>-brain`` and ``roco-<tag>-robot``, each with
  its own loopback; ``<tag>`` is 6 random hex digits, so parallel runs never share a name.
* ``link`` is the veth pair between them (the network a robot and its server share): the only
  path from one host to the other, which :mod:`services.hosts.link` shapes and cuts.
* ``uplink`` is a veth pair from the root namespace to ``brain`` (the operator's workstation on
  the brain's network): ``roco send``/``status`` and the tests reach the brain's router through
  it. The robot is not reachable from the root namespace (no forwarding, no route).

Every address is link-local (169.254.N.0/29, N chosen per run among the /24s the root namespace
does not use): the traffic never leaves the machine. Nothing but iproute2's ``ip`` is used.

Clean-up: :meth:`HostPair.destroy` ends whatever still runs in the two namespaces and deletes them
(which deletes the veths inside them, and with them their peers). A marker in
:data:`STATE_DIR` names the process that made the pair; :func:`sweep` deletes the pairs whose
maker has exited and in which nothing runs any more (a run that was killed), and every
:meth:`HostPair.create` sweeps first.
"""

from __future__ import annotations

import json
import os
import random
import re
import secrets
import shutil
import signal
import subprocess
import time
from dataclasses import asdict, dataclass
from pathlib import Path

from services.fleet.processes import running

STATE_DIR = Path("/run/roco-hosts")
"""One JSON marker per host pair made on this machine (``<tag>.json``)."""
PREFIX = "roco-"
HOSTS = ("brain", "robot")


class HostsError(RuntimeError):
    """The namespaces cannot be made here (not root, no iproute2) or an ``ip`` command failed."""


def unavailable(link: bool = True) -> str | None:
    """Why two hosts cannot be made on this machine, or None when they can: they need root and
    iproute2's ``ip`` (the namespaces), and with ``link`` nftables' ``nft`` (the link's shaping
    and cuts, :mod:`services.hosts.link`). The reason names the package to install."""
    if os.geteuid() != 0:
        return "network namespaces need root (ip netns add)"
    if shutil.which("ip") is None:
        return "iproute2's ip is not installed (apt-get install iproute2)"
    if link and shutil.which("nft") is None:
        return "nftables' nft is not installed (apt-get install nftables)"
    return None


def run_ip(*args: str, netns: str | None = None, check: bool = True) -> subprocess.CompletedProcess[str]:
    """``ip [-n NETNS] ARGS…``; raises HostsError with ip's message when it fails and ``check``."""
    cmd = ["ip", *(["-n", netns] if netns else []), *args]
    done = subprocess.run(cmd, capture_output=True, text=True, check=False)
    if check and done.returncode != 0:
        raise HostsError(f"{' '.join(cmd)}: {done.stderr.strip() or done.returncode}")
    return done


def netns_exec(netns: str) -> list[str]:
    """The command prefix that runs a program in ``netns`` (``ip netns exec`` execs it: the
    program keeps the PID that Popen returns)."""
    return ["ip", "netns", "exec", netns]


def _used_subnets() -> set[int]:
    out = run_ip("-4", "-o", "addr", "show", check=False).stdout
    return {int(m) for m in re.findall(r"inet 169\.254\.(\d+)\.", out)}


@dataclass(frozen=True)
class HostPair:
    """Two namespaces and their links. Addresses (all /29 of 169.254.``subnet``.0):
    uplink root .1 ↔ brain .2, link brain .5 ↔ robot .6."""

    tag: str
    subnet: int
    maker: int

    # ---- names ----
    def netns(self, host: str) -> str:
        """The namespace of ``host`` (``brain`` or ``robot``)."""
        return f"{PREFIX}{self.tag}-{host}"

    @property
    def link_dev(self) -> dict[str, str]:
        """The link's veth end in each host."""
        return {"brain": f"rk{self.tag}l", "robot": f"rk{self.tag}r"}

    @property
    def uplink_dev(self) -> tuple[str, str]:
        """The uplink's ends: (root namespace, brain)."""
        return f"rk{self.tag}u", f"rk{self.tag}b"

    def _addr(self, last: int) -> str:
        return f"169.254.{self.subnet}.{last}"

    @property
    def operator_addr(self) -> str:
        """The root namespace's address on the uplink."""
        return self._addr(1)

    @property
    def uplink_addr(self) -> str:
        """The brain's address on the uplink (where the operator reaches its router)."""
        return self._addr(2)

    def link_addr(self, host: str) -> str:
        """``host``'s address on the link."""
        return self._addr(5 if host == "brain" else 6)

    # ---- life ----
    @classmethod
    def create(cls) -> HostPair:
        """Make the two namespaces, the link and the uplink, with loopback up in each. Raises
        HostsError (after removing what it made) when a step fails."""
        why = unavailable()
        if why:
            raise HostsError(why)
        sweep()
        used = _used_subnets()
        free = [n for n in range(1, 255) if n not in used and n != 169]
        if not free:
            raise HostsError("no free /24 in 169.254.0.0/16 for the hosts' links")
        pair = cls(secrets.token_hex(3), random.choice(free), os.getpid())
        STATE_DIR.mkdir(parents=True, exist_ok=True)
        pair._marker().write_text(json.dumps(asdict(pair)))
        try:
            pair._build()
        except BaseException:
            pair.destroy()
            raise
        return pair

    def _build(self) -> None:
        brain, robot = self.netns("brain"), self.netns("robot")
        for ns in (brain, robot):
            run_ip("netns", "add", ns)
            run_ip("link", "set", "lo", "up", netns=ns)
        lb, lr = self.link_dev["brain"], self.link_dev["robot"]
        run_ip("link", "add", lb, "netns", brain, "type", "veth", "peer", "name", lr, "netns", robot)
        run_ip("addr", "add", f"{self.link_addr('brain')}/30", "dev", lb, netns=brain)
        run_ip("addr", "add", f"{self.link_addr('robot')}/30", "dev", lr, netns=robot)
        up_root, up_brain = self.uplink_dev
        run_ip("link", "add", up_root, "type", "veth", "peer", "name", up_brain, "netns", brain)
        run_ip("addr", "add", f"{self.operator_addr}/30", "dev", up_root)
        run_ip("addr", "add", f"{self.uplink_addr}/30", "dev", up_brain, netns=brain)
        for dev, ns in ((lb, brain), (lr, robot), (up_brain, brain)):
            run_ip("link", "set", dev, "up", netns=ns)
        run_ip("link", "set", up_root, "up")

    def _marker(self) -> Path:
        return STATE_DIR / f"{self.tag}.json"

    def pids(self) -> list[int]:
        """The processes running in either namespace."""
        found = []
        for host in HOSTS:
            out = run_ip("netns", "pids", self.netns(host), check=False).stdout
            found += [int(p) for p in out.split()]
        return found

    def exists(self) -> bool:
        names = run_ip("netns", "list", check=False).stdout
        return any(line.split()[0] in {self.netns(h) for h in HOSTS} for line in names.splitlines() if line)

    def destroy(self, grace_s: float = 5.0) -> None:
        """End what still runs in the namespaces (SIGTERM, SIGKILL after ``grace_s``), delete
        both (their veths go with them) and the uplink's root end, and the marker. Never
        raises for what is already gone."""
        end_processes(self.pids(), grace_s)
        for host in HOSTS:
            run_ip("netns", "del", self.netns(host), check=False)
        run_ip("link", "del", self.uplink_dev[0], check=False)
        self._marker().unlink(missing_ok=True)


def end_processes(pids: list[int], grace_s: float) -> None:
    """SIGTERM ``pids``, SIGKILL those still there after ``grace_s``."""
    for pid in pids:
        with _gone():
            os.kill(pid, signal.SIGTERM)
    deadline = time.monotonic() + grace_s
    alive = list(pids)
    while alive and time.monotonic() < deadline:
        time.sleep(0.05)
        alive = [p for p in alive if running(p)]
    for pid in alive:
        with _gone():
            os.kill(pid, signal.SIGKILL)


class _gone:
    def __enter__(self) -> None:
        return None

    def __exit__(self, kind: object, exc: object, tb: object) -> bool:
        return isinstance(exc, ProcessLookupError)


def load(tag: str) -> HostPair | None:
    """The host pair ``tag`` from its marker, None when there is none."""
    try:
        data = json.loads((STATE_DIR / f"{tag}.json").read_text())
        return HostPair(str(data["tag"]), int(data["subnet"]), int(data["maker"]))
    except (OSError, ValueError, KeyError, TypeError):
        return None


def sweep() -> list[str]:
    """Delete the host pairs left behind: their maker has exited and nothing runs in them, or
    their marker is gone (a namespace ``roco-<tag>-…`` with nothing in it). Returns their tags."""
    removed = []
    for tag in sorted(_tags()):
        pair = load(tag) or HostPair(tag, 0, 0)
        if _kept(pair):
            continue
        pair.destroy()
        removed.append(tag)
    return removed


def _tags() -> set[str]:
    """The tags of the host pairs there are: of the namespaces ``roco-<tag>-brain|robot``, and
    of the markers in :data:`STATE_DIR`."""
    names = [line.split()[0] for line in run_ip("netns", "list", check=False).stdout.splitlines() if line]
    tags = {m.group(1) for n in names if (m := re.fullmatch(rf"{PREFIX}([0-9a-f]{{6}})-(?:brain|robot)", n))}
    if STATE_DIR.is_dir():
        tags |= {p.stem for p in STATE_DIR.glob("*.json")}
    return tags


def _kept(pair: HostPair) -> bool:
    """Whether :func:`sweep` leaves ``pair``: its maker is alive, or it exited and something
    runs in it (a fleet of `roco hosts up` keeps running: `roco hosts down`)."""
    if pair.maker and running(pair.maker):
        return True
    return bool(pair.pids()) and bool(pair.maker)
