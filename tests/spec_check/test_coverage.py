"""``roco spec coverage`` on a synthetic record whose coverage is known exactly: a tap folder
(services/runtime/tap.py) with a few C7 conversations and a made-up FSM record of a_pl."""

from __future__ import annotations

import os
from pathlib import Path

from typer.testing import CliRunner

from services import cli
from services.runtime.behaviour import FSM, Arc, Behaviour
from services.runtime.fsm_record import FsmRecord
from services.runtime.tap import Tap, appender
from services.spec.model import DEFAULT_SPEC, default_spec
from services.spec.protocol_defs import protocols_of
from services.spec_check.coverage import Item, coverage_of, protocol_items
from services.spec_check.coverage_figure import panels
from services.spec_check.coverage_text import render
from shared.fipa_codec import Performative, encode
from shared.fipa_codec.languages.l_wm import Answer, SparqlQuery
from shared.fipa_codec.protocols import FIPA_QUERY
from tests.support.messages import communicate

P = Performative
C7 = "C7 fipa-query"
ASK = SparqlQuery(query="ASK {}")


def _put(
    tap: Tap, t: float, perf: Performative, sender: str, receiver: str, cid: str, term: object = None
) -> None:
    comm = communicate(perf, sender, receiver, "fipa-query", cid, term)  # type: ignore[arg-type]
    tap.put(t, f"roco/fipa/C7/{sender}/{receiver}", encode(comm))


def _tapped(folder: Path) -> None:
    """Two C7 conversations (one answered, one not understood), a time-out of a_hi's, and
    a_pl's FSM: idle → busy taken once, busy → idle never."""
    tap = Tap(folder, "bus-test")
    _put(tap, 1.0, P.QUERY_REF, "a_hi", "a_km", "q1", ASK)
    _put(tap, 1.1, P.INFORM_REF, "a_km", "a_hi", "q1", Answer(boolean=True))
    _put(tap, 2.0, P.QUERY_REF, "a_hi", "a_km", "q2", ASK)
    _put(tap, 2.1, P.NOT_UNDERSTOOD, "a_km", "a_hi", "q2")
    _put(tap, 3.0, P.REQUEST, "alice", "bob", "x")  # of no channel of the specification
    fsm = FSM(
        [Behaviour("idle", lambda: None, lambda: True), Behaviour("busy", lambda: None, lambda: True)],
        [Arc("idle", "busy", label="work"), Arc("busy", "idle")],
    )
    record = FsmRecord("a_pl", [appender(folder / "fsm" / f"a_pl.{os.getpid()}.jsonl")])
    record.declared(fsm, "services.agents.planner.agent:Planner")
    record.entered("idle", "start")
    record.entered("busy", "arc", "idle", "work")
    hi = FsmRecord("a_hi", [appender(folder / "fsm" / f"a_hi.{os.getpid()}.jsonl")])
    hi.timed_out("a_km", "fipa-query", "q3", "queried")


def test_the_coverage_of_a_known_record_is_exactly_what_it_took(tmp_path: Path) -> None:
    _tapped(tmp_path)
    cov = coverage_of([], tmp_path)
    taken = {i.key: n for i, n in cov.counts.items() if n}
    assert taken == {
        f"{C7}: start -I: query-ref-> queried": 2,
        f"{C7}: queried -P: inform-ref-> answered": 1,
        f"{C7}: not-understood by the participant": 1,
        f"{C7}: time-out: a reply-by passed unanswered": 1,
        f"{C7}: query-ref carries SparqlQuery": 2,
        f"{C7}: inform-ref carries Answer": 1,
        "a_pl: state idle": 1,
        "a_pl: state busy": 1,
        "a_pl: idle -> busy (work)": 1,
    }
    spec = default_spec()
    protocol = sum(
        len(protocol_items(f"{ch.name} {cp.protocol}", FIPA_QUERY, cp))
        for ch in spec.channels
        for cp in ch.protocols
        if cp.protocol == "fipa-query" and ch.name in ("C2", "C4", "C6", "C7")
    )
    # C2, C4, C6, C7 (the shipped fipa-query channels; one added since is left out): 22
    # transitions (query-ref's and query-if's, the cancel meta-protocol's), a not-understood by
    # each role and a time-out each; their
    # content terms (C4 and C6: 7 queries each by query-ref and by query-if, Answer by two)
    assert protocol == 4 * (22 + 2 + 1) + 2 + 2 * (7 + 7 + 1 + 1) + 2
    machines = protocols_of(DEFAULT_SPEC)  # the built-in machines, and roco-notify's of the table
    every = [
        protocol_items(f"{ch.name} {cp.protocol}", machines[cp.protocol], cp)
        for ch in spec.channels
        for cp in ch.protocols
    ]
    assert len(cov.items) == sum(map(len, every)) + 4  # a_pl's 2 states and 2 arcs
    assert cov.exercised == 9
    assert cov.share == 9 / len(cov.items)
    assert cov.outside == 1
    assert cov.where[Item(C7, "not-understood", "not-understood by the participant")] == {"queried": 1}
    # every agent but a_pl started in no record: their FSMs are not counted, and said so
    assert set(cov.unknown_fsms) == set(spec.agent_names) - {"a_pl"}


