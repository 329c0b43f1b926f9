"""The live requirement flags reach `roco status` over Zenoh from the traffic recorder, for a
fleet on any host: the recorder answers queries of ``roco/recorder/flags`` with the flags of
its run folder (services/recorder/flags.py), at most ``MAX_REPLIED`` of them and how many there
are; with no recorder, nobody answers and `roco status` says so in one line. Router and
recorder are processes of a :class:`Fleet` on a loopback endpoint with access control on (the
operator's session queries; only the recorder may answer); the flags are planted in the
recorder's run folder. Every wait polls a condition against a deadline."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import msgspec
import pytest
from typer.testing import CliRunner

from services.cli import app
from services.fleet.launcher import Fleet, free_port
from services.recorder.flags import MAX_REPLIED, FlagsReply, append_flag, ask_flags
from services.runtime.session import open_client
from tests.support.flags import a_flag

WAIT_S = 30.0
FLAG = a_flag(
    prop="a plan cancelled while a_ta holds an object in either gripper: that object put down, …",
    event="C1 a_ta → a_co inform SWStatus state=Preempted (conversation c-1)",
    why="C1 … came while waiting for C6 …",
    t=1_000.0,
    seq=212,
    recorded=213,
    flagged=1_000.5,
)


@pytest.fixture
def fleet(tmp_path: Path) -> Iterator[Fleet]:
    (tmp_path / "run" / "logs").mkdir(parents=True)
    fleet = Fleet(tmp_path / "run", f"tcp/127.0.0.1:{free_port()}")
    fleet.start_router()
    yield fleet
    fleet.stop()


def _status(fleet: Fleet, tmp_path: Path) -> list[str]:
    """`roco status` of ``fleet`` (no agent runs: exit 1), its lines."""
    runs = tmp_path / "no_fleet_of_roco_up"
    args = ["status", "--router", fleet.endpoint, "--runs-dir", str(runs), "--counters-timeout", "1"]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 1, result.output
    return result.output.splitlines()


def test_status_shows_the_flags_the_recorder_answers_with(fleet: Fleet, tmp_path: Path) -> None:
    assert (
        _status(fleet, tmp_path)[-1]
        == "flags     (the recorder did not answer: live requirement flags unknown)"
    )
    session = open_client(fleet.endpoint)
    try:
        assert ask_flags(session, timeout=0.5) is None  # no recorder yet
        fleet.start_recorder()
        fleet.wait_alive(session, ["recorder"], timeout=WAIT_S)
        assert ask_flags(session, timeout=WAIT_S) == FlagsReply(flags=[], total=0)
        append_flag(fleet.run_dir, FLAG)
        assert ask_flags(session, timeout=WAIT_S) == FlagsReply(flags=[FLAG], total=1)
    finally:
        session.close()
    lines = _status(fleet, tmp_path)
    assert lines[-1] == f"violated  {FLAG.line()}"
    assert not any("did not answer" in line for line in lines)


def test_the_answer_is_capped_and_says_how_many_more(fleet: Fleet, tmp_path: Path) -> None:
    for seq in range(MAX_REPLIED + 3):
        append_flag(fleet.run_dir, msgspec.structs.replace(FLAG, seq=seq))
    fleet.start_recorder()
    session = open_client(fleet.endpoint)
    try:
        fleet.wait_alive(session, ["recorder"], timeout=WAIT_S)
        reply = ask_flags(session, timeout=WAIT_S)
    finally:
        session.close()
    assert reply is not None and len(reply.flags) == MAX_REPLIED and reply.total == MAX_REPLIED + 3
    assert _status(fleet, tmp_path)[-1] == "violated  (and 3 more in the run folder's flags.jsonl)"
