"""What the router's access control refused: read from Zenoh's own log, counted and named.

Zenoh has no API that tells an application about a message its access control dropped, but its
ACL interceptor logs every decision (eclipse-zenoh 1.10.2, checked by experiment; target
:data:`ACL_TARGET`, level TRACE)::

    2026-11-22T22:01:09.924796Z TRACE rx-0 ThreadId(08) zenoh::net::routing::interceptor::
      access_control: 460cf6… on Interface(lo)+Username(a_pl)+Transport(Tcp)+460cf6… is
      unauthorized to Put (ingress) on roco/fipa/C1/a_pl/a_ta
    … access_control: Using cached result: 460cf6… is unauthorized to Put (ingress) on …

(one line each in the log; the second form once the key's decision is cached: it names the
session, not its subject), and at INFO a session whose credentials match no ACL subject ("…
did not match any configured ACL subject"). When a session declares a key expression, the
interceptor logs "ACL (ingress): caching permissions for `KEY` ..." and then, on the same
thread, its decision for each of the :data:`CACHED_KINDS` kinds of message on that key: those
lines decide nothing that was sent and are not refusals (they do name the session's identity).

The router process (services/runtime/refusal_watch.py) turns that target on and hands every line of
Zenoh's log to a :class:`RefusalLog`, which keeps the session → identity pairs, writes each
refusal to ``<run>/refusals.jsonl`` and counts them; the router answers ``roco/counters/ask``
with a :class:`RefusalReport` on ``roco/refusals/report/<router>`` (``roco status``).

An identity here is the user name the session authenticated with (user/password; with mutual TLS
the certificate's common name must match it, docs/security.md).
"""

from __future__ import annotations

import contextlib
import queue
import re
import threading
import time
from collections import Counter
from collections.abc import Iterator
from datetime import datetime
from pathlib import Path
from typing import IO, Any

import msgspec

ACL_TARGET = "zenoh::net::routing::interceptor::access_control"
"""The tracing target of Zenoh's ACL interceptor (zenoh/src/net/routing/interceptor/)."""
LINK_TARGETS = ("zenoh_link_tcp::unicast", "zenoh_link_tls::unicast")
"""Where Zenoh logs each connection it accepts (DEBUG, with the peer's address and, over TLS,
its certificate's common name) and a TLS handshake it refused (WARN)."""
ACCEPT_TARGET = "zenoh_transport::unicast::establishment::accept"
"""Where Zenoh logs a session it refused while authenticating it (DEBUG, user/password)."""
LOG_FILTER = ",".join([f"{ACL_TARGET}=trace", *(f"{t}=debug" for t in (*LINK_TARGETS, ACCEPT_TARGET))])
"""The directives (tracing EnvFilter syntax) that make Zenoh log every ACL decision, every
accepted connection and every session it refused to authenticate."""
REFUSALS_JSONL = "refusals.jsonl"
"""In a run folder: one :class:`Refusal` per line (JSON), in the order the router refused them."""
MAX_LINES = 100_000
"""Refusals written to :data:`REFUSALS_JSONL` per router life; beyond, they are only counted (a
flood of refused puts must not fill the disk); the report says how many were left out."""
MAX_NAMED = 64
"""Distinct (identity, message, flow, key) kept with counts and times; beyond, counted under
``refused.other``."""
REPORT_PREFIX = "roco/refusals/report"
"""Where a router answers ``roco/counters/ask``: ``roco/refusals/report/<router zid>``."""
REPORT_ALL = f"{REPORT_PREFIX}/*"
UNKNOWN = "?"
"""The identity of a session whose user name the log has not given (yet)."""

