"""The router's access control derived from the specification (services/spec_check/acl.py), checked
against the specification itself: every channel, both directions, every agent."""

from __future__ import annotations

import itertools

import pytest

from services.runtime import keys
from services.spec.model import DEFAULT_SPEC, SystemSpec, load
from services.spec_check.acl import (
    GATEWAY,
    OPERATOR,
    RECORDER,
    ROS2,
    ROS2_PEER,
    _includes,
    acl_config,
    agent_grants,
    all_grants,
    channel_routes,
    gateway_grants,
    identities,
    markdown_table,
    operator_grants,
    recorder_grants,
    ros2_grants,
    ros2_peer_grants,
    route_key,
)

JADE = "da0@host:1099/JADE"
"""A foreign agent's name: it plays the external role x_fipa."""
CALLER = "c000102030405060708090a0b0c0d0e0f@ros2"
"""A ROS 2 caller's name as roco ros2 puts it (services/ros2/face.py): it plays x_ros2."""


def key_of(spec: SystemSpec, channel: str, sender: str, receiver: str) -> str:
    """A concrete key of a route, a JADE-named agent standing for an external role."""

    def name(n: str) -> str:
        return {"x_fipa": JADE, "x_ros2": CALLER}.get(n, n)

    return keys.fipa_key(channel, name(sender), name(receiver))


@pytest.fixture(scope="module")
def spec() -> SystemSpec:
    return load(DEFAULT_SPEC)


def test_includes_follows_zenoh_wildcards() -> None:
    assert _includes("roco/fipa/**", "roco/fipa/C1/a_co/a_ta")
    assert _includes("roco/fipa/*/*/a_ta", "roco/fipa/C1/a_co/a_ta")
    assert not _includes("roco/fipa/*/*/a_ta", "roco/fipa/C1/a_ta/a_co")
    assert _includes("roco/**", "roco")
    assert not _includes("roco/fipa/C1/a_co/a_ta", "roco/fipa/*/*/a_ta")  # inclusion, not intersection
    foreign = f"roco/fipa/C8/{keys.FOREIGN}/a_hi"
    assert _includes(foreign, keys.fipa_key("C8", JADE, "a_hi"))
    assert not _includes(foreign, keys.fipa_key("C8", "a_co", "a_hi"))
    assert not _includes(foreign, "roco/fipa/C8/@x/a_hi")  # a verbatim chunk: no wildcard matches it


def test_every_route_is_put_by_its_sender_only_and_delivered_to_its_receiver_only(spec: SystemSpec) -> None:
    agents = [a.name for a in spec.agents]
    routes = channel_routes(spec)
    assert len(routes) == 2 * len(spec.channels)
    grants = {a: agent_grants(spec, a) for a in agents}
    for (channel, sender, receiver), agent in itertools.product(routes, agents):
        key = key_of(spec, channel, sender, receiver)
        assert grants[agent].may("ingress", "put", key) == (agent == sender), (key, agent)
        assert grants[agent].may("egress", "put", key) == (agent == receiver), (key, agent)


def test_no_agent_may_put_a_route_outside_the_spec_or_as_another(spec: SystemSpec) -> None:
    agents = [a.name for a in spec.agents]
    channels = [c.name for c in spec.channels]
    allowed = set(channel_routes(spec))
    for agent, channel, sender, receiver in itertools.product(agents, channels, agents, agents):
        key = keys.fipa_key(channel, sender, receiver)
        may = agent_grants(spec, agent).may("ingress", "put", key)
        assert may == (sender == agent and (channel, sender, receiver) in allowed), key
    # nothing but the channels: no wildcard puts, no made-up channel
    assert not agent_grants(spec, "a_pl").may("ingress", "put", "roco/fipa/C9/a_pl/a_km")


