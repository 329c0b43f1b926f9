"""What the agents raised, in one line (services/runtime/raised.py), and in `roco status`'s
counters line (services/runtime/counters.py ``summary``)."""

from __future__ import annotations

from pathlib import Path

import pytest

from services.runtime.counters import CountersReport, save_counters, summary
from services.runtime.raised import raised, raised_by_agent, raised_text
from services.runtime.run_folder import RunInfo, write_run_info
from tests.support.raised import assert_no_agent_raised


def test_only_error_counters_above_zero_are_raised() -> None:
    counters = {"received.inform": 12, "handler_errors": 2, "behaviour_errors": 0, "rejected": 1}
    assert raised(counters) == {"handler_errors": 2}
    assert raised_by_agent({"a_ta": counters, "a_co": {"received.inform": 3}}) == {
        "a_ta": {"handler_errors": 2}
    }
    assert raised_by_agent({"a_co": {"handler_errors": 0, "behaviour_errors": 0}}) == {}


def test_the_line_names_each_agent_its_errors_and_its_log() -> None:
    by_agent = {"a_ta": {"handler_errors": 2}, "a_co": {"handler_errors": 1, "behaviour_errors": 1}}
    assert raised_text(by_agent, {}) == (
        "1 handler error and 1 behaviour error in a_co: see logs/a_co.log; "
        "2 handler errors in a_ta: see logs/a_ta.log"
    )
    assert raised_text({}, {"a_km": [70]}) == (
        "a_km exited (code 70) and was started again: see logs/a_km.log"
    )
    assert raised_text({}, {"a_km": [70, 1]}) == (
        "a_km exited 2 times (code 70, 1) and was started again: see logs/a_km.log"
    )
    assert raised_text({}, {}) == "" and raised_text({}, {"a_km": []}) == ""


def test_status_line_names_the_errors_an_agent_counted() -> None:
    assert summary({"received.inform": 3}) == "received 3, rejected 0"
    line = summary({"received.inform": 3, "behaviour_errors": 1})
    assert line == "received 3, rejected 0, behaviour_errors 1"


def test_status_line_counts_the_notices_a_hi_passed_on_and_dropped() -> None:
    """`roco status` says how many notices a_hi told the person (and dropped, over its
    per-sender bound); nothing of notices when there were none."""
    told = summary({"received.inform": 9, "notices": 4, "notices_dropped": 5})
    assert told == "received 9, rejected 0, notices 4 (5 dropped)"
    assert summary({"received.inform": 4, "notices": 4}) == "received 4, rejected 0, notices 4"


def test_the_end_to_end_check_fails_on_an_agent_that_raised(tmp_path: Path) -> None:
    """tests/support/raised.py, as the pour's end-to-end test uses it, on planted run folders."""
    agents = ("a_co", "a_ta")
    write_run_info(tmp_path, RunInfo())
    clean = {a: CountersReport(a, 1.0, {"received.inform": 3, "handler_errors": 0}) for a in agents}
    save_counters(tmp_path, clean)
    assert_no_agent_raised(tmp_path, agents)
    save_counters(tmp_path, {**clean, "a_ta": CountersReport("a_ta", 1.0, {"handler_errors": 2})})
    with pytest.raises(AssertionError, match=r"2 handler errors in a_ta: see logs/a_ta\.log"):
        assert_no_agent_raised(tmp_path, agents)
    save_counters(tmp_path, {"a_co": clean["a_co"]})
    with pytest.raises(AssertionError, match="no counters of a_ta"):
        assert_no_agent_raised(tmp_path, agents)
    save_counters(tmp_path, clean)
    write_run_info(tmp_path, RunInfo(crashed={"a_ta": [70]}))
    with pytest.raises(AssertionError, match=r"a_ta exited \(code 70\)"):
        assert_no_agent_raised(tmp_path, agents)