_ANSI = re.compile(r"\x1b\[[0-9;]*m")
_DECISION = re.compile(
    r"^(?P<time>\S+)\s.*?" + re.escape(ACL_TARGET) + r":\s+(?:Using cached result: )?"
    r"(?P<zid>[0-9a-f]+)(?: on (?P<subject>\S+))? is (?P<verdict>authorized|unauthorized) to "
    r"(?P<action>.+?) \((?P<flow>ingress|egress)\) on (?P<key>\S*)\s*$"
)
_NO_SUBJECT = re.compile(
    r"^(?P<time>\S+)\s.*?"
    + re.escape(ACL_TARGET)
    + r":\s+(?P<zid>[0-9a-f]+) did not match any configured ACL subject"
)
_CACHING = re.compile(
    re.escape(ACL_TARGET) + r":\s+ACL \((?:ingress|egress)\): caching permissions for `(?P<key>[^`]*)`"
)
_THREAD = re.compile(r"ThreadId\((\d+)\)")
CACHED_KINDS = 9
"""Decisions Zenoh computes ahead for a declared key expression (query, reply, put, delete,
subscriber, queryable, liveliness token, liveliness query, liveliness subscriber)."""
_ACCEPTED = re.compile(
    r"Accepted (?P<proto>TCP|TLS) connection on \S+: (?P<peer>\S+?)\.?"
    r"(?: Common Name: (?P<cn>[^.]*)\.)?\s*$"
)
_AUTH_FAILED = re.compile(
    r"UsrPwd extension - Recv \w+\. (?P<why>Invalid password|Invalid user|Expected extension)"
)
_BAD_CERT = re.compile(r"invalid peer certificate: (?P<why>[^.]+)")
_NO_CERT = re.compile(r"peer sent no certificates")
"""A TLS client that showed no certificate (mutual TLS requires one; zenoh_link_tls logs it at
WARN, with no address)."""
_ALERT = re.compile(r"received fatal alert: (?P<why>\w+)")
"""The peer ended the TLS handshake: it did not trust this router's certificate (a router or a
client of another CA; zenoh_link_tls logs it at WARN, with no address)."""
NO_CERTIFICATE = "no certificate"
"""Why a TLS client that showed no certificate was refused (the refusal's ``key``)."""
AUTH_REASONS = {
    "Invalid password": "wrong password",
    "Invalid user": "unknown user",
    "Expected extension": "no credentials",
}
"""Zenoh's words for a refused authentication (zenoh-transport usrpwd.rs) → roco's."""
_USER = re.compile(r"Username\(([^)]*)\)")
_COMMON_NAME = re.compile(r"CertCommonName\(([^)]*)\)")


class Refusal(msgspec.Struct, frozen=True, kw_only=True):
    """One message the router's access control dropped.

    t: when (POSIX s, the router's clock); identity: the session's authenticated user name
    (:data:`UNKNOWN` when the log has not named it); message: what was refused, lower case with
    ``_`` (``put``, ``delete``, ``query``, ``reply``, ``declare_subscriber``,
    ``declare_liveliness_token``, …; ``session`` for a session that matches no ACL subject and
    may therefore do nothing; ``authenticate`` for a session refused at the handshake, ``key``
    then saying why: ``no credentials``, ``wrong password``, ``unknown user``, ``bad
    certificate: <TLS error>``, ``no certificate`` (a TLS client that showed none), or
    ``handshake ended by the peer: <TLS alert> …`` when the peer (a router or client of another
    CA) did not trust this router's certificate); flow:
    ``ingress`` (what the client sent) or ``egress`` (what the
    router would have delivered to it); key: the key expression; session: the Zenoh id (hex; ""
    before a session exists); peer: the client's address, where Zenoh logged it (a refused
    authentication; a refused TLS handshake is logged without it)."""

    t: float
    identity: str
    message: str
    flow: str
    key: str
    session: str
    peer: str = ""


def _handshake(stamp: str, why: str) -> Refusal:
    """A TLS handshake refused at ``stamp`` (the log line's time), ``why`` as the key; the log
    names no identity, session or address for it."""
    return Refusal(
        t=_time(stamp), identity=UNKNOWN, message="authenticate", flow="ingress", key=why, session=""
    )


class NamedCount(msgspec.Struct, frozen=True, kw_only=True):
    """How often one identity was refused one message on one key, first and last (POSIX s)."""

    identity: str
    message: str
    flow: str
    key: str
    count: int
    first: float
    last: float


class RefusalReport(msgspec.Struct, frozen=True, kw_only=True):
    """A router's answer to ``roco/counters/ask``: its Zenoh id, when (POSIX s), its counters
    (``refused``, ``refused.ingress`` — what clients sent —, ``refused.egress`` — what it did not
    deliver —, ``refused.<message>``, ``refused.other``, ``refusals_not_written``) and the
    refusals named, most frequent first."""

    router: str
    time: float
    counters: dict[str, int]
    named: list[NamedCount]


def _message(action: str) -> str:
    """``Put`` → ``put``, ``Declare Liveliness Token`` → ``declare_liveliness_token``."""
    return action.strip().lower().replace("/", "_").replace(" ", "_")


