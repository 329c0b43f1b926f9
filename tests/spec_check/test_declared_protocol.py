"""A protocol the specification declares by name in its own table (docs/spec.md, "Declaring a
protocol's state machine") is checked, explored for deadlocks, verified on a record and
counted by coverage, and compared with the agents' code, as a built-in one is.

The specification is a copy of the shipped one with two declared protocols on C6, a_ta
initiating: ``notify`` (one inform, nothing answers) and ``tell`` (an inform the participant
confirms)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from services.runtime.run_folder import RunInfo, write_run_info
from services.spec.check import check_report
from services.spec.model import DEFAULT_SPEC, SpecError, load
from services.spec.protocol_defs import protocols_of
from services.spec_check.code_check import verify_code_report
from services.spec_check.conformance import verify_report, verify_run
from services.spec_check.coverage import coverage_of
from services.spec_check.deadlock import analyse
from shared.fipa_codec.languages.l_wm import Answer, WorldUpdate
from tests.report.conftest import COMMAND_TEXT, STARTED, RunBuilder, write_traffic

NOTIFY = """[protocols.notify]
initiator = ["inform"]
participant = []
final = ["told"]
transitions = [["start", "initiator", "inform", "told"]]
"""

TELL = """[protocols.tell]
initiator = ["inform"]
participant = ["confirm"]
final = ["confirmed"]
transitions = [
  ["start", "initiator", "inform", "told"],
  ["told", "participant", "confirm", "confirmed"],
]
"""

TELL_DEADLOCKS = """[protocols.tell]
# Broken on purpose: the initiator's cancel ends its side at once, while a participant that
# confirmed before the cancel arrived waits for the initiator's confirm, which never comes.
initiator = ["inform", "confirm", "cancel"]
participant = ["confirm"]
final = ["done", "withdrawn"]
transitions = [
  ["start", "initiator", "inform", "told"],
  ["told", "participant", "confirm", "confirmed"],
  ["confirmed", "initiator", "confirm", "done"],
  ["told", "initiator", "cancel", "withdrawn"],
]
"""

ON_C6 = """  [[channels.protocols]]
  protocol = "notify"
  initiator = "a_ta"
  languages = { inform = "L_WM" }
  contents = { inform = ["WorldUpdate"] }
  [[channels.protocols]]
  protocol = "tell"
  initiator = "a_ta"
  languages = { inform = "L_WM", confirm = "L_WM" }
  contents = { inform = ["WorldUpdate"], confirm = ["Answer"] }
"""


def declared_spec(tmp_path: Path, tell: str = TELL, notify: str = NOTIFY) -> Path:
    """The shipped specification with ``notify`` and ``tell`` declared and spoken on C6."""
    text = DEFAULT_SPEC.read_text()
    anchor = "[protocols.coordinate]"
    text = text.replace(anchor, f"{notify}\n{tell}\n{anchor}", 1)
    c6 = 'transmits = "knowledge needed by a_ta and updates of the environment model"\n'
    assert text.count(c6) == 1
    text = text.replace(c6, c6 + ON_C6)
    path = tmp_path / "declared.toml"
    path.write_text(text)
    return path


UPDATE = WorldUpdate(stamp=1.0, objects=())
AGAIN = Answer(boolean=True)
"""A second confirm (another content: a byte-identical copy would be taken as a retransmission)."""


def _told(b: RunBuilder, t: float, conversation: str, protocol: str = "notify") -> None:
    b.add(t, "C6", "a_ta", "a_km", "inform", UPDATE, conversation=conversation, protocol=protocol)


def _run(tmp_path: Path, b: RunBuilder) -> Path:
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    write_run_info(run_dir, RunInfo(command=COMMAND_TEXT, started=STARTED))
    write_traffic(run_dir, b)
    return run_dir


def test_check_takes_the_declared_machines(tmp_path: Path) -> None:
    """Before, check looked only at the built-in protocols: 'C6 notify: no state machine for
    protocol 'notify''; and protocols_of refused notify: 'state 'not-understood' is
    unreachable'."""
    path = declared_spec(tmp_path)
    ok, report = check_report(path)
    assert ok, report
    machines = protocols_of(path)
    assert machines["notify"].states == {"start", "told"}
    assert machines["tell"].final == {"confirmed", "not-understood"}


def test_check_reports_a_malformed_declared_machine_saying_what_to_change(tmp_path: Path) -> None:
    path = declared_spec(tmp_path, notify=NOTIFY.replace('"told"]]', '"sent"]]'))
    ok, report = check_report(path)
    assert not ok
    assert (
        "- protocol notify: invalid state machine: state 'told' is unreachable from 'start'; add a "
        "transition into it from a reachable state, or take it out of 'final'"
    ) in report.splitlines()


def test_deadlock_explores_the_declared_protocols_and_finds_them_free(tmp_path: Path) -> None:
    result = analyse(declared_spec(tmp_path))
    assert not result.deadlock_found
    for name, states in (("notify", 3), ("tell", 5)):
        explored = result.protocol(name)
        assert explored.ok and explored.states == states and explored.notes == ()
    on_c6 = {c.protocol: c for c in result.channels if c.channel == "C6"}
    assert (on_c6["notify"].initiator, on_c6["notify"].participant) == ("a_ta", "a_km")


