"""``roco replay`` of a_co where a peer's communicates wait for a_co's that they do not name.

a_ta's informs on a plan's run (coordinate protocol) all answer a_co's request (their
in-reply-to), yet a_ta sends each after a_co's confirm of the one before. When the record holds
a_ta's first informs before what made a_co send its request (a_pl's plan, stamped by a clock
behind the others and seen late by the recorder), the replay holds them until a_co has sent the
request, and must then feed them one at a time, each after a_co's communicates to a_ta sent
before it."""

from __future__ import annotations

import json
from pathlib import Path

from services.replay.driver import render, replay
from services.replay.record import agent_record
from services.runtime.run_folder import TRAFFIC_JSONL
from tests.support.recorded_run import copy_record

FIXTURE = Path(__file__).parents[1] / "spec_check" / "fixtures" / "urgent_mid_pour"
"""A real record whose conversations of a_co are whole (its README)."""
PLAN, REQUEST, CONFIRM, FIRST, SECOND = 16, 17, 18, 19, 21
"""Records (``seq``) of the fixture: a_pl's first plan to a_co, a_co's request to a_ta to run
it, a_co's confirm of a_ta's first inform, and a_ta's first two informs (the second sent after
that confirm)."""


def _plan_late(dest: Path) -> Path:
    """A copy of the fixture with a_pl's first plan sent, by its timestamp, and reaching the
    recorder just after a_ta's second inform (and before anything else of a_pl's on its key):
    what a_pl's clock behind the others' (on a host of its own) and a slow path to the recorder
    show. (The recorder's time alone would not do: the replay takes an input as reaching the
    agent when its sender's timestamp says.)"""
    run = copy_record(FIXTURE, dest)
    path = run / TRAFFIC_JSONL
    records = [json.loads(line) for line in path.read_text().splitlines()]
    by_seq = {r["seq"]: r for r in records}
    assert (by_seq[PLAN]["sender"], by_seq[PLAN]["receivers"]) == ("a_pl", ["a_co"])
    assert [by_seq[s]["performative"] for s in (REQUEST, CONFIRM, FIRST, SECOND)] == [
        "request",
        "confirm",
        "inform",
        "inform",
    ]
    by_seq[PLAN]["t"] = by_seq[SECOND]["t"] + 0.0001
    by_seq[PLAN]["t_sent"] = by_seq[SECOND]["t_sent"] + 0.0001
    path.write_text("".join(json.dumps(r) + "\n" for r in records))
    return run


def test_a_ta_s_informs_recorded_before_a_co_asked_go_in_each_after_a_co_s_confirm(tmp_path: Path) -> None:
    """The fixture reproduces as recorded; with a_pl's plan recorded after a_ta's first two
    informs (so they come before it in a_co's input) it reproduces as well: neither inform
    reaches a_co before its request, nor the second before a_co's confirm of the first."""
    assert replay(FIXTURE, "a_co").equal
    run = _plan_late(tmp_path / "late")
    inputs = [item.seq for item in agent_record(run, "a_co").inputs]
    assert inputs.index(FIRST) < inputs.index(SECOND) < inputs.index(PLAN), inputs
    result = replay(run, "a_co")
    assert result.equal, render(result)
    assert not result.counters, render(result)