def test_each_agent_subscribes_to_its_inbox_and_holds_only_its_own_token(spec: SystemSpec) -> None:
    for a in spec.agents:
        g = agent_grants(spec, a.name)
        assert g.allowed[("ingress", "declare_subscriber")][0] == keys.inbox_key(a.name)
        assert not g.may("ingress", "declare_subscriber", keys.FIPA_ALL)
        own = [route_key(spec, c, s, r) for c, s, r in channel_routes(spec) if s == a.name]
        tokens = {keys.alive_key(a.name), *(keys.caches_of(k) for k in own)}
        if a.name == "a_hi":  # its reports' advanced publisher (services/runtime/transport.py)
            tokens.add(keys.HUMAN_OUT_CACHES)
        assert set(g.allowed[("ingress", "liveliness_token")]) == tokens
        assert g.allowed[("ingress", "declare_liveliness_subscriber")] == [keys.ALIVE_ALL]
        assert g.may("egress", "liveliness_token", keys.alive_key("a_co"))
        # its health check asks for its own token, and only for it
        assert g.allowed[("ingress", "liveliness_query")] == [keys.alive_key(a.name)]
        # the fault layer reaches it, and it answers as itself only
        assert g.may("egress", "put", "roco/fault/control/all")
        assert g.may("ingress", "put", f"roco/fault/state/{a.name}")
        assert not g.may("ingress", "put", "roco/fault/state/someone_else")


def test_extras_are_the_receptors_and_effectors_of_a_hi_and_ag_ex(spec: SystemSpec) -> None:
    assert (spec.playing("person"), spec.playing("robot")) == ("a_hi", "ag_ex")
    hi, ex, pl = agent_grants(spec, "a_hi"), agent_grants(spec, "ag_ex"), agent_grants(spec, "a_pl")
    assert hi.may("egress", "put", keys.HUMAN_IN) and hi.may("ingress", "put", keys.HUMAN_OUT)
    assert ex.may("ingress", "put", keys.state_key("ag_ex")) and ex.may("egress", "put", keys.SIM_DISTURB)
    assert not pl.may("ingress", "put", keys.HUMAN_OUT) and not pl.may("egress", "put", keys.HUMAN_IN)


def test_the_person_s_keys_follow_the_role_not_the_name(spec: SystemSpec) -> None:
    """A system whose interface agent is not named a_hi gets the person's keys for it."""
    import msgspec

    agents = tuple(
        msgspec.structs.replace(
            a, role="person" if a.name == "a_km" else "" if a.role == "person" else a.role
        )
        for a in spec.agents
    )
    moved = msgspec.structs.replace(spec, agents=agents)
    km, hi = agent_grants(moved, "a_km"), agent_grants(moved, "a_hi")
    assert km.may("egress", "put", keys.HUMAN_IN) and km.may("ingress", "put", keys.HUMAN_OUT)
    assert km.may("ingress", "declare_queryable", keys.HUMAN_OUTCOMES)
    assert not hi.may("egress", "put", keys.HUMAN_IN) and not hi.may("ingress", "put", keys.HUMAN_OUT)


def test_recorder_hears_all_traffic_and_sends_none(spec: SystemSpec) -> None:
    g = recorder_grants()
    assert g.may("ingress", "declare_subscriber", keys.FIPA_ALL)
    for c, s, r in channel_routes(spec):
        assert g.may("egress", "put", keys.fipa_key(c, s, r))
        assert not g.may("ingress", "put", keys.fipa_key(c, s, r))
    assert g.allowed[("ingress", "put")] == [keys.RECORDER_SYNCED]
    # it holds its own token only, and watches and asks for every process's (presence.jsonl)
    assert g.may("ingress", "liveliness_token", keys.alive_key("recorder"))
    assert not g.may("ingress", "liveliness_token", keys.alive_key("a_km"))
    assert g.may("ingress", "liveliness_query", keys.alive_key("a_km"))
    assert g.may("ingress", "declare_liveliness_subscriber", keys.ALIVE_ALL)


def test_operator_observes_and_commands_but_never_speaks_fipa(spec: SystemSpec) -> None:
    g = operator_grants()
    assert g.may("ingress", "declare_subscriber", keys.FIPA_ALL)
    assert g.may("ingress", "put", keys.HUMAN_IN) and g.may("ingress", "put", "roco/fault/control/a_pl")
    assert g.may("ingress", "liveliness_query", keys.ALIVE_ALL)
    for c, s, r in channel_routes(spec):
        assert not g.may("ingress", "put", key_of(spec, c, s, r))
    assert not g.allowed.get(("ingress", "liveliness_token"))
    assert not g.may("ingress", "put", keys.HUMAN_OUT)