def test_deadlock_reports_a_declared_protocol_that_deadlocks(tmp_path: Path) -> None:
    result = analyse(declared_spec(tmp_path, tell=TELL_DEADLOCKS))
    assert result.deadlock_found
    tell = result.protocol("tell")
    assert [f.detail for f in tell.deadlocks] == [
        "the initiator has ended in 'withdrawn'; the participant waits in 'confirmed' for confirm "
        "but its queue holds cancel"
    ]
    assert [step.text() for step in tell.deadlocks[0].trace] == [
        "initiator sends inform -> told",
        "initiator sends cancel -> withdrawn",
        "participant receives inform -> told",
        "participant sends confirm -> confirmed",
    ]
    assert result.protocol("notify").ok


def test_verify_follows_a_record_through_the_declared_protocols(tmp_path: Path) -> None:
    spec = declared_spec(tmp_path)
    b = RunBuilder()
    _told(b, 1.0, "n1")
    _told(b, 2.0, "t1", "tell")
    b.add(2.1, "C6", "a_km", "a_ta", "confirm", Answer(), conversation="t1", protocol="tell")
    _told(b, 3.0, "n2")
    b.add(3.1, "C6", "a_km", "a_ta", "not-understood", None, conversation="n2", protocol="notify")
    ok, text = verify_report(_run(tmp_path, b), spec)
    assert ok, text
    assert "full conformance: yes" in text


@pytest.mark.parametrize(
    ("planted", "kind", "text"),
    [
        (  # the participant confirms twice: the conversation ended in 'confirmed'
            lambda b: b.add(2.2, "C6", "a_km", "a_ta", "confirm", AGAIN, conversation="t1", protocol="tell"),
            "protocol-state",
            "tell: the conversation already ended in state 'confirmed'; the participant may not send "
            "'confirm'",
        ),
        (  # the participant answers a notification, which nothing answers
            lambda b: b.add(
                1.1, "C6", "a_km", "a_ta", "inform", UPDATE, conversation="n1", protocol="notify"
            ),
            "performative",
            None,
        ),
    ],
    ids=["confirmed twice", "a notification answered"],
)
def test_verify_finds_an_out_of_protocol_communicate_in_a_declared_protocol(
    tmp_path: Path, planted: Callable[[RunBuilder], None], kind: str, text: str | None
) -> None:
    spec = declared_spec(tmp_path)
    b = RunBuilder()
    _told(b, 1.0, "n1")
    _told(b, 2.0, "t1", "tell")
    b.add(2.1, "C6", "a_km", "a_ta", "confirm", Answer(), conversation="t1", protocol="tell")
    planted(b)
    report = verify_run(_run(tmp_path, b), load(spec), protocols=protocols_of(spec))
    assert [v.kind for v in report.violations] == [kind]
    if text is not None:
        assert report.violations[0].text == text
    assert not report.full_conformance


def test_verify_takes_the_spec_s_machines_by_default(tmp_path: Path) -> None:
    """verify_run without ``protocols`` follows the declared machines too (it took the
    built-in library only, and left a declared protocol's conversations unfollowed)."""
    spec = declared_spec(tmp_path)
    b = RunBuilder()
    _told(b, 2.0, "t1", "tell")
    b.add(2.1, "C6", "a_km", "a_ta", "confirm", Answer(), conversation="t1", protocol="tell")
    b.add(2.2, "C6", "a_km", "a_ta", "confirm", AGAIN, conversation="t1", protocol="tell")
    report = verify_run(_run(tmp_path, b), load(spec))
    assert [v.kind for v in report.violations] == ["protocol-state"]


def test_coverage_counts_the_declared_protocols(tmp_path: Path) -> None:
    spec = declared_spec(tmp_path)
    b = RunBuilder()
    _told(b, 1.0, "n1")
    _told(b, 2.0, "t1", "tell")
    b.add(2.1, "C6", "a_km", "a_ta", "confirm", Answer(), conversation="t1", protocol="tell")
    cov = coverage_of([_run(tmp_path, b)], spec_path=spec)
    counted = {item.key: cov.counts[item] for item in cov.items if item.group in ("C6 notify", "C6 tell")}
    assert counted["C6 notify: start -I: inform-> told"] == 1
    assert counted["C6 tell: told -P: confirm-> confirmed"] == 1
    # nothing answers a notification: no time-out, and nothing for the initiator to not understand
    assert "C6 notify: " + "time-out: a reply-by passed unanswered" not in counted
    assert "C6 notify: not-understood by the initiator" not in counted
    assert "C6 notify: not-understood by the participant" in counted


def test_a_spec_whose_declared_machine_is_malformed_stops_verify(tmp_path: Path) -> None:
    spec = declared_spec(tmp_path, tell=TELL.replace('"confirmed"]', '"confirmed", "told"]', 1))
    with pytest.raises(SpecError, match="leaves the final state 'told'"):
        protocols_of(spec)


def test_verify_code_lists_a_declared_protocol_s_roles_and_asks_for_them(tmp_path: Path) -> None:
    """The agents' code is compared with the declared machine: the shipped a_ta and a_km do
    not play notify yet, and the listing says what each role would send and receive."""
    ok, report = verify_code_report(declared_spec(tmp_path))
    assert not ok
    lines = report.splitlines()
    assert "  C6 notify initiator with a_km in L_WM: receives nothing; sends inform" in lines
    assert "  C6 notify participant with a_ta in L_WM: receives inform; sends nothing" in lines
    assert (
        "- agent a_ta declares no initiator role for notify on C6, which [[channels]] C6 gives it (in L_WM)"
    ) in lines
