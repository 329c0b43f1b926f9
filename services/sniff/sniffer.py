"""A terminal sniffer: live communicates as they cross Zenoh, in FIPA string form.

``roco sniff`` subscribes to every communicate key (``roco/fipa/**``, see
:mod:`services.runtime.keys`) through a Zenoh client session, decodes each payload
(:func:`shared.fipa_codec.decode`), keeps those that pass the filters and prints each as a
one-line header followed by the communicate in the FIPA SC00070 string form, one parameter a
line::

    14:03:21.418  C4  a_pl → a_km  (96 B)
    (query-ref
     :sender (agent-identifier :name a_pl)
     :receiver (set (agent-identifier :name a_km))
     :content "{\\"type\\":\\"object\\",\\"name\\":\\"jar\\"}"
     :language L_WM
     :encoding msgpack
     :protocol fipa-query
     :conversation-id q1)

The header holds the local wall time of arrival at the sniffer (ms), the channel, sender and
receiver named by the key (``roco/fipa/<channel>/<sender>/<receiver>``) and the payload size on
the wire (bytes of the msgpack communicate, as the traffic recorder counts them).

A communicate that crosses again byte for byte on the same key (a retransmission, answers
published again for a copy, a duplicate of the network; services/runtime/dedup.py) is shown as
one line, its header followed by ``copy of the communicate at HH:MM:SS.mmm``, and not counted
(the last :data:`COPIES_KEPT` communicates are remembered).

Like JADE's Sniffer, it is a passive observer: it sends nothing and no agent knows it is
there. It does not check communicates against the specification (``roco spec verify`` does
that on a recorded run).
"""

from __future__ import annotations

import queue
import threading
import time
from collections import OrderedDict
from collections.abc import Callable, Iterable
from collections.abc import Set as AbstractSet
from dataclasses import dataclass
from datetime import datetime

import zenoh

from services.runtime import keys
from services.runtime.dedup import wire_digest
from services.runtime.session import open_client
from services.spec.model import SystemSpec, default_spec, is_foreign
from shared.fipa_codec import Communicate, DecodeError, Performative, decode
from shared.fipa_codec.batch import unpack
from shared.fipa_codec.string_form import to_string

POLL_S = 0.1
"""How often (s) the sniffer looks at its ``stop`` event while no communicate arrives."""
COPIES_KEPT = 4096
"""Communicates remembered (their digests and times) to recognise a copy of one."""

_CONTROL = {c: f"\\x{c:02x}" for c in [*range(0x20), *range(0x7F, 0xA0)] if c != 0x0A}


@dataclass(frozen=True)
class Filters:
    """What the sniffer prints; a field that is None does not filter.

    agents: a communicate passes when one of them sends or receives it (the sender or receiver
    of its key, or of the communicate itself). channels: the channel of its key (``C1``..).
    performatives: its performative (FIPA SC00037 spelling, lower case). conversation: its
    ``:conversation-id``, exactly. All given filters must pass (and); values within one filter
    are alternatives (or).
    """

    agents: frozenset[str] | None = None
    channels: frozenset[str] | None = None
    performatives: frozenset[str] | None = None
    conversation: str | None = None

    def key_passes(self, channel: str, sender: str, receiver: str) -> bool:
        """Whether a payload on ``roco/fipa/<channel>/<sender>/<receiver>`` can pass: the
        channel filter, and the agent filter on the key's ends."""
        if self.channels is not None and channel not in self.channels:
            return False
        return self.agents is None or bool({sender, receiver} & self.agents)

    def passes(self, channel: str, sender: str, receiver: str, msg: Communicate) -> bool:
        """Whether communicate ``msg``, seen on the key with these parts, is printed."""
        if self.channels is not None and channel not in self.channels:
            return False
        if self.agents is not None:
            ends = {sender, receiver, *(r.name for r in msg.receiver)}
            if msg.sender is not None:
                ends.add(msg.sender.name)
            if not ends & self.agents:
                return False
        if self.performatives is not None and msg.performative.value not in self.performatives:
            return False
        return self.conversation is None or msg.conversation_id == self.conversation


def _chosen(
    kind: str, values: Iterable[str] | None, known: list[str], norm: Callable[[str], str], problems: list[str]
) -> frozenset[str] | None:
    """The ``known`` names ``values`` choose (compared after ``norm``), None when there are no
    values; the unknown ones are added to ``problems`` in one sentence."""
    values = list(values or ())
    if not values:
        return None
    by_norm = {norm(k): k for k in known}
    matches = [(v, by_norm.get(norm(v.strip()))) for v in values]
    unknown = [v for v, k in matches if k is None]
    if unknown:
        problems.append(_unknown(kind, unknown, known))
    return frozenset(k for _, k in matches if k is not None)