@pytest.mark.parametrize(
    ("answerer", "key"), [("recorder", keys.RECORDER_FLAGS), ("a_hi", keys.HUMAN_OUTCOMES)]
)
def test_only_its_owner_answers_a_queryable_and_the_operator_asks(
    spec: SystemSpec, answerer: str, key: str
) -> None:
    """roco status asks the recorder for the live requirement flags (services/recorder/flags.py);
    roco send and the scenario runner ask a_hi for the outcomes it told
    (services/runtime/person.py). Nobody else declares the queryable or replies on
    its key."""
    identities = [agent_grants(spec, a.name) for a in spec.agents] + [recorder_grants()]
    owner = next(g for g in identities if g.identity == answerer)
    assert key in owner.allowed[("ingress", "declare_queryable")]
    assert owner.may("egress", "query", key) and owner.may("ingress", "reply", key)
    op = operator_grants()
    assert op.may("ingress", "query", key) and op.may("egress", "reply", key)
    assert not op.allowed.get(("ingress", "declare_queryable")) and not op.may("ingress", "reply", key)
    for g in identities:
        if g is not owner:
            assert not g.may("ingress", "declare_queryable", key), g.identity
            assert not g.may("ingress", "reply", key), g.identity


def test_acl_config_is_default_deny_with_one_subject_and_policy_per_identity(spec: SystemSpec) -> None:
    names = identities(spec)
    assert names == [*(a.name for a in spec.agents), RECORDER, OPERATOR, GATEWAY, ROS2, ROS2_PEER]
    for tls in (False, True):
        conf = acl_config(spec, tls=tls)
        assert conf["enabled"] is True and conf["default_permission"] == "deny"
        assert [s["id"] for s in conf["subjects"]] == names
        for s in conf["subjects"]:
            assert s["usernames"] == [s["id"]]
            assert s.get("cert_common_names") == ([s["id"]] if tls else None)
        rule_ids = {r["id"] for r in conf["rules"]}
        assert len(rule_ids) == len(conf["rules"])
        for p in conf["policies"]:
            assert p["subjects"] == [p["id"]] and set(p["rules"]) <= rule_ids
            assert all(r.startswith(f"{p['id']}/") for r in p["rules"])
        for r in conf["rules"]:
            assert r["permission"] == "allow" and len(r["flows"]) == 1 and r["key_exprs"]


def test_only_leaves_a_revoked_identity_without_subject(spec: SystemSpec) -> None:
    conf = acl_config(spec, tls=True, only={"a_co", "recorder"})
    assert [s["id"] for s in conf["subjects"]] == ["a_co", "recorder"]
    assert all(r["id"].split("/")[0] in ("a_co", "recorder") for r in conf["rules"])


def test_table_names_every_identity(spec: SystemSpec) -> None:
    table = markdown_table(spec)
    for g in all_grants(spec):
        assert f"| {g.identity} | puts on |" in table or g.identity in (OPERATOR, ROS2_PEER)
        assert f"| {g.identity} | subscribes to |" in table
    assert "`roco/fipa/C4/a_pl/a_km`" in table


def test_advanced_publishers_answer_cache_queries_only_with_their_own_communicates(spec: SystemSpec) -> None:
    """an agent's publisher caches answer the recorder's queries, on its own keys only."""
    pl = agent_grants(spec, "a_pl")
    mine, other = keys.fipa_key("C4", "a_pl", "a_km"), keys.fipa_key("C4", "a_km", "a_pl")
    assert pl.may("ingress", "reply", mine) and not pl.may("ingress", "reply", other)
    assert pl.may("ingress", "declare_queryable", f"{mine}/@adv/pub/z/7/_")
    assert not pl.may("ingress", "declare_queryable", f"{other}/@adv/pub/z/7/_")
    assert not pl.may("ingress", "put", f"{other}/@adv/pub/z/7/_")
    assert pl.may("egress", "query", keys.FIPA_CACHES)
    rec = recorder_grants()
    assert rec.may("ingress", "query", keys.FIPA_CACHES) and rec.may("egress", "reply", mine)
    assert not rec.may("ingress", "put", mine)


