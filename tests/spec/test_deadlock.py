"""Deadlock analysis of a specification (paper §4 step 3; services/spec_check/deadlock.py)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from services.spec.model import DEFAULT_SPEC, SpecError, default_spec
from services.spec.protocol_defs import protocols_of
from services.spec_check.deadlock import (
    GlobalState,
    Message,
    Step,
    WaitCycle,
    WaitEdge,
    analyse,
    analyse_library,
    deadlock_report,
    explore,
    library_report,
    render,
    wait_cycles,
    wait_edges,
)
from shared.fipa_codec.acts import Performative
from shared.fipa_codec.protocols import INITIATOR as I_
from shared.fipa_codec.protocols import PARTICIPANT as P_
from shared.fipa_codec.protocols import PROTOCOLS, Protocol, _build
from tests.support.conversation import Walk

FIXTURES = Path(__file__).with_name("fixtures")
SPEC = default_spec()
NEW = f"C{len(SPEC.channels) + 1}"
"""A channel the shipped specification does not have."""


def _kinds(path: Path) -> dict[str, list[tuple[str, GlobalState]]]:
    result = analyse(path)
    return {
        p.protocol: [(f.kind, f.state) for f in (*p.deadlocks, *p.unspecified_receptions)]
        for p in result.protocols
    }


# ---------------------------------------------------------------- the shipped specification


def test_shipped_spec_has_no_deadlock() -> None:
    result = analyse(DEFAULT_SPEC)
    for name in ("fipa-request", "fipa-query", "fipa-subscribe", "coordinate"):
        assert result.protocol(name).ok, name
    assert result.cycles == ()
    assert len(result.waits) >= 3  # a_co, a_pl and a_ta wait on the conversations they open
    assert {c.channel for c in result.channels} == {c.name for c in SPEC.channels}
    assert {"C1", "C2", "C3", "C4", "C5", "C6", "C7", "C8"} <= {c.channel for c in result.channels}
    assert all(c.result is result.protocol(c.protocol) for c in result.channels)


def test_outcomes_that_cross_a_cancel_end_the_conversation() -> None:
    """Found by this analysis and fixed in shared/fipa_codec/protocols.py: in 'cancelling' the
    initiator used to accept only agree, failure and inform, so a refuse (or, in fipa-query,
    an inform-ref) sent before the cancel arrived was never consumed and the initiator waited
    for ever. Now any final answer crossing the cancel ends the conversation: a crossing
    transition (:attr:`Protocol.crossing_transitions`), which the receiving role takes."""
    for name in ("fipa-request", "fipa-query", "fipa-subscribe"):
        result = explore(PROTOCOLS[name])
        assert result.deadlocks == () and result.unspecified_receptions == (), name
    fipa_request = PROTOCOLS["fipa-request"]
    assert fipa_request.next_state("cancelling", P_, Performative.REFUSE) is None
    assert fipa_request.next_state("cancelling", P_, Performative.REFUSE, crossing=True) == "refused"
    refused = Walk(fipa_request)  # unlinked: the refuse may have been sent before the cancel arrived
    for role, perf in ((I_, Performative.REQUEST), (I_, Performative.CANCEL), (P_, Performative.REFUSE)):
        refused.step(role, perf)
    # ended in every reading but the one where the cancel arrived after the refuse and may
    # still be answered (services/runtime/protocol_state.py, a late cancel)
    assert refused.states == {"refused"} and refused.may_be_finished


def test_tolerating_the_crossing_outcomes_removes_every_deadlock() -> None:
    found, text = deadlock_report(FIXTURES / "crossing_tolerated.toml")
    assert not found, text
    assert text.rstrip().splitlines()[-1].startswith("no deadlock found (")


def test_the_shipped_spec_is_explored_once_per_protocol_over_a_few_hundred_states() -> None:
    """What keeps ``roco spec deadlock`` fast (its time: scripts/bench_deadlock.py): each of the
    five protocols is explored once, however many channels use it, and their products stay
    small: 332 states and 633 transitions in all at queue capacity 2 (38, 48, 65, 178 and 3
    states). The bounds leave a fifth for the specification to grow."""
    result = analyse(DEFAULT_SPEC)
    assert len(result.channels) == sum(len(c.protocols) for c in SPEC.channels) >= 12
    assert len(result.protocols) == len({p.protocol for c in SPEC.channels for p in c.protocols})
    assert all(c.result is result.protocol(c.protocol) for c in result.channels)
    assert sum(p.states for p in result.protocols) <= 400, [(p.protocol, p.states) for p in result.protocols]
    assert sum(p.transitions for p in result.protocols) <= 760


# ---------------------------------------------------------------- a protocol that deadlocks


def test_a_cancel_crossing_the_first_report_deadlocks_with_its_shortest_trace() -> None:
    result = analyse(FIXTURES / "deadlock_protocol.toml")
    coordinate = result.protocol("coordinate")
    assert [f.state for f in coordinate.deadlocks] == [
        GlobalState("cancelled", "reported", (Message("cancel"),), (Message("inform"),)),
        GlobalState("cancelled", "ending", (Message("cancel"),), (Message("inform", terminal=True),)),
    ]
    first, second = coordinate.deadlocks
    assert first.trace == (
        Step(I_, "send", "request", "requested"),
        Step(I_, "send", "cancel", "cancelled"),
        Step(P_, "receive", "request", "requested"),
        Step(P_, "send", "inform", "reported"),
    )
    assert second.trace[-1] == Step(P_, "send", "inform", "ending", terminal=True)
    assert first.detail == (
        "the initiator has ended in 'cancelled'; "
        "the participant waits in 'reported' for confirm but its queue holds cancel"
    )
    assert coordinate.unspecified_receptions == ()  # the stuck cancel is part of the deadlocks
    assert result.deadlock_found

    found, text = deadlock_report(FIXTURES / "deadlock_protocol.toml")
    assert found
    assert (
        "  C1 coordinate: a_co initiates, a_ta participates: 18 states: 2 deadlocks, 2 late messages\n"
        "    DEADLOCK: a_co (initiator) has ended in 'cancelled'; a_ta (participant) waits in 'reported' "
        "for confirm but its queue holds cancel\n"
        "      1. a_co sends request -> requested\n"
        "      2. a_co sends cancel -> cancelled\n"
        "      3. a_ta receives request -> requested\n"
        "      4. a_ta sends inform -> reported\n"
    ) in text


def test_traces_are_shortest() -> None:
    """No deadlock is reachable in fewer steps than the reported trace (BFS)."""
    machine = protocols_of(FIXTURES / "deadlock_protocol.toml")["coordinate"]
    for capacity in (1, 2, 3):
        result = explore(machine, queue_capacity=capacity)
        assert [len(f.trace) for f in result.deadlocks] == [4, 4]


# ---------------------------------------------------------------- exploration options


def test_not_understood_turns_the_deadlock_into_an_unspecified_reception() -> None:
    machine = protocols_of(FIXTURES / "deadlock_protocol.toml")["coordinate"]
    plain = explore(machine)
    escaped = explore(machine, not_understood=True)
    assert plain.deadlocks and plain.unspecified_receptions == ()
    assert escaped.deadlocks == () and escaped.unspecified_receptions
    assert escaped.states > plain.states


def _spoke_without_hearing(trace: tuple[Step, ...]) -> bool:
    """Some role sends not-understood with nothing received since it last sent (or at all)."""
    last: dict[str, str] = {}
    for step in trace:
        if (
            step.event == "send"
            and step.performative == "not-understood"
            and last.get(step.role) != "receive"
        ):
            return True
        last[step.role] = step.event
    return False


def test_a_role_sends_not_understood_only_after_it_received_something_since_it_last_sent() -> None:
    """The rule every agent is held to (services/runtime/protocol_state.py ``judge``), over the
    library: before it, fipa-propose's and fipa-recruiting's initiators answered their own
    opening with not-understood (112 traces of the findings)."""
    findings = []
    for protocol in PROTOCOLS.values():
        result = explore(protocol, not_understood=True)
        findings += [*result.deadlocks, *result.unspecified_receptions, *result.late_messages]
    assert sum(any(s.performative == "not-understood" for s in f.trace) for f in findings) > 50
    assert not [f.detail for f in findings if _spoke_without_hearing(f.trace)]


def test_queue_bound() -> None:
    propose = explore(PROTOCOLS["fipa-propose"])
    assert propose.ok and not propose.bound_reached and propose.states == 7
    subscribe = [explore(PROTOCOLS["fipa-subscribe"], queue_capacity=c) for c in (1, 2, 3)]
    assert all(r.bound_reached for r in subscribe)  # informs without end
    assert subscribe[0].states < subscribe[1].states < subscribe[2].states
    with pytest.raises(ValueError):
        explore(PROTOCOLS["fipa-propose"], queue_capacity=0)
    with pytest.raises(SpecError, match="more than 10 product states"):
        explore(protocols_of(DEFAULT_SPEC)["coordinate"], max_states=10)


def test_late_messages_are_reported_but_are_no_deadlock() -> None:
    result = explore(PROTOCOLS["fipa-request"])
    assert [(f.detail, f.trace[-1]) for f in result.late_messages] == [
        ("cancel reaches the participant after it ended in 'failed'", Step(P_, "send", "failure", "failed")),
        ("cancel reaches the participant after it ended in 'done'", Step(P_, "send", "inform", "done")),
        ("cancel reaches the participant after it ended in 'refused'", Step(P_, "send", "refuse", "refused")),
    ]


# ---------------------------------------------------------------- agents: the wait-for graph


def test_a_wait_cycle_is_reported_with_the_cycle_as_trace() -> None:
    path = FIXTURES / "wait_cycle.toml"
    result = analyse(path)
    assert result.cycles == (
        WaitCycle(
            (
                WaitEdge("a_km", "C4:fipa-query", "C6:fipa-subscribe", "a_ta"),
                WaitEdge("a_ta", "C1:coordinate", "C6:fipa-query", "a_km"),
            )
        ),
    )
    assert result.cycles[0].agents == ("a_km", "a_ta")
    text = render(result)
    assert (
        "  CYCLE a_km -> a_ta -> a_km:\n"
        "    1. a_km, serving C4:fipa-query, opens C6:fipa-subscribe and waits for a_ta\n"
        "    2. a_ta, serving C1:coordinate, opens C6:fipa-query and waits for a_km\n"
    ) in text
    assert deadlock_report(path)[0]


def test_the_agents_own_waits_form_no_cycle() -> None:
    edges = wait_edges(FIXTURES / "wait_cycle.toml")
    assert edges[:3] == (
        WaitEdge("a_co", "C2:fipa-request", "C3:fipa-request", "a_pl"),
        WaitEdge("a_co", "C2:fipa-request", "C1:coordinate", "a_ta"),
        WaitEdge("a_pl", "C3:fipa-request", "C4:fipa-query", "a_km"),
    )
    real = [e for e in edges if e.agent != "a_km" and e.opens != "C6:fipa-query"]
    assert len(real) == 4
    assert wait_cycles(real) == ()


def test_wait_cycles_are_elementary_and_listed_once() -> None:
    def e(a: str, b: str, opens: str = "C:p") -> WaitEdge:
        return WaitEdge(a, "S:p", opens, b)

    edges = [e("x", "y"), e("y", "z"), e("z", "x"), e("y", "x"), e("y", "x", "D:p"), e("q", "x")]
    cycles = wait_cycles(edges)
    assert [c.agents for c in cycles] == [("x", "y"), ("x", "y"), ("x", "y", "z")]
    assert wait_cycles([e("x", "y"), e("y", "z")]) == ()
    assert len(wait_cycles([e("x", "y"), e("y", "x"), e("x", "z"), e("z", "x")], limit=1)) == 1


def _spec_with_waits(tmp_path: Path, agent: str, waits: str) -> Path:
    text = DEFAULT_SPEC.read_text()
    anchor = f'name = "{agent}"\n'
    assert anchor in text
    text = re.sub(rf'(name = "{agent}"\n(?:[^\n\[]+\n)*?)waits = [^\n]*\n', r"\1", text)
    path = tmp_path / "spec.toml"
    path.write_text(text.replace(anchor, anchor + f"waits = {waits}\n"))
    return path


@pytest.mark.parametrize(
    ("agent", "waits", "message"),
    [
        ("a_pl", '[{ serving = "C3:fipa-request" }]', "agent a_pl: waits entry 1: expected { serving ="),
        ("a_pl", '[{ serving = "C3:fipa-request", opens = [] }]', "opens must be a non-empty list"),
        (
            "a_pl",
            '[{ serving = "C3", opens = ["C4:fipa-query"] }]',
            "agent a_pl: waits entry 1: serving 'C3': expected \"CHANNEL:PROTOCOL\"",
        ),
        (
            "a_pl",
            f'[{{ serving = "{NEW}:fipa-request", opens = ["C4:fipa-query"] }}]',
            f"serving '{NEW}:fipa-request': no channel '{NEW}' (channels: "
            f"{', '.join(c.name for c in SPEC.channels)})",
        ),
        (
            "a_pl",
            '[{ serving = "C3:fipa-request", opens = ["C6:fipa-query"] }]',
            "opens 'C6:fipa-query': a_pl is not an end of C6 (a_ta and a_km)",
        ),
        (
            "a_pl",
            '[{ serving = "C3:fipa-query", opens = ["C4:fipa-query"] }]',
            "serving 'C3:fipa-query': C3 carries no protocol 'fipa-query' (it carries fipa-request)",
        ),
        (
            "a_pl",
            '[{ serving = "C4:fipa-query", opens = ["C4:fipa-query"] }]',
            "serving 'C4:fipa-query': a_pl initiates it, so it cannot serve it (only its participant can)",
        ),
        (
            "a_pl",
            '[{ serving = "C3:fipa-request", opens = ["C3:fipa-request"] }]',
            "opens 'C3:fipa-request': a_co initiates it, so a_pl cannot open it",
        ),
    ],
)
def test_a_malformed_waits_entry_gives_a_precise_error(
    tmp_path: Path, agent: str, waits: str, message: str
) -> None:
    path = _spec_with_waits(tmp_path, agent, waits)
    with pytest.raises(SpecError) as err:
        analyse(path)
    assert str(err.value).startswith(f"{path}: agent {agent}: waits")
    assert message in str(err.value)


def test_a_malformed_protocol_table_stops_the_analysis() -> None:
    with pytest.raises(SpecError, match="'infrom' is not a FIPA performative"):
        deadlock_report(FIXTURES / "malformed_protocol.toml")


def test_waits_of_the_wrong_type_are_refused_when_the_spec_loads(tmp_path: Path) -> None:
    path = _spec_with_waits(tmp_path, "a_pl", '"C4"')
    with pytest.raises(SpecError, match=r"Expected `array`, got `str` - at `\$\.agents\[2\]\.waits`"):
        analyse(path)


# ---------------------------------------------------------------- the built-in library


def test_every_protocol_of_the_library_is_deadlock_free() -> None:
    results = analyse_library()
    assert [r.protocol for r in results] == list(PROTOCOLS)
    for r in results:
        assert r.ok, (r.protocol, [f.detail for f in (*r.deadlocks, *r.unspecified_receptions)])
    found, text = library_report()
    assert not found
    for name in (
        "fipa-iterated-contract-net",
        "fipa-english-auction",
        "fipa-dutch-auction",
        "fipa-brokering",
        "fipa-recruiting",
    ):
        assert f"\n  {name} (FIPA SC000" in text
    assert text.rstrip().splitlines()[-1].startswith("no deadlock found (")


def _without_crossing(protocol: Protocol, key: tuple[str, str, Performative]) -> Protocol:
    """``protocol`` without its crossing transition ``key``."""
    crossing = dict(protocol.crossing_transitions)
    del crossing[key]  # type: ignore[arg-type]
    return Protocol(
        name=protocol.name,
        states=protocol.states,
        initial=protocol.initial,
        final=protocol.final,
        transitions=protocol.transitions,
        terminal_transitions=protocol.terminal_transitions,
        spec=protocol.spec,
        crossing_transitions=crossing,
    )


def test_an_auction_whose_end_cannot_cross_a_bid_deadlocks() -> None:
    """Planted: the English auction without the end of the auction taken after a bid (the
    crossing transition for the bid and the auctioneer's inform(end-of-auction) that cross on
    the wire)."""
    english = PROTOCOLS["fipa-english-auction"]
    broken = _without_crossing(english, ("bid", I_, Performative.INFORM))
    result = explore(broken)
    assert result.deadlocks and not result.ok
    first = result.deadlocks[0]
    assert first.state == GlobalState("ended", "bid", (Message("inform"),), (Message("propose"),))
    assert first.trace == (
        Step(I_, "send", "inform", "announced"),
        Step(I_, "send", "cfp", "called"),
        Step(P_, "receive", "inform", "announced"),
        Step(I_, "send", "inform", "ended"),
        Step(P_, "receive", "cfp", "called"),
        Step(P_, "send", "propose", "bid"),
    )
    assert first.detail == (
        "the initiator has ended in 'ended'; the participant waits in 'bid' for "
        "accept-proposal, cfp, reject-proposal but its queue holds inform"
    )
    found, text = library_report({broken.name: broken, "fipa-request": PROTOCOLS["fipa-request"]})
    assert found
    assert "    DEADLOCK: the initiator has ended in 'ended'; the participant waits in 'bid' for" in text
    assert "      6. participant sends propose -> bid\n" in text
    assert text.rstrip().splitlines()[-1].startswith("DEADLOCK FOUND (")


def test_a_winner_never_asked_is_a_state_with_no_way_out() -> None:
    """Planted: the English auction's winner never requested: 'won' is not final and only
    not-understood leads out of it, so both roles wait there for ever."""
    english = PROTOCOLS["fipa-english-auction"]
    edges = [
        (source, role, perf, target)
        for (source, role, perf), target in english.transitions.items()
        if perf is not Performative.NOT_UNDERSTOOD and source != "won"
    ]
    crossing = [
        (source, role, perf, target) for (source, role, perf), target in english.crossing_transitions.items()
    ]
    broken = _build(english.name, english.spec, "", edges, ["ended"], crossing_edges=crossing)
    result = explore(broken)
    assert [f.state for f in result.deadlocks] == [GlobalState("won", "won", (), ())]
    assert result.deadlocks[0].detail == (
        "the initiator waits in 'won' for nothing; the participant waits in 'won' for nothing"
    )
    assert library_report({broken.name: broken})[0]