def test_transitions_are_counted_per_protocol_whatever_the_channel(tmp_path: Path) -> None:
    """A transition taken on C7 counts as taken for fipa-query on every channel; FSM arcs
    count per agent; not-understood, time-outs and terms are not transitions."""
    _tapped(tmp_path)
    cov = coverage_of([], tmp_path)
    per = cov.transitions()
    query = {i.name for i in cov.items if i.kind == "transition" and i.group.endswith(" fipa-query")}
    assert per["fipa-query"] == (2, len(query)) and len(query) == 22
    assert per["a_pl FSM"] == (1, 2)
    assert per["fipa-request"][0] == per["coordinate"][0] == per["fipa-subscribe"][0] == 0
    assert "transitions of the protocols (on any channel) and of the agents' FSMs: 3 of " in render(cov)


def test_the_text_lists_what_was_never_taken(tmp_path: Path) -> None:
    _tapped(tmp_path)
    text = render(coverage_of([], tmp_path))
    never = text.split(f"\n{C7}: ", 1)[1].split("never taken:", 1)[1].split("\n\n", 1)[0]
    assert "    queried -P: refuse-> refused" in never
    assert "start -I: query-ref-> queried" not in never
    assert "a_pl FSM (services.agents.planner.agent:Planner): 3 of 4" in text
    assert "    busy -> idle\n" in text.split("a_pl FSM", 1)[1] + "\n"
    assert "a_co: no FSM record declares its FSM" in text


def test_the_figure_draws_each_protocol_and_the_known_fsms(tmp_path: Path) -> None:
    _tapped(tmp_path)
    drawn = panels(coverage_of([], tmp_path))
    titles = [p.title.split(" (")[0].split(":")[0] for p in drawn]
    shipped = ["coordinate", "fipa-request", "fipa-subscribe", "fipa-query", "roco-notify"]
    # the shipped specification's protocols in its order, then any a grown one added
    grown = {p.protocol for c in default_spec().channels for p in c.protocols} - set(shipped)
    assert titles[0] == "agents and channels" and titles[-1] == "a_pl FSM"
    assert titles[1:6] == shipped and set(titles[6:-1]) == grown, titles
    query = drawn[4]
    assert ("P: inform-ref", 1) in query.edges[("queried", "answered")]
    assert ("P: refuse", 0) in query.edges[("queried", "refused")]
    assert drawn[-1].edges[("busy", "idle")] == [("", 0)]


def test_min_fails_with_one_line_when_the_share_is_under_it(tmp_path: Path) -> None:
    _tapped(tmp_path)
    svg = tmp_path / "coverage.svg"
    args = ["spec", "coverage", "--tests", "--tap", str(tmp_path), "--brief"]
    under = CliRunner().invoke(cli.app, [*args, "--min", "0.5", "--svg", str(svg)], prog_name="roco")
    assert under.exit_code == 1
    last = under.output.strip().splitlines()[-1]
    assert last.startswith("roco: exercised: 9 of ") and last.endswith("under --min 50.0 %")
    assert svg.read_text().lstrip().startswith("<?xml")
    over = CliRunner().invoke(cli.app, [*args, "--min", "0.01"], prog_name="roco")
    assert over.exit_code == 0, over.output


def test_nothing_to_count_and_a_missing_tap_are_refused(tmp_path: Path) -> None:
    nothing = CliRunner().invoke(cli.app, ["spec", "coverage"], prog_name="roco")
    assert nothing.exit_code == 2 and "nothing to count" in nothing.output
    missing = CliRunner().invoke(
        cli.app, ["spec", "coverage", "--tests", "--tap", str(tmp_path / "no")], prog_name="roco"
    )
    assert missing.exit_code == 2 and missing.output.strip().startswith("roco: ")
