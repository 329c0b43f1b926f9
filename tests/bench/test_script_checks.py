"""The benchmark scripts that run roco's agents check the work they time (scripts/profile_runtime.py:
the synthetic pair's exchange, services/bench/messaging.py ``check_exchange``): a planted fault
fails the script with one ``roco:`` line and no figure."""

from __future__ import annotations

import sys
from typing import Any

import pytest

from services.bench import parts

profile_runtime = parts.scripts_module("profile_runtime")


def _run(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], *argv: str
) -> tuple[int, str, str]:
    monkeypatch.setattr(sys, "argv", ["profile_runtime.py", *argv])
    code = profile_runtime.main()
    out, err = capsys.readouterr()
    return code, out, err


def test_profile_runtime_times_the_exchange_it_names(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, err = _run(monkeypatch, capsys, "--n", "100")
    assert code == 0 and err == "" and "stream send:" in out


def test_profile_runtime_prints_no_figure_when_a_communicate_is_not_understood(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    hand = profile_runtime.hand

    def garbling(src: Any, dst: Any) -> None:  # the first communicate handed over is cut short
        key, payload = src.engine.transport.out[0]
        src.engine.transport.out[0] = (key, payload[:-3])
        monkeypatch.setattr(profile_runtime, "hand", hand)
        hand(src, dst)

    monkeypatch.setattr(profile_runtime, "hand", garbling)
    code, out, err = _run(monkeypatch, capsys, "--n", "100")
    assert code == 1 and out == ""
    assert len(err.splitlines()) == 1
    assert err.startswith("roco: profile_runtime: the pair's exchange was not the work timed: ")


def test_the_stage_profile_gives_every_function_a_stage_and_says_what_was_compiled(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--stages``: the table's rows add up to its total, the round trip's own stages are there,
    and the compiled modules whose time lands in their callers are named (here, in the test's
    process, whichever are compiled)."""
    code, out, err = _run(monkeypatch, capsys, "--stages", "--n", "100")
    assert code == 0 and err == "", err
    table = [r for r in out.splitlines() if r.startswith("| ") and not r.startswith("| stage")]
    cells = [r.split("|")[1:3] for r in table]
    rows = {name.strip(): float(us) for name, us in cells}
    total = rows.pop("all")
    assert abs(sum(rows.values()) - total) < 0.01 * total + 0.5
    assert rows["elementary actions, hand-offs"] > 0 and rows["the handler (benchmark agents)"] > 0
    assert profile_runtime.stage_of("/x/services/runtime/protocol_state.py", "step") == "protocol state"
    assert profile_runtime.stage_of("~", "<method 'decode' of 'msgspec.msgpack.Decoder' objects>") == "decode"
