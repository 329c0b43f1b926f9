"""`roco fault msg|net|clear|show` reach a running agent process over Zenoh, and the traffic
recorder writes the faults it applied to the run folder (faults.jsonl), which the report
lists."""

from __future__ import annotations

from pathlib import Path

from typer.testing import CliRunner

from services.cli import app
from services.report import build_report
from services.runtime.faults import FaultEvent
from services.spec.model import default_spec
from shared.fipa_codec import Performative
from tests.fault.conftest import LiveFleet


def test_message_faults_set_live_are_applied_recorded_and_cleared(live: LiveFleet) -> None:
    out = live.roco("msg", "C4", "--drop", "1")
    assert out.returncode == 0, out.stderr
    assert "C4: drop 1 on a_km" in out.stdout

    live.query("q-dropped")  # a_km's answer is dropped by a_km's own fault layer
    show = live.roco("show")
    assert show.returncode == 0, show.stderr
    assert "a_km" in show.stdout and "C4 drop 1" in show.stdout

    def dropped(events: list[FaultEvent]) -> bool:
        return any(e.kind == "drop" and e.conversation_id == "q-dropped" for e in events)

    events = live.recorded_faults(dropped)
    drop = next(e for e in events if e.kind == "drop")
    assert (drop.agent, drop.channel, drop.performative) == ("a_km", "C4", "inform-ref")
    assert any(e.kind == "settings" and e.agent == "a_km" and '"drop":1.0' in e.detail for e in events)

    out = live.roco("clear", "C4")
    assert out.returncode == 0, out.stderr
    live.query("q-answered")
    replies = live.answer("q-answered")
    assert [r.in_reply_to for r in replies] == ["q-answered"]  # the dropped one never came
    assert replies[0].performative is Performative.INFORM_REF

    report = build_report(live.run_dir)
    rows = {(f.kind, f.by, f.where): f for f in report.faults}
    assert rows[("drop", "a_km", "C4")].count == 1


def test_partition_makes_an_agent_look_gone_and_heal_brings_it_back(live: LiveFleet) -> None:
    out = live.roco("net", "a_km", "--partition")
    assert out.returncode == 0, out.stderr
    assert "a_km network faults: partitioned" in out.stdout
    live.wait_alive("a_km", alive=False)  # its liveliness token is withdrawn
    live.query("q-cut")  # does not reach a_km

    out = live.roco("net", "a_km", "--delay", "0.05")
    assert out.returncode == 0, out.stderr
    assert "delay 0.05 s, partitioned" in out.stdout  # options not given are kept

    out = live.roco("net", "a_km", "--heal")
    assert out.returncode == 0, out.stderr
    assert "a_km network faults: delay 0.05 s" in out.stdout
    live.wait_alive("a_km")
    live.query("q-healed")
    assert [r.in_reply_to for r in live.answer("q-healed")] == ["q-healed"]

    def recorded(events: list[FaultEvent]) -> bool:
        kinds = {(e.kind, e.conversation_id) for e in events}
        return {
            ("partition", None),
            ("partition_in", "q-cut"),
            ("heal", None),
            ("net_delay", "q-healed"),
        } <= kinds

    live.recorded_faults(recorded)
    assert live.roco("clear").returncode == 0


def test_bad_fault_input_is_one_line_and_exit_2(tmp_path: Path) -> None:
    runner = CliRunner()
    new = f"C{len(default_spec().channels) + 1}"  # no channel of the specification
    for args, text in [
        (("msg", new, "--drop", "0.1"), f"unknown channel '{new}'"),
        (("msg", "C4", "--drop", "1.5"), "--drop must be a probability"),
        (("msg", "C4"), "no fault given"),
        (("msg", "C4", "--delay-p", "0.5"), "--delay-p needs --delay"),
        (("msg", "C4", "--delay", "-1"), "--delay must be seconds"),
        (("net", "a_km"), "nothing to change"),
        (("net", "router", "--loss", "0.1"), "need --compose"),
        (("kill", "a_xx"), "no service 'a_xx'"),
        (("clear", "C77"), "neither a channel"),
    ]:
        out = runner.invoke(app, ["fault", *args, "--runs-dir", str(tmp_path)])
        assert out.exit_code == 2, (args, out.output)
        assert out.stderr.startswith("roco: ") and text in out.stderr, (args, out.stderr)
        assert len(out.stderr.strip().splitlines()) == 1, out.stderr
    out = runner.invoke(app, ["fault", "kill", "a_km", "--runs-dir", str(tmp_path)])
    assert out.exit_code == 1 and out.stderr.startswith("roco: no fleet is up")
