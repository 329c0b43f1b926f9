"""`roco send` hears a_hi's outcome when a_hi gave it while the router was down.

A real router on a loopback port, a stand-in for a_hi on a ZenohTransport, and `roco send` as a
process of its own. The router is SIGKILLed while `roco send` waits, a_hi tells the outcome into
the outage, and the router is started again on the same endpoint. Three ways a_hi tells it:

- through the transport's advanced publisher (as a_hi does): its cache gives it to `roco send`
  once the router is back; `roco send` prints it once and exits 0;
- as a plain Zenoh put, and a_hi keeps the outcomes it told (services/agents/human_interface/
  told.py, as a_hi does: an a_hi that died after telling has no cache left): `roco send` asks
  for it after ``ASK_AFTER_S`` of silence, prints it once and exits 0;
- as a plain put, kept nowhere (how a_hi told before either): it is lost, and `roco send`
  gives up: the check can fail.

Every wait reads a line or a queue against a deadline.
"""

from __future__ import annotations

import os
import queue
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import msgspec
import pytest

from services.fleet.launcher import Fleet
from services.runtime import keys
from services.runtime.human import HumanInput, HumanReport, ReportKind, RequestKind
from services.runtime.person import Told
from services.runtime.transport import ZenohTransport
from tests.support.lines import lines_of
from tests.support.router import router_fleet

ROOT = Path(__file__).resolve().parents[2]
OUTCOME = "pour the jar into the bowl: succeeded"
SEND_TIMEOUT_S = 25
"""`roco send --timeout`: ample for reconnecting after the outage (≈ 1 s, the retry schedule)
and for asking a_hi after ``ASK_AFTER_S`` (10 s) of silence."""


@pytest.fixture
def fleet(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Fleet]:
    yield from router_fleet(tmp_path_factory, "outage")


def kill_router(fleet: Fleet) -> None:
    proc = fleet.processes["router"]
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait(timeout=10)


@pytest.mark.parametrize(
    ("cached", "kept"),
    [(True, False), (False, True), (False, False)],
    ids=["advanced-publisher", "plain-put-kept", "plain-put-lost"],
)
def test_send_prints_an_outcome_given_while_the_router_was_down(
    fleet: Fleet, cached: bool, kept: bool
) -> None:
    a_hi = ZenohTransport([fleet.endpoint])
    heard: queue.SimpleQueue[HumanInput] = queue.SimpleQueue()
    a_hi.subscribe(keys.HUMAN_IN, lambda _k, p: heard.put(msgspec.json.decode(p, type=HumanInput)))
    told = Told()
    if kept:
        a_hi.serve(keys.HUMAN_OUTCOMES, told.answer)
    a_hi.announce(keys.alive_key("a_hi"))

    def report(request_id: str, kind: ReportKind, text: str) -> None:
        said = HumanReport(request_id=request_id, kind=kind, text=text)
        told.keep(said)
        payload = msgspec.json.encode(said)
        if cached:
            a_hi.publish(keys.HUMAN_OUT, payload)
        else:
            a_hi.session.put(keys.HUMAN_OUT, payload)

    options = ["--router", fleet.endpoint, "--timeout", str(SEND_TIMEOUT_S)]
    send = subprocess.Popen(
        [sys.executable, "-m", "services.cli", "send", "pour the jar into the bowl", *options],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=ROOT,
    )
    try:
        out = lines_of(send)
        said = heard.get(timeout=60)
        report(said.request_id, ReportKind.ACCEPTED, "pour the jar into the bowl: accepted")
        assert out.get(timeout=30) == "accepted: pour the jar into the bowl: accepted"
        kill_router(fleet)  # roco send waits for the outcome
        report(said.request_id, ReportKind.SUCCEEDED, OUTCOME)
        fleet.start_router()
        rest = []
        while (line := out.get(timeout=SEND_TIMEOUT_S + 30)) is not None:
            rest.append(line)
        send.wait(timeout=30)
        err = send.stderr.read() if send.stderr is not None else ""
    finally:
        if send.poll() is None:
            send.kill()
            send.wait()
        a_hi.close()
    if cached or kept:
        assert rest == [f"succeeded: {OUTCOME}"], (rest, err)
        assert send.returncode == 0, err
    else:  # the bug: the outcome is lost, roco send waits out its timeout
        assert rest == [], rest
        assert send.returncode == 1 and f"no outcome within {SEND_TIMEOUT_S} s" in err, err


def test_a_request_is_shown_up_to_its_final_report_only() -> None:
    from services.runtime.reports import ReportFilter

    shown = ReportFilter(max_ended=2)
    r = [
        HumanReport(request_id=rid, kind=kind, text=t, request=RequestKind.COMMAND)
        for rid, kind, t in [
            ("a", ReportKind.PROGRESS, "1"),
            ("a", ReportKind.SUCCEEDED, "2"),
            ("a", ReportKind.SUCCEEDED, "2"),  # told again (a restarted a_hi, a re-ask)
            ("a", ReportKind.PROGRESS, "late"),
            ("b", ReportKind.FAILED, "3"),
            ("c", ReportKind.STOPPED, "4"),
            ("a", ReportKind.SUCCEEDED, "2"),  # a forgotten: at most 2 ended requests kept
        ]
    ]
    assert [shown.keep(x) for x in r] == [True, True, False, False, True, True, True]
    with pytest.raises(ValueError, match="max_ended"):
        ReportFilter(max_ended=0)
