"""The Zenoh router's access control, derived from the specification; default deny. The
manual, key by key per identity: docs/security.md "Who may send what where".

Each identity (an agent of the specification, the traffic ``recorder``, the ``gateway``, the
``operator``'s tools) gets exactly the key expressions it needs, per message kind and flow as
the router sees it (``ingress``: what the identity sends; ``egress``: what the router
delivers to it). Agent ``A`` puts only on ``roco/fipa/<C>/A/<peer>`` for its channels ``C``,
subscribes to its inbox ``roco/fipa/*/*/A`` and is delivered only ``roco/fipa/<C>/<peer>/A``;
holds only ``roco/alive/A``; has the fault layer's, the counters' and the clock's keys
(services/runtime/faults.py, services/runtime/clock.py), its advanced publishers' ``@adv``
keys below its own (services/runtime/transport.py), and the keys outside FIPA of the role it
plays (:func:`role_extras`: the person's, the robot's). A channel end that is an external
role (``x_fipa``) is keyed ``$*@$*`` (``keys.FOREIGN``: a chunk holding ``@``, as every
foreign name has and no roco agent's); only the ``gateway`` puts as a foreign agent. The
recorder hears ``roco/fipa/**`` and queries the publishers' caches; the operator hears
``roco/**`` but never puts on ``roco/fipa/**`` nor holds a liveliness token.

Zenoh (1.10) allows a message when an allow rule's key expression *includes* the message's key
expression (a subscriber on ``roco/fipa/**`` is not allowed by rules naming single channels).
Subjects: one per identity, by user name (usrpwd) and, with TLS, also by certificate common
name (both must match). Source of the schema: eclipse-zenoh DEFAULT_CONFIG.json5,
``access_control``.
"""

from __future__ import annotations

import re
from collections import defaultdict
from dataclasses import dataclass, field
from typing import Any, Literal

from services.runtime import keys
from services.runtime.acl_kinds import Message
from services.spec.model import SystemSpec

Flow = Literal["ingress", "egress"]

RECORDER = "recorder"  # services/recorder/recorder.py: RECORDER
OPERATOR = "operator"
"""The identity of the operator's tools (CLI, scenario runner, fault injector, tests)."""
GATEWAY = "gateway"  # services/gateway/bridge.py: GATEWAY
"""The identity of ``roco gateway``, which speaks for agents of other platforms."""
ROS2 = "ros2"  # services/ros2/face.py: ROS2
"""The identity of ``roco ros2``, which speaks for ROS 2 nodes (the external role of platform
``ros2``) and publishes the robot's state in rmw_zenoh's wire format."""
ROS2_SAYS = tuple(
    f"**/{t}/*"  # <domain>/<topic>/<DDS type>/<type hash>: no key of roco ends so
    for t in (
        "sensor_msgs::msg::dds_::JointState_",
        "tf2_msgs::msg::dds_::TFMessage_",
        "sensor_msgs::msg::dds_::Image_",
        "sensor_msgs::msg::dds_::CameraInfo_",
        "roco_msgs::msg::dds_::TaskState_",
        "roco_msgs::msg::dds_::SayProgress_",
    )
)
"""What ``roco ros2`` publishes (services/ros2/face.py)."""
ROS2_SERVES = "**/roco_msgs::srv::dds_::Say_/*"
"""The queryable of its sentence service (any type hash: a wrong one is refused and counted)."""
ROS2_TOKENS = "@ros2_lv/**"
"""Its node's and entities' liveliness tokens (rmw_zenoh's design document, "Graph Cache")."""
ROS2_PEER = "ros2_peer"
"""The identity of a ROS 2 session outside the fleet (rmw_zenoh_cpp or any ROS 2-over-Zenoh
client) that talks to ``roco ros2``'s node: it plays the external role of platform ``ros2``
only through that node, never on ``roco/**``."""
INJECTOR = "roco"  # services/fault/process.py: INJECTOR, the sender of process-fault events

_FAULT = "roco/fault"  # services/runtime/faults.py: FAULT_PREFIX
FAULT_CONTROL_ALL = f"{_FAULT}/control/all"


def _fault_control(agent: str) -> str:
    return f"{_FAULT}/control/{agent}"


def _fault_state(agent: str) -> str:
    return f"{_FAULT}/state/{agent}"


def _fault_event(agent: str) -> str:
    return f"{_FAULT}/event/{agent}"