def _time(stamp: str) -> float:
    try:
        return datetime.fromisoformat(stamp.replace("Z", "+00:00")).timestamp()
    except ValueError:
        return time.time()


class RefusalLog:
    """Reads Zenoh's log lines, keeps the refusals: :meth:`feed` one line at a time (thread
    safe). ``out``: a text file each refusal is appended to as a JSON line (flushed per
    line), or None."""

    def __init__(self, out: IO[str] | None = None) -> None:
        self._out = out
        self._lock = threading.Lock()
        self._identity: dict[str, str] = {}
        self._ahead: dict[str, tuple[str, int]] = {}  # thread → (key being cached, decisions left)
        self._peers: dict[str, tuple[str, str]] = {}  # accepting thread → (peer, TLS common name)
        self.counters: Counter[str] = Counter()
        self._named: dict[tuple[str, str, str, str], list[float]] = {}
        self._counts: Counter[tuple[str, str, str, str]] = Counter()
        self._written = 0
        self._enc = msgspec.json.Encoder()

    def feed(self, line: str) -> Refusal | None:
        """Take one line of Zenoh's log; returns the refusal it reports, else None (an allowed
        message, or a line of another target)."""
        if ACL_TARGET not in line:
            if ACCEPT_TARGET in line or any(t in line for t in LINK_TARGETS):
                return self._feed_link(_ANSI.sub("", line).strip())
            return None
        if " is authorized " in line and ("Using cached result" in line or not self._ahead):
            # the bulk: an allowed message (not a decision computed ahead, which is counted
            # down below); a session's identity is learnt from the lines computed ahead, or
            # from its refused message's own line
            return None
        line = _ANSI.sub("", line).strip()
        thread = _THREAD.search(line)
        tid = thread.group(1) if thread else ""
        caching = _CACHING.search(line)
        if caching is not None:
            self._ahead[tid] = (caching["key"], CACHED_KINDS)
            return None
        m = _DECISION.match(line)
        if m is None:
            n = _NO_SUBJECT.match(line)
            if n is None:
                return None
            refused = Refusal(
                t=_time(n["time"]),
                identity=UNKNOWN,
                message="session",
                flow="ingress",
                key="",
                session=n["zid"],
            )
            return self._add(refused)
        zid, subject = m["zid"], m["subject"]
        if subject:
            user = _USER.search(subject) or _COMMON_NAME.search(subject)
            if user is not None:
                with self._lock:
                    self._identity[zid] = user.group(1)
        ahead = self._ahead.get(tid)
        if ahead is not None and ahead[0] == m["key"] and "Using cached result" not in line:
            if ahead[1] <= 1:
                del self._ahead[tid]
            else:
                self._ahead[tid] = (ahead[0], ahead[1] - 1)
            return None  # computed ahead for a declared key, not a message
        if m["verdict"] == "authorized":
            return None
        with self._lock:
            identity = self._identity.get(zid, UNKNOWN)
        refusal = Refusal(
            t=_time(m["time"]),
            identity=identity,
            message=_message(m["action"]),
            flow=m["flow"],
            key=m["key"],
            session=zid,
        )
        return self._add(refusal)

    def _feed_link(self, line: str) -> Refusal | None:
        """A connection accepted (remembered per accepting thread: the refusal that follows on
        it names the peer), a session refused at authentication, or a TLS handshake refused."""
        thread = _THREAD.search(line)
        tid = thread.group(1) if thread else ""
        stamp = line.split(" ", 1)[0]
        accepted = _ACCEPTED.search(line)
        if accepted is not None:
            self._peers[tid] = (f"{accepted['proto'].lower()}/{accepted['peer']}", accepted["cn"] or "")
            return None
        failed = _AUTH_FAILED.search(line)
        if failed is not None and ACCEPT_TARGET in line:
            peer, cn = self._peers.pop(tid, ("", ""))
            why = AUTH_REASONS[failed["why"]]
            refused = Refusal(
                t=_time(stamp),
                identity=cn or UNKNOWN,
                message="authenticate",
                flow="ingress",
                key=why,
                session="",
                peer=peer,
            )
            return self._add(refused)
        bad = _BAD_CERT.search(line)
        if bad is not None:
            return self._add(_handshake(stamp, f"bad certificate: {bad['why']}"))
        if _NO_CERT.search(line) is not None:
            return self._add(_handshake(stamp, NO_CERTIFICATE))
        alert = _ALERT.search(line)
        if alert is not None:
            why = f"handshake ended by the peer: {alert['why']} (it does not trust our certificate)"
            return self._add(_handshake(stamp, why))
        return None

    def _add(self, r: Refusal) -> Refusal:
        what = (r.identity, r.message, r.flow, r.key)
        with self._lock:
            self.counters["refused"] += 1
            self.counters[f"refused.{r.flow}"] += 1
            self.counters[f"refused.{r.message}"] += 1
            if what in self._named or len(self._named) < MAX_NAMED:
                times = self._named.setdefault(what, [r.t, r.t])
                times[1] = r.t
                self._counts[what] += 1
            else:
                self.counters["refused.other"] += 1
            if self._out is not None:
                if self._written < MAX_LINES:
                    self._out.write(self._enc.encode(r).decode() + "\n")
                    self._out.flush()
                    self._written += 1
                else:
                    self.counters["refusals_not_written"] += 1
        return r

    def report(self, router: str, now: float) -> RefusalReport:
        """What this log counted, as the router's answer (:class:`RefusalReport`)."""
        with self._lock:
            named = [
                NamedCount(
                    identity=w[0],
                    message=w[1],
                    flow=w[2],
                    key=w[3],
                    count=n,
                    first=self._named[w][0],
                    last=self._named[w][1],
                )
                for w, n in self._counts.most_common()
            ]
            return RefusalReport(router=router, time=now, counters=dict(self.counters), named=named)


