"""The link between the two hosts (services/hosts/netns.py): its shaping and its cuts, and the
run folder's record of both (``link.jsonl``).

Shaping, per direction (what ``tc netem`` on both ends of a veth gives):

* where the kernel has ``sch_netem``: ``tc qdisc replace … netem delay D J loss L%`` on both
  ends of the link (preferred: delay, jitter and loss per packet, in the kernel);
* else (this project's VMs: no netem, only HTB/TBF): loss by nftables in the robot's namespace,
  ``numgen random mod 1000 < 10·L drop`` on the link's device in both directions, and the delay
  by the relay (services/hosts/relay.py) that the routers' link goes through.

A partition is an nftables table in the robot's namespace that drops everything on the link's
device both ways (a cable pulled in the middle: neither side is told, TCP retransmits into the
void); healing deletes the table. Both need only the robot's namespace: the machine's own
firewall is not touched.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import threading
import time
from dataclasses import asdict, dataclass
from pathlib import Path

from services.hosts.netns import HostPair, HostsError
from services.recorder.record import LINK_JSONL

SHAPE_TABLE = "roco_shape"
CUT_TABLE = "roco_cut"


@dataclass(frozen=True)
class Shaping:
    """One-way delay ``delay_ms`` ± ``jitter_ms`` (uniform) and packet loss ``loss_pct`` (%) on
    each direction of the link."""

    delay_ms: float = 0.0
    jitter_ms: float = 0.0
    loss_pct: float = 0.0

    def __post_init__(self) -> None:
        if self.delay_ms < 0 or self.jitter_ms < 0 or self.jitter_ms > self.delay_ms:
            raise ValueError(f"delay {self.delay_ms} ms ± {self.jitter_ms} ms: need 0 ≤ jitter ≤ delay")
        if not 0 <= self.loss_pct < 100:
            raise ValueError(f"loss {self.loss_pct} %: need 0 ≤ loss < 100")

    def __str__(self) -> str:
        return f"{self.delay_ms:g} ± {self.jitter_ms:g} ms, {self.loss_pct:g} % loss each way"


def _run(cmd: list[str], *, check: bool = True, stdin: str | None = None) -> subprocess.CompletedProcess[str]:
    done = subprocess.run(cmd, capture_output=True, text=True, input=stdin, check=False)
    if check and done.returncode != 0:
        raise HostsError(f"{' '.join(cmd)}: {done.stderr.strip() or done.returncode}")
    return done


def _nft(pair: HostPair, script: str, *, check: bool = True) -> None:
    if shutil.which("nft") is None:
        raise HostsError("nftables' nft is not installed (apt-get install nftables)")
    _run(["ip", "netns", "exec", pair.netns("robot"), "nft", "-f", "-"], stdin=script, check=check)


def netem_available(pair: HostPair) -> bool:
    """Whether this kernel has ``sch_netem`` (tried on the robot's end of the link)."""
    dev, ns = pair.link_dev["robot"], pair.netns("robot")
    tc = ["ip", "netns", "exec", ns, "tc", "qdisc"]
    if (
        shutil.which("tc") is None
        or _run([*tc, "add", "dev", dev, "root", "netem", "delay", "0ms"], check=False).returncode
    ):
        return False
    _run([*tc, "del", "dev", dev, "root"], check=False)
    return True


def shape(pair: HostPair, shaping: Shaping, *, netem: bool) -> str:
    """Put ``shaping`` on the link; with ``netem`` all of it by ``tc netem`` on both ends, else
    only the loss (nftables; the caller runs the relay for the delay). Returns how, in words."""
    if netem:
        for host in ("brain", "robot"):
            ns, dev = pair.netns(host), pair.link_dev[host]
            delay = ["delay", f"{shaping.delay_ms}ms", f"{shaping.jitter_ms}ms"]
            _run(["ip", "netns", "exec", ns, "tc", "qdisc", "replace", "dev", dev, "root", "netem", *delay,
                  "loss", f"{shaping.loss_pct}%"])  # fmt: skip
        return "tc netem"
    dev = pair.link_dev["robot"]
    per_mille = round(shaping.loss_pct * 10)
    _nft(pair, f"table inet {SHAPE_TABLE}\ndelete table inet {SHAPE_TABLE}\n", check=False)
    if per_mille:
        lose = f"numgen random mod 1000 < {per_mille}"
        _nft(
            pair,
            f"table inet {SHAPE_TABLE} {{\n"
            f" chain in {{ type filter hook input priority 0; iifname {dev} {lose} drop; }}\n"
            f" chain out {{ type filter hook output priority 0; oifname {dev} {lose} drop; }}\n"
            "}\n",
        )
    return "no netem here: loss by nftables, delay by a relay"


def cut(pair: HostPair) -> None:
    """Drop everything on the link, both ways, until :func:`mend`."""
    dev = pair.link_dev["robot"]
    _nft(
        pair,
        f"table inet {CUT_TABLE} {{\n"
        f" chain in {{ type filter hook input priority -10; iifname {dev} drop; }}\n"
        f" chain out {{ type filter hook output priority -10; oifname {dev} drop; }}\n"
        "}\n",
    )


def mend(pair: HostPair) -> None:
    """Undo :func:`cut` (nothing happens when the link is not cut)."""
    _nft(pair, f"table inet {CUT_TABLE}\ndelete table inet {CUT_TABLE}\n", check=False)


def is_cut(pair: HostPair) -> bool:
    done = _run(
        ["ip", "netns", "exec", pair.netns("robot"), "nft", "list", "table", "inet", CUT_TABLE], check=False
    )
    return done.returncode == 0


def record(run_dir: Path, event: str, **fields: object) -> None:
    """Append one event to ``run_dir/link.jsonl``."""
    with (run_dir / LINK_JSONL).open("a") as f:
        f.write(json.dumps({"t": time.time(), "event": event, **fields}) + "\n")


def record_counters(pair: HostPair, run_dir: Path) -> None:
    """Append the link device's counters to ``run_dir/link.jsonl`` (event ``counters``: bytes and
    packets the robot's end sent, ``tx_*``: robot → brain, and received, ``rx_*``: brain →
    robot, since the link was made: everything on the wire, TCP/IP headers and retransmissions
    included); nothing when the device is gone or ``ip`` cannot say."""
    dev, ns = pair.link_dev["robot"], pair.netns("robot")
    try:
        done = _run(["ip", "-n", ns, "-s", "-j", "link", "show", "dev", dev], check=False)
        stats = json.loads(done.stdout)[0]["stats64"]
        fields = {
            f"{way}_{what}": int(stats[way][what]) for way in ("tx", "rx") for what in ("bytes", "packets")
        }
    except (OSError, ValueError, LookupError, TypeError):
        return
    record(run_dir, "counters", device=dev, **fields)


def record_shaping(run_dir: Path, shaping: Shaping, how: str) -> None:
    record(run_dir, "shaping", **asdict(shaping), how=how)


def partition(pair: HostPair, run_dir: Path, seconds: float | None) -> threading.Timer | None:
    """Cut the link now (recorded ``down``); with ``seconds``, mend it that much later
    (recorded ``up``) from a timer thread, which is returned (cancel it and call :func:`heal` to
    mend earlier)."""
    cut(pair)
    record(run_dir, "down", seconds=seconds)
    if seconds is None:
        return None
    timer = threading.Timer(seconds, heal, (pair, run_dir))
    timer.daemon = True
    timer.start()
    return timer


def heal(pair: HostPair, run_dir: Path) -> None:
    """Mend the link (recorded ``up`` when it was cut)."""
    if is_cut(pair):
        mend(pair)
        record(run_dir, "up")