@dataclass(frozen=True)
class Extras:
    """Non-FIPA keys of one agent: ``hears`` (subscribes to) and ``says`` (puts on)."""

    hears: tuple[str, ...] = ()
    says: tuple[str, ...] = ()


def role_extras(role: str, agent: str) -> Extras:
    """Receptors and effectors outside the FIPA channels of ``agent`` playing ``role``
    (services/spec/model.py ``ROLES``): the person's keys (services/runtime/person.py), the
    robot's state, clock and camera and the world's disturbances (services/agents/executor/
    agent.py). An agent without a role has none."""
    if role == "person":
        return Extras(hears=(keys.HUMAN_IN,), says=(keys.HUMAN_OUT,))
    if role == "robot":
        return Extras(
            hears=(keys.SIM_DISTURB,), says=(keys.state_key(agent), keys.SIM_CLOCK, keys.camera_key(agent))
        )
    return Extras()


@dataclass
class Grants:
    """What one identity may do: key expressions per (flow, message)."""

    identity: str
    allowed: dict[tuple[Flow, Message], list[str]] = field(default_factory=lambda: defaultdict(list))

    def allow(self, flow: Flow, message: Message, *key_exprs: str) -> None:
        for k in key_exprs:
            if k not in self.allowed[(flow, message)]:
                self.allowed[(flow, message)].append(k)

    def hear(self, *key_exprs: str) -> None:
        """Subscribe to ``key_exprs`` and be delivered what is put there."""
        self.allow("ingress", "declare_subscriber", *key_exprs)
        self.allow("egress", "put", *key_exprs)

    def say(self, *key_exprs: str) -> None:
        self.allow("ingress", "put", *key_exprs)

    def watch_alive(self) -> None:
        """Watch the white pages: liveliness subscriber on ``roco/alive/*`` and its tokens."""
        self.allow("ingress", "declare_liveliness_subscriber", keys.ALIVE_ALL)
        self.allow("egress", "liveliness_token", keys.ALIVE_ALL)

    def own_token(self, key: str) -> None:
        """Hold the liveliness token ``key`` and ask whether it is there (a liveliness query on
        that key alone: the health probe services/runtime/health.py, run in the identity's
        container, has its credentials only)."""
        self.allow("ingress", "liveliness_token", key)
        self.allow("ingress", "liveliness_query", key)
        self.allow("egress", "liveliness_token", key)

    def may(self, flow: Flow, message: Message, key: str) -> bool:
        """Whether a message on the concrete ``key`` is allowed (wildcards ``*`` and ``**`` in
        the granted expressions; a key with wildcards must be granted literally)."""
        return any(_includes(k, key) for k in self.allowed.get((flow, message), []))


def _chunk_includes(pattern: str, chunk: str) -> bool:
    """Whether a chunk of a key expression includes a concrete ``chunk``: ``*`` any chunk, a
    pattern with ``$*`` any characters there; wildcards never match a verbatim ``@`` chunk."""
    if pattern == chunk:
        return True
    if chunk.startswith("@") or chunk in ("*", "**"):
        return False
    if pattern == "*":
        return True
    if "$*" in pattern:
        return re.fullmatch(".*".join(re.escape(p) for p in pattern.split("$*")), chunk) is not None
    return False


def _includes(pattern: str, key: str) -> bool:
    """Whether key expression ``pattern`` includes ``key`` (chunks; ``*`` one, ``**`` any,
    ``$*`` any characters within a chunk)."""
    p, k = pattern.split("/"), key.split("/")

    def rec(i: int, j: int) -> bool:
        if i == len(p):
            return j == len(k)
        if p[i] == "**":
            return any(rec(i + 1, jj) for jj in range(j, len(k) + 1))
        if j == len(k):
            return False
        return _chunk_includes(p[i], k[j]) and rec(i + 1, j + 1)

    return rec(0, 0)


def channel_routes(spec: SystemSpec) -> list[tuple[str, str, str]]:
    """Every (channel, sender, receiver) the specification allows: both directions of each
    channel, in file order (an external role by its name, ``x_fipa``)."""
    routes = []
    for ch in spec.channels:
        a, b = ch.ends
        routes += [(ch.name, a, b), (ch.name, b, a)]
    return routes


