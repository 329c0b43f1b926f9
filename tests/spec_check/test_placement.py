"""``roco spec what-if`` (services/spec_check/placement.py, critical_path.py, whatif.py): the
placement read strictly, what crosses which link as roco routes, the critical paths in round
trips, the reply-by deadlines an RTT breaks, and the prediction beside what a real two-host run's
link carried.

``two_hosts_run/`` is part of the run folder of a real two-host pour (its README says how it was
made): the traffic record (``traffic.jsonl``, ``traffic.msgpack``), the relay's count of the
link (``link_bytes.jsonl``), ``link.jsonl``, ``hosts.json`` and ``run.json``."""

from __future__ import annotations

import itertools
import re
from pathlib import Path

import pytest
from typer.testing import CliRunner

import services.cli as cli
from services.recorder.record import TrafficRecord, read_records
from services.report.load import Message
from services.spec.model import SystemSpec, load
from services.spec_check.critical_path import Conversation, CriticalPaths, conversations
from services.spec_check.placement import (
    PUT_OVERHEAD_B,
    Placement,
    PlacementError,
    parse_placement,
    parse_rtt,
    puts_of,
    traffic,
)
from services.spec_check.whatif import declared_reply_by, unseen_peers, what_if
from services.spec_check.whatif_text import what_if_report
from shared.fipa_codec import AgentIdentifier, Communicate, Performative
from tests.spec_check.walkthrough import walkthrough_spec

TWO_HOSTS_RUN = Path(__file__).with_name("two_hosts_run")
AGENTS = ("a_hi", "a_co", "a_pl", "a_km", "a_ta", "ag_ex")
ROBOT = "ag_ex a_ta | a_km a_pl a_co a_hi"


def placed(spec: SystemSpec, hosts: str, records: list[TrafficRecord] | None = None) -> Placement:
    """``hosts`` for ``spec``'s agents as what-if places them for ``records`` (default: the two-host
    run's): an agent the record never saw (one added since) goes with its peers."""
    seen = read_records(TWO_HOSTS_RUN) if records is None else records
    return parse_placement(spec.agent_names, hosts, unseen=unseen_peers(spec, seen))


# ---- reading the options -------------------------------------------------------------------


@pytest.mark.parametrize(
    ("hosts", "merges", "recorder", "message"),
    [
        ("ag_ex | a_co a_pl a_km a_ta", (), "a_hi", "--hosts: a_hi on no host; place every agent"),
        ("ag_ex | a_co a_pl a_km a_ta a_hi bob", (), "a_hi", "--hosts: unknown agent 'bob'"),
        ("ag_ex a_co | a_co a_pl a_km a_ta a_hi", (), "a_hi", "--hosts: a_co is on H1 and H2"),
        ("ag_ex ag_ex | a_co a_pl a_km a_ta a_hi", (), "a_hi", "--hosts: ag_ex is twice on H1"),
        ("ag_ex || a_co a_pl a_km a_ta a_hi", (), "a_hi", "--hosts: host 2 names no agent"),
        (None, ("a_pl",), "a_hi", "--merge 'a_pl': name two or more agents"),
        (None, ("a_pl+",), "a_hi", "--merge 'a_pl+': name two or more agents"),
        (None, ("a_pl+bob",), "a_hi", "--merge: unknown agent 'bob'"),
        (None, ("a_pl+a_km", "a_km+a_co"), "a_hi", "--merge: a_km is in two merges"),
        (ROBOT, ("a_ta+a_km",), "a_hi", "--merge a_ta+a_km: its agents are on H1 and H2"),
        (None, (), "bob", "--recorder-with: unknown agent 'bob'"),
        ("x" * 3000, (), "a_hi", "--hosts: longer than"),
    ],
)
def test_a_placement_that_does_not_read_is_refused_naming_why(
    hosts: str | None, merges: tuple[str, ...], recorder: str, message: str
) -> None:
    with pytest.raises(PlacementError) as caught:
        parse_placement(AGENTS, hosts, merges, recorder)
    assert str(caught.value).startswith(message)
    assert "\n" not in str(caught.value)