def _unknown(kind: str, unknown: list[str], known: list[str]) -> str:
    """The sentence naming the ``unknown`` values of ``kind`` and listing the ``known`` ones."""
    return (
        f"unknown {kind}{'s' if len(unknown) > 1 else ''} "
        f"{', '.join(repr(u) for u in unknown)} (known: {', '.join(known)})"
    )


def _chosen_agents(
    agents: Iterable[str] | None, spec: SystemSpec, problems: list[str]
) -> frozenset[str] | None:
    """The agents chosen: the specification's, and agents of other platforms (local@platform),
    which play its external role when it has one; unknown ones are added to ``problems``."""
    agents = list(agents or ())
    foreign = {a.strip() for a in agents if spec.externals and is_foreign(a.strip())}
    named = [a for a in agents if a.strip() not in foreign]
    chosen = _chosen("agent", named, [a.name for a in spec.agents], str, problems)
    if foreign:
        return frozenset(foreign | (chosen or set()))
    return chosen


def parse_filters(
    *,
    agents: Iterable[str] | None = None,
    channels: Iterable[str] | None = None,
    performatives: Iterable[str] | None = None,
    conversation: str | None = None,
    spec: SystemSpec | None = None,
) -> Filters:
    """Check and normalise the sniffer's filters (the CLI's repeated ``--agent``, ``--channel``,
    ``--performative`` and ``--conversation``); an empty or None collection does not filter.

    Performatives are read in any case (``QUERY-REF`` is ``query-ref``, as SC00070 reads
    keywords) and must be one of the 22 of FIPA SC00037; channels (``c4`` is ``C4``) and agents
    must be named in the specification (``spec``, default: the shipped Robot Companion one), or
    be agents of another platform (``local@platform``, e.g. ``da0@host:1099/JADE``) when it has
    an external role.
    Raises ValueError naming every unknown value and listing the known ones.
    """
    spec = spec or default_spec()
    problems: list[str] = []
    chosen_agents = _chosen_agents(agents, spec, problems)
    chosen_channels = _chosen("channel", channels, [c.name for c in spec.channels], str.upper, problems)
    chosen_performatives = _chosen(
        "performative", performatives, [p.value for p in Performative], str.lower, problems
    )
    if conversation is not None and not conversation.strip():
        problems.append("empty conversation-id")
    if problems:
        raise ValueError("; ".join(problems))
    return Filters(
        agents=chosen_agents,
        channels=chosen_channels,
        performatives=chosen_performatives,
        conversation=conversation,
    )


def _clock(t: float) -> str:
    """Local wall time ``HH:MM:SS.mmm`` of POSIX time ``t``."""
    return datetime.fromtimestamp(t).strftime("%H:%M:%S.%f")[:-3]


def header(t: float, channel: str, sender: str, receiver: str, size: int) -> str:
    """The header line of one payload: wall time, channel, sender → receiver, size in bytes."""
    return f"{_clock(t)}  {channel}  {sender} → {receiver}  ({size} B)"


def render(msg: Communicate, *, content: bool = True) -> str:
    """``msg`` in the FIPA SC00070 string form, one parameter a line.

    ``content`` True: the readable form (``to_string(human=True)``): ``:content`` is the content
    term decoded in its language and written as compact JSON (msgspec.json), other binary
    content as ``"<n bytes, base64 …>"``, and control characters other than line feeds are
    escaped as ``\\xNN`` so that they cannot drive the terminal; valid SC00070, but it does not
    parse back to ``msg``. ``content`` False: the exact string form (``to_string``), which
    :func:`shared.fipa_codec.string_form.parse` reads back to ``msg``; octets of
    byte-length-encoded strings (msgpack content) appear as the characters U+0000–U+00FF, one
    per octet, as they are.
    """
    if not content:
        return to_string(msg, pretty=True)
    return to_string(msg, pretty=True, human=True).translate(_CONTROL)


def _one_line(text: str, limit: int = 200) -> str:
    text = text.translate(_CONTROL).replace("\n", "\\n")
    return text if len(text) <= limit else text[: limit - 1] + "…"