def route_key(spec: SystemSpec, channel: str, sender: str, receiver: str) -> str:
    """The key expression of a route: :func:`keys.fipa_key`, with ``keys.FOREIGN`` for an
    external role's end (any foreign name plays it)."""
    platforms = {e.name: e.platform for e in spec.externals}

    def chunk(name: str) -> str:
        if name not in platforms:
            return keys.key_chunk(name)
        return f"$*@{keys.key_chunk(platforms[name])}" if platforms[name] else keys.FOREIGN

    return f"{keys.FIPA_PREFIX}{channel}/{chunk(sender)}/{chunk(receiver)}"


def agent_grants(spec: SystemSpec, agent: str) -> Grants:
    """The grants of ``agent``. Raises KeyError when the specification has no such agent."""
    role = next((a.role for a in spec.agents if a.name == agent), None)
    if role is None:
        raise KeyError(agent)
    g = Grants(agent)
    routes = channel_routes(spec)
    sends = [route_key(spec, c, s, r) for c, s, r in routes if s == agent]
    g.say(*sends)
    _cached_publisher(g, sends)
    g.allow("ingress", "declare_subscriber", keys.inbox_key(agent))
    g.allow("egress", "put", *(route_key(spec, c, s, r) for c, s, r in routes if r == agent))
    g.own_token(keys.alive_key(agent))
    g.watch_alive()
    g.hear(FAULT_CONTROL_ALL, _fault_control(agent))
    g.say(_fault_state(agent), _fault_event(agent))
    g.hear(keys.COUNTERS_ASK)  # roco status asks every agent for its counters
    g.hear(keys.SIM_CLOCK)  # the simulation's time its periodic behaviours run on (runtime/clock.py)
    g.say(keys.counters_key(agent))
    extra = role_extras(role, agent)
    g.hear(*extra.hears)
    g.say(*extra.says)
    if role == "robot":  # renders its camera only while a subscriber matches (the matching status)
        g.allow("egress", "declare_subscriber", keys.camera_key(agent))
    if keys.HUMAN_OUT in extra.says:
        _report_publisher(g)
        _answers(g, keys.HUMAN_OUTCOMES)  # the outcomes it told (a person's tool asks)
    return g


def _answers(g: Grants, key: str) -> None:
    """A queryable on ``key``: declare it, be asked, answer on ``key`` only."""
    g.allow("ingress", "declare_queryable", key)
    g.allow("egress", "query", key)
    g.allow("ingress", "reply", key)


def _asks(g: Grants, key: str) -> None:
    """Ask the queryable on ``key`` and hear its answers."""
    g.allow("ingress", "query", key)
    g.allow("egress", "reply", key)


def _report_publisher(g: Grants) -> None:
    """What a_hi's advanced publisher of reports needs (services/runtime/transport.py): to
    learn of the person's tools' subscribers, to declare its cache queryable, liveliness token
    and heartbeat below ``roco/human/out``, to hear their queries and to answer them."""
    g.allow("egress", "declare_subscriber", keys.HUMAN_OUT, keys.HUMAN_OUT_CACHES)
    g.allow("ingress", "declare_queryable", keys.HUMAN_OUT_CACHES)
    g.allow("ingress", "liveliness_token", keys.HUMAN_OUT_CACHES)
    g.say(keys.HUMAN_OUT_CACHES)
    g.allow("egress", "query", keys.HUMAN_OUT_CACHES)
    g.allow("ingress", "reply", keys.HUMAN_OUT, keys.HUMAN_OUT_CACHES)


def _cached_publisher(g: Grants, sends: list[str]) -> None:
    """What an agent's advanced publishers on its keys ``sends`` need (services/runtime/transport.py):
    to learn which subscribers match (a declared publisher that hears of none drops its puts),
    to declare their cache queryable, liveliness token and heartbeat below each key, to hear the
    recorder's queries and to answer them — with replies on its own keys only. It also learns
    of the recorder's subscriber to their heartbeats (below ``roco/fipa/**/@adv/``): a peer
    sends its heartbeats towards the router only once it knows someone there listens (a client
    sends everything to its router)."""
    g.allow("egress", "declare_subscriber", keys.FIPA_ALL, keys.FIPA_CACHES)
    caches = [keys.caches_of(k) for k in sends]
    g.allow("ingress", "declare_queryable", *caches)
    g.allow("ingress", "liveliness_token", *caches)
    g.say(*caches)
    g.allow("egress", "query", keys.FIPA_CACHES)
    g.allow("ingress", "reply", *sends, *caches)