def test_an_agent_the_record_never_saw_goes_with_its_peers_or_is_refused_naming_the_option() -> None:
    """A specification that has grown since the run: its new agent is not in the record."""
    agents = (*AGENTS, "a_new")
    p = parse_placement(agents, ROBOT, unseen={"a_new": ("a_km", "a_pl")})
    assert p.hosts == (("ag_ex", "a_ta"), ("a_km", "a_pl", "a_co", "a_hi", "a_new")) and p.with_peers == (
        "a_new",
    )
    named = parse_placement(agents, ROBOT + " a_new", unseen={"a_new": ("a_km",)})
    assert named.host_of("a_new") == 1 and named.with_peers == ()
    # two new agents, one of them joined to the other only
    two = parse_placement((*agents, "a_two"), ROBOT, unseen={"a_two": ("a_new",), "a_new": ("a_ta",)})
    assert (two.host_of("a_new"), two.host_of("a_two")) == (0, 0)
    for unseen, message in (
        (
            {"a_new": ("a_km", "a_ta")},
            "--hosts: a_new on no host; the record never saw it and its peers are on more than one "
            "(a_km on H2, a_ta on H1): name its host in --hosts",
        ),
        ({"a_new": ()}, "--hosts: a_new on no host; the record never saw it and no peer is placed"),
        ({}, "--hosts: a_new on no host; place every agent"),  # one the record saw
    ):
        with pytest.raises(PlacementError) as caught:
            parse_placement(agents, ROBOT, unseen=unseen)
        assert str(caught.value).startswith(message), caught.value


@pytest.mark.walkthrough
def test_what_if_on_a_record_older_than_the_specification_places_the_new_agent_and_says_so(
    tmp_path: Path,
) -> None:
    grown = walkthrough_spec(tmp_path / "spec.toml")  # docs/spec.md's a_wt, on channels to a_km and a_hi
    ok, text = what_if_report(TWO_HOSTS_RUN, hosts=ROBOT, rtt="40ms", spec_path=grown)
    assert ok, text
    # on H2 with a_km, after the agents --hosts names (and any other the record never saw)
    assert re.search(
        r"ran as: H1 ag_ex a_ta \| H2 a_km a_pl a_co a_hi( \w+)* a_wt( \w+)* \(\+recorder\)", text
    )
    assert (
        "note: a_wt is not in the record (the specification has grown since the run): placed on H2 "
        "with its peers (a_hi, a_km)"
    ) in text
    assert "measured on this run's link" in text  # still the run's own placement
    args = ["spec", "what-if", str(TWO_HOSTS_RUN), "--hosts", "ag_ex | a_ta a_km a_pl a_co a_hi"]
    result = CliRunner().invoke(cli.app, [*args, "--spec", str(grown)], prog_name="roco")
    assert result.exit_code == 0 and re.search(r"\| H2 a_ta a_km a_pl a_co a_hi( \w+)* a_wt", result.output)


def test_a_placement_reads_hosts_merges_and_the_recorder() -> None:
    p = parse_placement(AGENTS, "ag_ex, a_ta | a_km  a_pl a_co a_hi", ["a_pl+a_km"])
    assert p.hosts == (("ag_ex", "a_ta"), ("a_km", "a_pl", "a_co", "a_hi"))
    assert p.merged == (("a_pl", "a_km"),)
    assert (p.recorder, p.hub) == (1, 1)
    assert parse_placement(AGENTS).hosts == (AGENTS,)
    none = parse_placement(AGENTS, ROBOT, recorder_with="none")
    assert (none.recorder, none.hub) == (None, 1)


@pytest.mark.parametrize(
    ("text", "seconds"), [("20ms", 0.02), ("0.5s", 0.5), ("250 us", 250e-6), (" 1.5 s ", 1.5)]
)
def test_an_rtt_reads_with_its_unit(text: str, seconds: float) -> None:
    assert parse_rtt(text) == pytest.approx(seconds)


@pytest.mark.parametrize("text", ["20", "-3ms", "20 min", "ms", "1e3ms", "9999s", ""])
def test_an_rtt_without_unit_or_out_of_range_is_refused(text: str) -> None:
    with pytest.raises(PlacementError, match=r"^--rtt "):
        parse_rtt(text)


@pytest.mark.parametrize(
    "args",
    [
        ["--hosts", "ag_ex | a_co a_pl a_km a_ta"],
        ["--hosts", "ag_ex a_co | a_co a_pl a_km a_ta a_hi"],
        ["--merge", "a_pl+nobody"],
        ["--rtt", "20"],
    ],
)
def test_the_cli_refuses_bad_options_in_one_line_and_exit_2(args: list[str]) -> None:
    result = CliRunner().invoke(cli.app, ["spec", "what-if", str(TWO_HOSTS_RUN), *args], prog_name="roco")
    lines = result.output.strip().splitlines()
    assert result.exit_code == 2 and len(lines) == 1 and lines[0].startswith("roco: --"), result.output


# ---- what crosses ----------------------------------------------------------------------------