def sniff(
    endpoint: str | zenoh.Session,
    *,
    agents: AbstractSet[str] | None,
    channels: AbstractSet[str] | None,
    performatives: AbstractSet[str] | None,
    conversation: str | None,
    out: Callable[[str], None],
    stop: threading.Event,
    content: bool = True,
    ready: threading.Event | None = None,
) -> int:
    """Print the communicates crossing the Zenoh router at ``endpoint`` until ``stop`` is set;
    returns the number of communicates printed. ``endpoint`` may be an open session instead
    (the operator's, ``roco sniff --credentials``), which is left open.

    Opens a client session (:func:`services.fleet.launcher.open_client`) and subscribes to
    ``roco/fipa/**``. The filters are those of :func:`parse_filters` (checked by it here, so a
    ValueError names an unknown agent, channel or performative); None or empty: no filter.
    Each communicate that passes is given to ``out`` as one string: the header line (local wall
    time of arrival, channel, sender → receiver of the key, payload bytes) and the string form
    of :func:`render`, one parameter a line. With ``content`` True (the default) the printed
    ``:content`` is the decoded content term as compact JSON, a readability choice: it is not
    what crossed the wire; ``content`` False (the CLI's ``--raw``) prints the exact SC00070
    string form, which parses back to the communicate.

    A payload that is not a communicate (or a key that is not ``roco/fipa/C/S/R``) is given to
    ``out`` as one line, ``<time>  <channel>  <sender> → <receiver>  (<n> B)  malformed
    payload: <reason>``, when the channel and agent filters pass on its key (it has no
    performative or conversation to filter on), and the sniffer goes on; such lines are not
    counted. ``out`` is called from the calling thread only. ``ready``, when given, is set once
    the subscription is declared. Raises zenoh.ZError when no router answers at ``endpoint``.
    """
    filters = parse_filters(
        agents=agents, channels=channels, performatives=performatives, conversation=conversation
    )
    samples: queue.SimpleQueue[tuple[float, str, bytes]] = queue.SimpleQueue()

    def on_sample(sample: zenoh.Sample) -> None:
        t, key = time.time(), str(sample.key_expr)
        for payload in unpack(sample.payload.to_bytes()):  # a batch: each communicate
            samples.put((t, key, payload))

    earlier: OrderedDict[bytes, float] = OrderedDict()  # digest of key and payload → first arrival
    own = isinstance(endpoint, str)
    session = open_client(endpoint) if isinstance(endpoint, str) else endpoint
    printed = 0
    try:
        session.declare_subscriber(keys.FIPA_ALL, on_sample)
        if ready is not None:
            ready.set()
        while not stop.is_set():
            try:
                t, key, payload = samples.get(timeout=POLL_S)
            except queue.Empty:
                continue
            line = _one(filters, t, key, payload, content, earlier)
            if line is None:
                continue
            text, is_communicate = line
            out(text)
            if is_communicate:
                printed += 1
    finally:
        if own:
            session.close()
    return printed


def _first_seen(
    earlier: OrderedDict[bytes, float] | None, t: float, key: str, payload: bytes
) -> float | None:
    """When the communicate ``key``, ``payload`` was first seen, if it is a copy (None: the
    first, now remembered in ``earlier``, which keeps at most :data:`COPIES_KEPT`; or no
    ``earlier``)."""
    if earlier is None:
        return None
    d = wire_digest(key, payload)
    first = earlier.get(d)
    if first is not None:
        return first
    earlier[d] = t
    if len(earlier) > COPIES_KEPT:
        earlier.popitem(last=False)
    return None


def _one(
    filters: Filters,
    t: float,
    key: str,
    payload: bytes,
    content: bool,
    earlier: OrderedDict[bytes, float] | None = None,
) -> tuple[str, bool] | None:
    """What to print for one sample (text, whether it is a counted communicate), or None.
    ``earlier``: digests of the communicates seen so far with their arrival times (updated
    here; at most :data:`COPIES_KEPT`), to show a copy as one line."""
    try:
        channel, sender, receiver = keys.parse_fipa_key(key)
    except ValueError:
        if filters.channels is not None or filters.agents is not None:
            return None
        return (
            f"{_clock(t)}  ?  {_one_line(key)}  ({len(payload)} B)  malformed key: not roco/fipa/C/S/R",
            False,
        )
    head = header(t, channel, sender, receiver, len(payload))
    try:
        msg = decode(payload)
    except DecodeError as exc:
        if not filters.key_passes(channel, sender, receiver):
            return None
        return f"{head}  malformed payload: {_one_line(exc.reason)}", False
    if not filters.passes(channel, sender, receiver, msg):
        return None
    first = _first_seen(earlier, t, key, payload)
    if first is not None:
        return f"{head}  copy of the communicate at {_clock(first)}", False
    try:
        body = render(msg, content=content)
    except ValueError as exc:  # a :protocol, reply-by or user parameter the string form cannot write
        return f"{head}  not printable in the string form: {_one_line(str(exc))}", False
    return f"{head}\n{body}", True