def gateway_grants(spec: SystemSpec) -> Grants:
    """The grants of ``roco gateway`` (module docstring): it puts as any foreign agent to the
    agents the external roles have channels to, and hears only what those agents say to
    foreign agents."""
    g = Grants(GATEWAY)
    outside = tuple(e.name for e in spec.externals if not e.platform)
    routes = channel_routes(spec)
    sends = [route_key(spec, c, s, r) for c, s, r in routes if s in outside and r not in outside]
    g.say(*sends)
    _cached_publisher(g, sends)
    g.hear(*(route_key(spec, c, s, r) for c, s, r in routes if r in outside and s not in outside))
    g.own_token(keys.alive_key(GATEWAY))
    g.hear(keys.COUNTERS_ASK)
    g.say(keys.counters_key(GATEWAY))
    return g


def _speak_for(g: Grants, spec: SystemSpec, outside: tuple[str, ...]) -> None:
    """Put as the external roles ``outside`` to the agents they have channels to (with the
    advanced publishers' keys), hear what those agents say to them."""
    routes = channel_routes(spec)
    sends = [route_key(spec, c, s, r) for c, s, r in routes if s in outside and r not in outside]
    g.say(*sends)
    _cached_publisher(g, sends)
    g.hear(*(route_key(spec, c, s, r) for c, s, r in routes if r in outside and s not in outside))


def ros2_grants(spec: SystemSpec) -> Grants:
    """The grants of ``roco ros2``: it puts as any ``…@ros2`` caller to the agents the external
    role of platform ``ros2`` has channels to and hears what they say to such callers; hears
    ag_ex's state and camera images, the simulation's clock and a_ta's informs to a_co on C1
    (the task state it republishes); publishes :data:`ROS2_SAYS`, serves :data:`ROS2_SERVES`, holds
    :data:`ROS2_TOKENS` and its own ``roco/alive/ros2``."""
    g = Grants(ROS2)
    _speak_for(g, spec, tuple(e.name for e in spec.externals if e.platform == ROS2))
    g.hear(keys.state_key("ag_ex"), keys.SIM_CLOCK, keys.camera_key("ag_ex"))
    g.hear(*(route_key(spec, c, s, r) for c, s, r in channel_routes(spec) if (s, r) == ("a_ta", "a_co")))
    g.say(*ROS2_SAYS)
    # a publisher that hears of no subscriber drops its puts: it learns of ROS 2 sessions' ones
    g.allow("egress", "declare_subscriber", *ROS2_SAYS)
    _answers(g, ROS2_SERVES)
    g.allow("ingress", "liveliness_token", ROS2_TOKENS)
    g.own_token(keys.alive_key(ROS2))
    g.hear(keys.COUNTERS_ASK)
    g.say(keys.counters_key(ROS2))
    return g


def ros2_peer_grants(spec: SystemSpec) -> Grants:
    """The grants of :data:`ROS2_PEER`, the mirror of ``roco ros2``'s (:func:`ros2_grants`):
    subscribe to and be delivered what the face publishes (:data:`ROS2_SAYS`, any domain,
    namespace and type hash); query its sentence service (:data:`ROS2_SERVES`) and hear the
    replies, when the specification gives the external role of platform ``ros2`` a channel;
    declare, watch and query liveliness tokens under :data:`ROS2_TOKENS` (rmw_zenoh's graph:
    its own node's and entities' and the face's). Nothing under ``roco/``."""
    g = Grants(ROS2_PEER)
    g.hear(*ROS2_SAYS)
    roles = {e.name for e in spec.externals if e.platform == ROS2}
    if any(roles & set(ch.ends) for ch in spec.channels):
        _asks(g, ROS2_SERVES)
        g.allow("egress", "declare_queryable", ROS2_SERVES)  # a peer learns where to send a query
    g.allow("ingress", "liveliness_token", ROS2_TOKENS)
    g.allow("ingress", "declare_liveliness_subscriber", ROS2_TOKENS)
    g.allow("ingress", "liveliness_query", ROS2_TOKENS)
    g.allow("egress", "liveliness_token", ROS2_TOKENS)
    return g