def test_a_communicate_crosses_to_its_receiver_and_to_the_recorder_each_link_once() -> None:
    two = parse_placement(AGENTS, ROBOT)  # the robot H1, the brain H2 with the recorder
    assert two.edges_of("a_ta", "ag_ex") == {(0, 1)}  # to the recorder only: ag_ex is local
    assert two.edges_of("ag_ex", "a_ta") == {(0, 1)}
    assert two.edges_of("a_co", "a_ta") == {(1, 0)}
    assert two.edges_of("a_pl", "a_km") == set()
    assert two.crossings("a_ta", "ag_ex") == 0 and two.crossings("a_co", "a_ta") == 1
    # three hosts: a star around the recorder's host
    three = parse_placement(AGENTS, "ag_ex | a_ta | a_km a_pl a_co a_hi")
    assert three.edges_of("a_ta", "ag_ex") == {(1, 2), (2, 0)}
    assert three.crossings("a_ta", "ag_ex") == 2
    assert sorted(three.links) == [(0, 2), (1, 2)]
    # without a recorder, only the receiver wants it; merged agents use no link at all
    assert parse_placement(AGENTS, ROBOT, recorder_with="none").edges_of("a_ta", "ag_ex") == set()
    merged = parse_placement(AGENTS, ROBOT, ["ag_ex+a_ta"])
    assert merged.edges_of("a_ta", "ag_ex") == set() and merged.crossings("a_ta", "ag_ex") == 0


_seq = itertools.count()


def rec(
    sender: str,
    receiver: str,
    size: int,
    t: float,
    *,
    channel: str = "C5",
    sn: int | None = None,
    part: int = 0,
) -> TrafficRecord:
    return TrafficRecord(
        seq=next(_seq), t=t, size=size, channel=channel, sender=sender, receivers=(receiver,),
        performative="inform", source="p:1" if sn is not None else None, sn=sn, part=part,
    )  # fmt: skip


def test_a_batch_is_one_put_and_its_bytes_on_the_wire_are_msgpacks() -> None:
    batch = [rec("a_pl", "a_km", 300, 1.0, channel="C4", sn=7, part=i) for i in range(3)]
    alone = rec("a_pl", "a_km", 200, 1.5, channel="C4")
    puts = puts_of([*batch, alone])
    assert [len(p.records) for p in puts] == [3, 1]
    assert puts[0].size == 1 + 3 * (3 + 300)  # fixarray, bin 16 headers
    assert puts[1].size == 200


def test_the_traffic_per_link_counts_payload_and_wire_per_second() -> None:
    p = parse_placement(AGENTS, "ag_ex | a_ta a_km a_pl a_co a_hi")
    records = [
        rec("a_ta", "ag_ex", 1000, 100.2, sn=0),
        rec("ag_ex", "a_ta", 500, 100.7, sn=1),
        rec("ag_ex", "a_ta", 4000, 101.1, sn=2),
        rec("a_pl", "a_km", 9999, 101.5, channel="C4", sn=3),
    ]
    t = traffic(records, p)
    down, up = t.links[(1, 0)]["C5"], t.links[(0, 1)]["C5"]
    assert (down.communicates, down.payload_b, down.wire_b) == (1, 1000, 1000 + PUT_OVERHEAD_B)
    assert (up.communicates, up.payload_b, up.puts) == (2, 4500, 2)
    assert up.payload_per_s == {100: 500, 101: 4000}
    assert "C4" not in t.links.get((1, 0), {}) and len(t.crossing) == 3


# ---- critical paths and deadlines --------------------------------------------------------------


def msg(
    t: float,
    channel: str,
    protocol: str,
    cid: str,
    sender: str,
    receiver: str,
    perf: Performative,
    *,
    rw: str | None = None,
    irt: str | None = None,
    reply_by: float | None = None,
) -> Message:
    comm = Communicate(
        performative=perf, sender=AgentIdentifier(sender), receiver=(AgentIdentifier(receiver),),
        protocol=protocol, conversation_id=cid, reply_with=rw, in_reply_to=irt, reply_by=reply_by,
    )  # fmt: skip
    r = TrafficRecord(
        seq=next(_seq), t=t, size=300, channel=channel, sender=sender, receivers=(receiver,),
        performative=perf.value, protocol=protocol, conversation_id=cid, t_sent=t,
    )  # fmt: skip
    return Message(r, t, comm)


REQ, INF, AGR = Performative.REQUEST, Performative.INFORM, Performative.AGREE