def test_the_gateway_speaks_only_as_foreign_agents_on_their_channels(spec: SystemSpec) -> None:
    """the gateway puts as any foreign agent (local@platform) to a_hi on C8 and hears
    a_hi's answers to them; nothing else, and it cannot pose as one of roco's agents."""
    g = gateway_grants(spec)
    assert g.may("ingress", "put", keys.fipa_key("C8", JADE, "a_hi"))
    assert g.may("ingress", "put", keys.fipa_key("C8", "ams@other:1099/JADE", "a_hi"))
    assert not g.may("ingress", "put", keys.fipa_key("C8", "a_co", "a_hi"))  # no @: a roco agent
    assert not g.may("ingress", "put", keys.fipa_key("C2", JADE, "a_co"))
    assert not g.may("ingress", "put", keys.fipa_key("C8", JADE, "a_co"))
    assert g.may("egress", "put", keys.fipa_key("C8", "a_hi", JADE))
    assert not g.may("egress", "put", keys.fipa_key("C2", "a_hi", "a_co"))
    assert not g.may("egress", "put", keys.fipa_key("C8", "a_hi", "a_co"))
    assert g.may("ingress", "liveliness_token", keys.alive_key(GATEWAY))
    assert not g.may("ingress", "liveliness_token", keys.alive_key("a_hi"))
    hi = agent_grants(spec, "a_hi")  # a_hi answers foreign agents only, on C8
    assert hi.may("ingress", "put", keys.fipa_key("C8", "a_hi", JADE))
    assert not hi.may("ingress", "put", keys.fipa_key("C8", "a_hi", "a_co"))
    assert hi.may("egress", "put", keys.fipa_key("C8", JADE, "a_hi"))
    assert not hi.may("egress", "put", keys.fipa_key("C8", "a_co", "a_hi"))


def test_roco_ros2_speaks_only_as_ros2_callers_to_a_hi_on_c9(spec: SystemSpec) -> None:
    """roco ros2 puts as any …@ros2 caller to a_hi on C9 and hears a_hi's answers to them; it
    cannot speak on C8 (the gateway's), as a JADE agent or as a roco agent; it hears ag_ex's
    state and a_ta's informs to a_co, publishes only its ROS 2 types under their DDS names and
    holds only its own tokens. The gateway cannot speak as a ROS 2 caller on C9."""
    g = ros2_grants(spec)
    assert g.may("ingress", "put", keys.fipa_key("C9", CALLER, "a_hi"))
    assert not g.may("ingress", "put", keys.fipa_key("C8", CALLER, "a_hi"))
    assert not g.may("ingress", "put", keys.fipa_key("C9", JADE, "a_hi"))
    assert not g.may("ingress", "put", keys.fipa_key("C9", "a_co", "a_hi"))
    assert not g.may("ingress", "put", keys.fipa_key("C2", "a_hi", "a_co"))
    assert g.may("egress", "put", keys.fipa_key("C9", "a_hi", CALLER))
    assert not g.may("egress", "put", keys.fipa_key("C8", "a_hi", JADE))
    assert g.may("egress", "put", keys.state_key("ag_ex")) and g.may(
        "egress", "put", keys.fipa_key("C1", "a_ta", "a_co")
    )
    assert not g.may("egress", "put", keys.fipa_key("C1", "a_co", "a_ta"))
    joint = "0/joint_states/sensor_msgs::msg::dds_::JointState_/RIHS01_a13e"
    assert g.may("ingress", "put", joint) and g.may("ingress", "put", "3/robot1/" + joint[2:])
    assert not g.may("ingress", "put", "roco/fipa/C9/a_hi/x") and not g.may("ingress", "put", keys.HUMAN_IN)
    assert g.may("ingress", "declare_queryable", "0/roco/say/roco_msgs::srv::dds_::Say_/*")
    assert g.may("ingress", "liveliness_token", "@ros2_lv/0/zid/0/0/NN/%/%/roco")
    assert g.may("ingress", "liveliness_token", keys.alive_key(ROS2))
    assert not g.may("ingress", "liveliness_token", keys.alive_key("a_hi"))
    assert not gateway_grants(spec).may("ingress", "put", keys.fipa_key("C9", CALLER, "a_hi"))
    hi = agent_grants(spec, "a_hi")
    assert hi.may("egress", "put", keys.fipa_key("C9", CALLER, "a_hi"))
    assert hi.may("ingress", "put", keys.fipa_key("C9", "a_hi", CALLER))
    assert not hi.may("ingress", "put", keys.fipa_key("C9", "a_hi", JADE))