@contextlib.contextmanager
def collect_reports(session: Any, into: list[RefusalReport], grace: float = 0.3) -> Iterator[None]:
    """Gather the routers' :class:`RefusalReport` answers into ``into`` while the block runs
    (it puts ``roco/counters/ask``), waiting ``grace`` s after it for late ones (routers answer
    at once). ``session``: a :class:`zenoh.Session`. Malformed answers are skipped; a router
    answering twice is kept once (its last answer)."""
    got: queue.SimpleQueue[bytes] = queue.SimpleQueue()
    sub = session.declare_subscriber(REPORT_ALL, lambda s: got.put(s.payload.to_bytes()))
    try:
        yield
        time.sleep(grace)
    finally:
        sub.undeclare()
    dec = msgspec.json.Decoder(RefusalReport)
    latest: dict[str, RefusalReport] = {}
    while True:
        try:
            payload = got.get_nowait()
        except queue.Empty:
            break
        with contextlib.suppress(msgspec.DecodeError, msgspec.ValidationError):
            r = dec.decode(payload)
            latest[r.router] = r
    into.extend(latest.values())


def read_refusals(run_dir: Path) -> list[Refusal]:
    """The refusals a run's router wrote (none when it wrote no file); unreadable lines are
    skipped."""
    path = run_dir / REFUSALS_JSONL
    if not path.exists():
        return []
    dec = msgspec.json.Decoder(Refusal)
    out = []
    for line in path.read_bytes().splitlines():
        try:
            out.append(dec.decode(line))
        except msgspec.DecodeError:
            continue
    return out


def summary(report: RefusalReport, limit: int = 4) -> str:
    """One line: the messages clients sent that the router refused, the most frequent named,
    and how many it withheld from delivery (egress: in a fleet working as specified, the
    recorder's advanced subscriber's declarations, which agents are not told of)::

        refused 3: a_pl put roco/fipa/C1/a_pl/a_ta ×2 (last 22:01:09), …; withheld 20
    """
    sent = report.counters.get("refused.ingress", 0)
    withheld = report.counters.get("refused.egress", 0)
    parts = []
    named = [n for n in report.named if n.flow == "ingress"]
    for n in named[:limit]:
        when = datetime.fromtimestamp(n.last).astimezone().strftime("%H:%M:%S")
        if n.message == "authenticate":
            who = n.identity if n.identity != UNKNOWN else "a client"
            parts.append(f"{who} at authentication, {n.key} ×{n.count} (last {when})")
            continue
        key = f" {n.key}" if n.key else ""
        parts.append(f"{n.identity} {n.message}{key} ×{n.count} (last {when})")
    if len(named) > limit:
        parts.append(f"… {len(named) - limit} more")
    head = f"refused {sent}" + (": " + ", ".join(parts) if parts else "")
    return f"{head}; withheld {withheld}"