def command_run() -> list[Message]:
    """a_hi's command (C2) served by a_co: a plan (C3) served by a_pl with three queries to a_km
    sent together (C4, overlapping) and one after; then an execution (C1) in which a_ta asks
    ag_ex twice, one after the other (C5)."""
    m = [
        msg(0.0, "C2", "fipa-request", "cmd", "a_hi", "a_co", REQ, rw="h1", reply_by=120.0),
        msg(0.01, "C2", "fipa-request", "cmd", "a_co", "a_hi", AGR, irt="h1"),
        msg(0.02, "C3", "fipa-request", "plan", "a_co", "a_pl", REQ, rw="c1", reply_by=600.02),
    ]
    m += [
        msg(0.03, "C4", "fipa-query", f"q{i}", "a_pl", "a_km", Performative.QUERY_REF, rw=f"p{i}")
        for i in range(3)
    ]
    m += [
        msg(0.05 + i / 100, "C4", "fipa-query", f"q{i}", "a_km", "a_pl", Performative.INFORM_REF, irt=f"p{i}")
        for i in range(3)
    ]
    m += [
        msg(0.10, "C4", "fipa-query", "q3", "a_pl", "a_km", Performative.QUERY_REF, rw="p3"),
        msg(0.11, "C4", "fipa-query", "q3", "a_km", "a_pl", Performative.INFORM_REF, irt="p3"),
        msg(0.12, "C3", "fipa-request", "plan", "a_pl", "a_co", INF, irt="c1"),
        msg(0.20, "C1", "coordinate", "exec", "a_co", "a_ta", REQ, rw="x1"),
        msg(0.21, "C5", "fipa-request", "m1", "a_ta", "ag_ex", REQ, rw="t1", reply_by=3.21),
        msg(2.21, "C5", "fipa-request", "m1", "ag_ex", "a_ta", INF, irt="t1"),
        msg(2.22, "C1", "coordinate", "exec", "a_ta", "a_co", INF, irt="x1", rw="s1", reply_by=302.22),
        msg(2.23, "C5", "fipa-request", "m2", "a_ta", "ag_ex", REQ, rw="t2", reply_by=4.23),
        msg(3.23, "C5", "fipa-request", "m2", "ag_ex", "a_ta", INF, irt="t2"),
        msg(3.24, "C1", "coordinate", "exec", "a_co", "a_ta", Performative.CONFIRM, irt="s1"),
        msg(3.25, "C1", "coordinate", "exec", "a_ta", "a_co", INF, irt="x1", rw="s2"),
        msg(3.26, "C2", "fipa-request", "cmd", "a_co", "a_hi", INF, irt="h1"),
    ]
    return m


def paths_for(hosts: str) -> tuple[CriticalPaths, dict[str, Conversation]]:
    spec = load()
    run = command_run()
    placement = placed(spec, hosts, [m.rec for m in run])
    convs = conversations(run)
    from services.spec_check.critical_path import waits_of

    paths = CriticalPaths(convs, waits_of((a.name, a.waits) for a in spec.agents), placement.crossings)
    return paths, {c.conversation_id: c for c in convs}


def test_the_critical_path_adds_nested_conversations_in_sequence_and_overlapping_ones_once() -> None:
    # a_km alone; every other agent of the specification on the other host (an agent added
    # since, whom the record never saw, is placed there too)
    paths, by_id = paths_for("a_km | " + " ".join(a for a in load().launch_order if a != "a_km"))
    # the plan: its own request and inform stay on one host; the three queries sent together
    # cost one round trip, the fourth another
    assert paths.half_trips(by_id["plan"]) == 4
    assert paths.half_trips(by_id["cmd"]) == 4  # the plan nested in the command
    assert paths.half_trips(by_id["exec"]) == 0
    paths, by_id = paths_for("ag_ex | a_hi a_co a_pl a_km a_ta")
    assert paths.half_trips(by_id["exec"]) == 4  # the two motions, one after the other
    assert paths.half_trips(by_id["cmd"]) == 4 and paths.half_trips(by_id["plan"]) == 0


