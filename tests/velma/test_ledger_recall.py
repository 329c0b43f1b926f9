"""A starting ag_ex recalls from its ledger the commands an earlier ag_ex's loop ended, with
their results (velma/executor/ledger.py ``recall``), within its bounds."""

from __future__ import annotations

from pathlib import Path

from shared.fipa_codec.languages.l_ex import CommandResult
from shared.fipa_codec.languages.l_sd import Observation
from velma.executor.capture import WorldCapture
from velma.executor.ledger import (
    ANSWERS_FILE,
    INTERRUPTED,
    LEDGER_FILE,
    MAX_TEXT,
    Ledger,
    read_ledger,
    recall,
)

OK = CommandResult(command="wait", ok=True, sim_time=1.5)


def _ledger(tmp_path: Path) -> Path:
    """c1: a wait ended ok (in the line); c2: an Observe's capture and c3: an Observation (in
    the side store); c4: cut short by the stop; c5: started only; c6: no result kept."""
    path = tmp_path / LEDGER_FILE
    ledger = Ledger(path, life="100-aaaaaa")
    ledger.ended("c1", "wait", 1.5, "ok", OK)
    ledger.ended("c2", "observe", 2.0, "captured", WorldCapture(objects=(), stamp=2.0, qpos=b"\0" * 1440))
    ledger.ended("c3", "observe", 3.0, "observed", Observation(stamp=3.0, objects=()))
    ledger.ended("c4", "wait", 4.0, INTERRUPTED, CommandResult(command="wait", ok=False, reason="stopped"))
    ledger.started("c5", "wait", 5.0)
    ledger.ended("c6", "wait", 6.0, "ok")
    ledger.close()
    return path


def test_ended_commands_are_recalled_with_their_results(tmp_path: Path) -> None:
    path = _ledger(tmp_path)
    got = recall(path)
    assert sorted(got) == ["c1", "c2", "c3"]
    assert got["c1"].answer == OK and got["c1"].command == "wait"
    assert isinstance(got["c2"].answer, WorldCapture) and len(got["c2"].answer.qpos) == 1440
    assert got["c3"].answer == Observation(stamp=3.0, objects=()) and got["c3"].sim_time == 3.0
    ends = {e.conversation: e for e in read_ledger(tmp_path).entries}
    assert ends["c1"].result == OK and ends["c1"].stored is None and ends["c2"].stored is not None
    assert recall(tmp_path / "none.jsonl") == {}


def test_a_damaged_side_store_or_a_cut_id_is_not_recalled_and_only_the_ledger_s_end_is_read(
    tmp_path: Path,
) -> None:
    """Planted: the side store cut short (c3's result gone); a conversation-id cut to
    MAX_TEXT; a window that holds only the last lines."""
    path = _ledger(tmp_path)
    side = tmp_path / ANSWERS_FILE
    side.write_bytes(side.read_bytes()[:-5])
    assert sorted(recall(path)) == ["c1", "c2"]
    ledger = Ledger(path, life="200-bbbbbb")
    ledger.ended("x" * 2 * MAX_TEXT, "wait", 7.0, "ok", OK)
    ledger.ended("c7", "wait", 8.0, "ok", OK)
    ledger.close()
    assert sorted(recall(path)) == ["c1", "c2", "c7"]
    last = path.read_bytes().splitlines(keepends=True)[-1]
    assert sorted(recall(path, max_bytes=len(last) + 10)) == ["c7"]
    assert sorted(recall(path, max_bytes=len(last))) == ["c7"]
    assert recall(path, max_bytes=len(last) - 1) == {}  # the window cuts its only line