def recorder_grants() -> Grants:
    g = Grants(RECORDER)
    g.hear(keys.FIPA_ALL, keys.RECORDER_SYNC, f"{_FAULT}/event/*")
    g.say(keys.RECORDER_SYNCED)
    # its advanced subscriber: heartbeats, late publishers' tokens, queries of their caches
    g.hear(keys.FIPA_CACHES)
    g.allow("ingress", "query", keys.FIPA_CACHES)
    g.allow("egress", "reply", keys.FIPA_ALL, keys.FIPA_CACHES)
    g.allow("ingress", "declare_liveliness_subscriber", keys.FIPA_CACHES)
    g.allow("ingress", "liveliness_query", keys.FIPA_CACHES)
    g.allow("egress", "liveliness_token", keys.FIPA_CACHES)
    g.own_token(keys.alive_key(RECORDER))
    # the processes' tokens for the run folder's presence record: those alive, then each change
    g.watch_alive()
    g.allow("ingress", "liveliness_query", keys.ALIVE_ALL)
    _answers(g, keys.RECORDER_FLAGS)  # the live requirement flags (roco status asks it)
    return g


def operator_grants() -> Grants:
    g = Grants(OPERATOR)
    g.hear(f"{keys.PREFIX}/**")
    g.say(
        keys.HUMAN_IN,
        keys.SIM_DISTURB,
        keys.RECORDER_SYNC,
        FAULT_CONTROL_ALL,
        f"{_FAULT}/control/*",
        _fault_event(INJECTOR),
        keys.COUNTERS_ASK,
    )
    g.watch_alive()
    g.allow("ingress", "liveliness_query", keys.ALIVE_ALL)
    # its advanced subscriber of a_hi's reports (services/runtime/reports.py): heartbeats,
    # a_hi's publisher's token, queries of its cache
    g.hear(keys.HUMAN_OUT_CACHES)
    g.allow("ingress", "query", keys.HUMAN_OUT_CACHES)
    g.allow("egress", "reply", keys.HUMAN_OUT, keys.HUMAN_OUT_CACHES)
    g.allow("ingress", "declare_liveliness_subscriber", keys.HUMAN_OUT_CACHES)
    g.allow("ingress", "liveliness_query", keys.HUMAN_OUT_CACHES)
    g.allow("egress", "liveliness_token", keys.HUMAN_OUT_CACHES)
    _asks(g, keys.RECORDER_FLAGS)  # the recorder's flags (roco status)
    _asks(g, keys.HUMAN_OUTCOMES)  # the outcomes a_hi told (roco send, the scenario runner)
    return g


def all_grants(spec: SystemSpec) -> list[Grants]:
    """The grants of every identity: the agents in file order, then recorder and operator, then
    the gateway when the specification has an external role without a platform, ``roco ros2``
    and the outside ROS 2 sessions (:data:`ROS2_PEER`) when it has one of platform ``ros2``."""
    gateway = [gateway_grants(spec)] if any(not e.platform for e in spec.externals) else []
    ros2 = (
        [ros2_grants(spec), ros2_peer_grants(spec)] if any(e.platform == ROS2 for e in spec.externals) else []
    )
    return [
        *(agent_grants(spec, a.name) for a in spec.agents),
        recorder_grants(),
        operator_grants(),
        *gateway,
        *ros2,
    ]


def identities(spec: SystemSpec) -> list[str]:
    """Every identity a deployment issues credentials to."""
    return [g.identity for g in all_grants(spec)]


def acl_config(spec: SystemSpec, *, tls: bool, only: set[str] | None = None) -> dict[str, Any]:
    """The router's ``access_control`` section (JSON-able): default deny, one rule per
    (identity, flow, message), one subject per identity (``usernames``, plus
    ``cert_common_names`` when ``tls``), one policy per identity. ``only`` restricts it to those
    identities (a revoked one is left out: it may then do nothing)."""
    rules: list[dict[str, Any]] = []
    subjects: list[dict[str, Any]] = []
    policies: list[dict[str, Any]] = []
    for g in all_grants(spec):
        if only is not None and g.identity not in only:
            continue
        ids = []
        for (flow, message), kes in g.allowed.items():
            if not kes:
                continue
            rid = f"{g.identity}/{flow}/{message}"
            rules.append(
                {
                    "id": rid,
                    "permission": "allow",
                    "flows": [flow],
                    "messages": [message],
                    "key_exprs": list(kes),
                }
            )
            ids.append(rid)
        subject: dict[str, Any] = {"id": g.identity, "usernames": [g.identity]}
        if tls:
            subject["cert_common_names"] = [g.identity]
        subjects.append(subject)
        policies.append({"id": g.identity, "rules": ids, "subjects": [g.identity]})
    return {
        "enabled": True,
        "default_permission": "deny",
        "rules": rules,
        "subjects": subjects,
        "policies": policies,
    }