def test_a_wait_breaks_at_the_rtt_its_reply_by_leaves_room_for() -> None:
    paths, by_id = paths_for("ag_ex | a_hi a_co a_pl a_km a_ta")
    (first,) = paths.waits_in(by_id["m1"])
    assert first.budget_s == pytest.approx(3.0) and first.recorded_s == pytest.approx(2.0)
    assert first.half_trips == 2
    assert first.predicted_s(0.5) == pytest.approx(2.5)
    assert first.breaks_at_s() == pytest.approx(1.0)  # 2 s + RTT > 3 s from an RTT of 1 s
    assert first.breaks(1.01) and not first.breaks(0.99)
    # against a budget it exceeded in the record already, it is late, not broken by the link
    assert first.late(1.5) and first.breaks_at_s(1.5) is None and not first.breaks(0.5, 1.5)
    (second,) = paths.waits_in(by_id["m2"])
    assert second.breaks_at_s() == pytest.approx(1.0)  # 1 s recorded, 2 s of room
    (confirm,) = paths.waits_in(by_id["exec"])  # a_ta's first L_SW inform awaits a_co's confirm
    assert confirm.answer is not None and confirm.answer.performative == "confirm"
    assert confirm.half_trips == 0  # a_ta and a_co share a host here
    paths, by_id = paths_for(ROBOT)
    (confirm,) = paths.waits_in(by_id["exec"])
    assert confirm.half_trips == 2 and confirm.recorded_s == pytest.approx(1.02)


# ---- the tool on real runs ---------------------------------------------------------------------


def test_the_prediction_for_a_two_host_run_is_within_10_percent_of_what_its_link_carried() -> None:
    """The done-when of the tool: a real `roco hosts` pour (two_hosts_run/README.md), its record
    placed as it ran, the cross-host kbps predicted beside the relay's count of the same seconds."""
    spec = load()
    placement = placed(spec, ROBOT)
    w = what_if(TWO_HOSTS_RUN, spec, placement, parse_rtt("40ms"))
    assert w.measured is not None, "the run's own placement is recognised"
    for edge, measured_b in w.measured.by_edge.items():
        predicted_b = w.traffic.totals[edge].wire_b
        assert abs(predicted_b - measured_b) <= 0.10 * measured_b, (edge, predicted_b, measured_b)
    measured_peak = max(w.measured.per_s.values())
    per_s = w.traffic.totals[(0, 1)].wire_per_s + w.traffic.totals[(1, 0)].wire_per_s
    assert abs(max(per_s.values()) - measured_peak) <= 0.10 * measured_peak
    # the payload alone (without the put overhead) would miss by more than 10 %
    payload = sum(f.payload_b for f in w.traffic.totals.values())
    assert payload < 0.85 * sum(w.measured.by_edge.values())


def test_another_placement_of_the_run_is_not_compared_with_its_link() -> None:
    spec = load()
    w = what_if(TWO_HOSTS_RUN, spec, placed(spec, "ag_ex | a_ta a_km a_pl a_co a_hi"), None)
    assert w.measured is None
    assert set(w.traffic.totals) == {(0, 1), (1, 0)}
    assert {ch for flows in w.traffic.links.values() for ch in flows} == {"C5"}


def test_the_report_of_the_two_host_run_names_the_link_the_deadlines_and_the_roles() -> None:
    ok, text = what_if_report(TWO_HOSTS_RUN, hosts=ROBOT, rtt="40ms")
    assert ok, text
    assert "measured on this run's link" in text
    assert "C1:coordinate inform by a_ta" in text  # a_ta's L_SW informs wait for a_co's confirm
    assert "a_pl C4 fipa-query 30 s" in text  # a role's declared reply-by
    assert text.endswith("deadlines broken at RTT 40 ms: 0")
    broken, text = what_if_report(TWO_HOSTS_RUN, hosts="ag_ex | a_ta a_km a_pl a_co a_hi", rtt="5s")
    assert not broken and "C5:fipa-request request by a_ta" in text and "BREAKS" in text
    # a_ta's first Observe was answered after its reply-by while the camera started: a fact of
    # the record, not something the placement breaks
    assert "1 answered after the reply-by in the record already" in text


def test_a_merge_takes_its_channel_off_zenoh() -> None:
    ok, text = what_if_report(TWO_HOSTS_RUN, merges=["a_pl+a_km"])
    assert ok
    assert "In one process (merged): off Zenoh and the record:\n  C4: 60 communicates" in text
    assert "C3:fipa-request a_co→a_pl" in text  # the plan's queries no longer go through Zenoh


def test_the_roles_declared_reply_by_are_read_from_the_agents() -> None:
    roles, notes = declared_reply_by(load())
    found = {(r.agent, r.channel, r.protocol): r.reply_by_s for r in roles}
    assert found[("a_pl", "C4", "fipa-query")] == 30.0 and ("ag_ex", "C5", "fipa-request") not in found
    assert notes == []


def test_a_placement_object_describes_itself() -> None:
    p = Placement((("ag_ex",), ("a_hi", "a_co")), (), recorder=1, hub=1)
    assert p.describe() == "H1 ag_ex | H2 a_hi a_co (+recorder)"
