"""scripts/bench_reading.py: its setup is accepted (a_hi set up as its loop would, each line a
conversation of its own) and it times what it names: lines read, refused and stopped on."""

from __future__ import annotations

from services.bench.parts import scripts_module


def test_every_shape_is_read_refused_or_stopped_as_it_names() -> None:
    rows = scripts_module("bench_reading").measure(1)
    answers = {(r.shape, r.chars): r.answer for r in rows}
    assert answers[("command", 26)] == "read: a command"
    assert answers[("polite", 299)] == "read: a command"  # the 48-token line, parsed in full
    assert answers[("polite", 312)] == "refused: too many tokens"
    assert answers[("command", 100_000)] == "refused: too long"
    assert all(r.answer == "stop" for r in rows if r.shape == "stop")
    assert all(r.p50_ms > 0 for r in rows)
