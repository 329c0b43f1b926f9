"""The traffic record on real processes: a traffic recorder killed while communicates flow loses none of
them — the next incarnation fetches what was sent while it was down from the publishers'
caches (zenoh-ext advanced publisher/subscriber), in order, without writing twice what the
first one wrote — and the same holds across a router restart. Router and recorder are
processes of a :class:`Fleet` with access control on (the sender authenticates as a_pl and may
put only on its own keys); the sender is a :class:`ZenohTransport` of this test. Every wait
polls a condition against a deadline; processes are ended by their PID."""

from __future__ import annotations

import os
import signal
from collections.abc import Iterator
from pathlib import Path

import pytest

from services.fleet.launcher import Fleet, free_port
from services.recorder.record import read_records
from services.recorder.recorder import RECORDER
from services.report.load import load_run
from services.runtime import keys
from services.runtime.session import alive_agents, open_client
from services.runtime.transport import ZenohTransport
from shared.fipa_codec import Performative, encode
from tests.runtime.test_router_restart import kill_router, wait_for
from tests.support.messages import communicate

KEY = keys.fipa_key("C4", "a_pl", "a_km")
WAIT_S = 30.0


@pytest.fixture
def fleet(tmp_path: Path) -> Iterator[Fleet]:
    (tmp_path / "logs").mkdir()
    fleet = Fleet(tmp_path, f"tcp/127.0.0.1:{free_port()}")
    fleet.start_router()
    fleet.start_recorder()
    yield fleet
    fleet.stop()


def _send(t: ZenohTransport, numbers: range) -> None:
    for i in numbers:
        t.publish(KEY, encode(communicate(Performative.QUERY_REF, "a_pl", "a_km", "fipa-query", f"c-{i}")))


def _recorded(run_dir: Path) -> list[str | None]:
    return [r.conversation_id for r in read_records(run_dir)] if (run_dir / "traffic.jsonl").exists() else []


def test_a_killed_recorder_comes_back_with_everything_sent_while_it_was_down(fleet: Fleet) -> None:
    session = open_client(fleet.endpoint)
    fleet.wait_alive(session, ["recorder"], timeout=WAIT_S)
    sender = ZenohTransport([fleet.endpoint], identity="a_pl")
    try:
        _send(sender, range(20))
        wait_for(lambda: len(_recorded(fleet.run_dir)) == 20, WAIT_S, "20 communicates recorded")
        recorder = fleet.processes["recorder"]
        os.kill(recorder.pid, signal.SIGKILL)
        recorder.wait(timeout=10)
        _send(sender, range(20, 50))  # nobody records these now
        # the router drops the killed recorder's token when it sees the link close: until then a
        # wait for "recorder" would find the old token, and c-50 would go before the new one listens
        wait_for(lambda: RECORDER not in alive_agents(session), WAIT_S, "the killed recorder's token gone")
        fleet.start_recorder()
        fleet.wait_alive(session, ["recorder"], timeout=WAIT_S)
        _send(sender, range(50, 51))
        wanted = [f"c-{i}" for i in range(51)]
        wait_for(lambda: _recorded(fleet.run_dir) == wanted, WAIT_S, "all 51, in order, once each")

        # the router restarts: what is put while it is down reaches nobody, but stays cached
        kill_router(fleet)
        _send(sender, range(51, 56))
        fleet.start_router()
        _send(sender, range(56, 57))
        wanted += [f"c-{i}" for i in range(51, 57)]
        wait_for(lambda: _recorded(fleet.run_dir) == wanted, WAIT_S, "all 57 after the router restart")
    finally:
        sender.close()
        session.close()
    fleet.stop()
    run = load_run(fleet.run_dir)
    assert run.integrity.intact, run.integrity.summary()
    assert len(run.integrity.incarnations) == 2 and run.integrity.paired == 57
    late = [m.rec.conversation_id for m in run.messages if m.rec.late]
    assert late == [f"c-{i}" for i in range(20, 50)]  # sent before the second incarnation listened
    assert all(m.comm is not None and m.comm.conversation_id == m.rec.conversation_id for m in run.messages)