def markdown_table(spec: SystemSpec) -> str:
    """Who may send what where, as a Markdown table (docs/security.md)."""
    names = {
        ("ingress", "put"): "puts on",
        ("ingress", "declare_subscriber"): "subscribes to",
        ("egress", "put"): "is delivered",
        ("ingress", "liveliness_token"): "liveliness token",
        ("ingress", "declare_liveliness_subscriber"): "watches liveliness",
        ("egress", "liveliness_token"): "sees tokens",
        ("ingress", "liveliness_query"): "queries liveliness",
    }
    lines = ["| identity | may | key expressions |", "|---|---|---|"]
    for g in all_grants(spec):
        for fm, kes in g.allowed.items():
            if kes:
                what = names.get(fm, f"{fm[1]} ({fm[0]})")
                lines.append(f"| {g.identity} | {what} | {', '.join(f'`{k}`' for k in kes)} |")
    return "\n".join(lines) + "\n"


def channel_table(spec: SystemSpec) -> str:
    """Per agent, the channels it may put on and be delivered on, and its other keys (Markdown;
    the summary of docs/security.md). Every agent also holds ``roco/alive/<agent>``, watches
    ``roco/alive/*`` and hears/answers the fault layer's keys."""
    routes = channel_routes(spec)
    lines = [
        "| agent | puts on (channel → receiver) | is delivered (channel ← sender) | other keys |",
        "|---|---|---|---|",
    ]
    for a in spec.agents:
        n = a.name
        out = ", ".join(f"{c} → {r}" for c, s, r in routes if s == n)
        into = ", ".join(f"{c} ← {s}" for c, s, r in routes if r == n)
        e = role_extras(a.role, n)
        other = "—"
        if e.hears or e.says:
            other = (
                f"hears {', '.join(f'`{k}`' for k in e.hears)}; says {', '.join(f'`{k}`' for k in e.says)}"
            )
        lines.append(f"| {n} | {out} | {into} | {other} |")
    return "\n".join(lines) + "\n"


ROUTER_PREFIX = "router_"
"""Identities of meshed routers (services/security/certs.py ``issue_router_identity``)."""
ROUTER_MESSAGES = (
    "put",
    "delete",
    "declare_subscriber",
    "query",
    "declare_queryable",
    "reply",
    "liveliness_token",
    "declare_liveliness_subscriber",
    "liveliness_query",
)

ROUTER_KEYS = ("**", "**/@adv/**")
"""What meshed routers pass each other: every key, and the keys below zenoh-ext's verbatim
``@adv`` chunk (advanced publishers' caches, liveliness tokens and heartbeats; the recorder's
advanced subscriber), which ``**`` does not match."""


def with_routers(acl: dict[str, Any], routers: list[str]) -> dict[str, Any]:
    """``acl`` with the meshed routers ``routers`` allowed every message both ways.

    A router of a mesh forwards its own clients' messages, which it has already checked against
    the same ACL (each router applies it to the clients connected to it), so the routers trust
    one another and nothing else: the subject matches by certificate common name only — the
    router a connection reaches presents a certificate but no user name, so a subject that also
    asked for one would match neither direction (measured with eclipse-zenoh 1.10: a put from
    the robot's host then never reached the brain's). A router whose certificate is not from the
    deployment's CA never gets a link at all (mutual TLS).

    The rule names :data:`ROUTER_KEYS`: ``**`` alone never matches zenoh-ext's verbatim
    ``@adv`` chunk, and with it only, each router withheld the advanced publishers' cache
    queryables and liveliness tokens from the other (seen in ``refusals.jsonl``: "withheld
    declare_queryable roco/fipa/C5/a_ta/ag_ex/@adv/pub/…"), so the brain's recorder could not
    fetch from a robot-side cache what a router's restart had kept from it."""
    if not routers:
        return acl
    rule = {
        "id": "routers",
        "permission": "allow",
        "flows": ["ingress", "egress"],
        "messages": list(ROUTER_MESSAGES),
        "key_exprs": list(ROUTER_KEYS),
    }
    return acl | {
        "rules": [*acl["rules"], rule],
        "subjects": [*acl["subjects"], {"id": "routers", "cert_common_names": sorted(routers)}],
        "policies": [*acl["policies"], {"id": "routers", "rules": ["routers"], "subjects": ["routers"]}],
    }
