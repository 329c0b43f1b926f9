"""The live fuzz with access control on. During a pour by the whole fleet
(router with access control, recorder, six agent processes, MuJoCo), a fuzzer holding the
stolen credentials of a_co and a_ta puts malformed communicates to every agent they may reach
(between them: all six) on their own keys — all the router lets them use — and tries keys they
may not use. The pour succeeds, no agent dies, every answerable fuzz is answered with
not-understood, the agents' counters account for every one, the router refuses every
forbidden put and names the identity that made it (its report, as ``roco status`` shows it —
tests/security/test_refusals.py —, and refusals.jsonl), and the traffic record shows the spoofs
it let through (claimed sender ≠ the key's sender).

CI runs 2,000 per agent (12,000 in all); scripts/fuzz_live.py runs 10,000 per agent for the
figures in docs/security.md."""

from __future__ import annotations

from pathlib import Path

import pytest

from services.fleet.launcher import AGENT_ORDER
from services.runtime.refusals import read_refusals
from tests.fuzz.live import IDENTITIES, run_live_fuzz

pytestmark = [pytest.mark.slow, pytest.mark.fleet]
PER_AGENT = 2_000
FORBIDDEN = 100  # per identity


def test_malformed_communicates_from_stolen_identities_during_a_pour(tmp_path: Path) -> None:
    run = run_live_fuzz(tmp_path, PER_AGENT, FORBIDDEN)
    assert run.fuzzer_code == 0, run.fuzzer_output[-3000:]
    assert run.report is not None and run.report.kind.value == "succeeded", run.report
    assert run.dead == []
    s = run.summary
    assert s["sent"] == PER_AGENT * len(AGENT_ORDER)
    assert s["answered"] == s["answerable"] and int(str(s["answerable"])) > PER_AGENT, s
    assert set(run.counters) == set(AGENT_ORDER)
    for agent in AGENT_ORDER:
        c = run.counters[agent].counters
        rejected = sum(v for k, v in c.items() if k.startswith("rejected."))
        assert rejected + c.get("duplicates", 0) >= PER_AGENT, (agent, c)
        assert c.get("rejected.internal", 0) == 0, (agent, c)
        assert c.get("behaviour_errors", 0) == 0, (agent, c)
    # every forbidden put refused, counted and named with the identity that made it
    assert run.refusals is not None
    assert s["forbidden"] == FORBIDDEN * len(IDENTITIES)
    assert run.refusals.counters.get("refused.put", 0) == s["forbidden"], run.refusals.counters
    named = {n.identity for n in run.refusals.named if n.message == "put"}
    assert named == set(IDENTITIES)
    # … and in the run folder, one line each
    written = [r for r in read_refusals(tmp_path) if r.flow == "ingress"]
    assert len(written) == s["forbidden"] and {r.identity for r in written} == set(IDENTITIES)
    # roco status shows the agents' rejects and the router's refusals, named
    assert "a_km      alive  received" in run.status and "malformed" in run.status, run.status
    (router_line,) = [ln for ln in run.status.splitlines() if ln.startswith("router")]
    assert f"refused {s['forbidden']}: a_" in router_line, router_line
    # what the router let through (their own keys) and claimed another sender is recorded so
    assert set(run.spoofs_recorded) == set(IDENTITIES), run.spoofs_recorded