def test_a_ros2_peer_reaches_only_the_faces_topics_service_and_graph(spec: SystemSpec) -> None:
    """an outside ROS 2 session (ros2_peer) subscribes to what roco ros2 publishes, in any
    domain and namespace, calls roco/say, holds, watches and asks for rmw_zenoh's liveliness
    tokens, and does nothing on roco/**: it speaks to a_hi only through the face."""
    g = ros2_peer_grants(spec)
    face = ros2_grants(spec)
    joint = "0/joint_states/sensor_msgs::msg::dds_::JointState_/RIHS01_a13e"
    say = "0/roco/say/roco_msgs::srv::dds_::Say_/RIHS01_0f"
    for key in (
        joint,
        "3/kitchen/" + joint[2:],
        "0/roco/task_state/roco_msgs::msg::dds_::TaskState_/RIHS01_1",
    ):
        assert g.may("ingress", "declare_subscriber", key) and g.may("egress", "put", key)
        assert face.may("ingress", "put", key) and not g.may("ingress", "put", key)
    assert g.may("ingress", "query", say) and g.may("egress", "reply", say)
    assert g.may("egress", "declare_queryable", say) and not g.may("ingress", "declare_queryable", say)
    assert face.may("egress", "query", say) and face.may("ingress", "reply", say)
    token = "@ros2_lv/0/zid/0/1/MS/%/%/listener/%joint_states/sensor_msgs::msg::dds_::JointState_/RIHS01_a"
    for message in ("liveliness_token", "declare_liveliness_subscriber", "liveliness_query"):
        assert g.may("ingress", message, token)  # type: ignore[arg-type]
    assert g.may("egress", "liveliness_token", token)
    for key in (
        keys.fipa_key("C9", CALLER, "a_hi"),
        keys.HUMAN_IN,
        keys.state_key("ag_ex"),
        keys.alive_key(ROS2),
    ):
        for flow, message in g.allowed:
            assert not g.may(flow, message, key), (flow, message, key)
    granted = [k for ks in g.allowed.values() for k in ks]
    assert not any(k in ("**", "*/**") or k.startswith(keys.PREFIX) for k in granted), granted
    assert not g.allowed.get(("ingress", "put")) and not g.allowed.get(("ingress", "reply"))


def test_only_ag_ex_puts_its_camera_images_and_roco_ros2_hears_them(spec: SystemSpec) -> None:
    """ag_ex puts roco/state/ag_ex/camera and learns of its subscribers (it renders only while one
    matches); roco ros2 subscribes and is delivered it, and publishes Image and CameraInfo; no
    other agent puts the images and none hears them."""
    camera = keys.camera_key("ag_ex")
    ex, g = agent_grants(spec, "ag_ex"), ros2_grants(spec)
    assert ex.may("ingress", "put", camera) and ex.may("egress", "declare_subscriber", camera)
    assert g.may("ingress", "declare_subscriber", camera) and g.may("egress", "put", camera)
    assert not g.may("ingress", "put", camera)
    for a in spec.agents:
        if a.name != "ag_ex":
            other = agent_grants(spec, a.name)
            assert not other.may("ingress", "put", camera) and not other.may("egress", "put", camera)
    for t in ("Image_", "CameraInfo_"):
        assert g.may("ingress", "put", f"0/head_camera/image_raw/sensor_msgs::msg::dds_::{t}/RIHS01_ab")
