"""The live fuzz with access control on, at full size (docs/security.md).

    python scripts/fuzz_live.py [--per-agent 10000] [--forbidden 500] [--seed 8] [--keep DIR]

Starts the fleet with access control (router, recorder, six agent processes, MuJoCo) in a
fresh run folder, and during a pour lets a fuzzer holding the stolen credentials of a_co and
a_ta (between them they reach all six agents) put ``--per-agent`` malformed communicates to
each agent on their own keys, plus ``--forbidden`` puts per identity on keys they may not use
(tests/fuzz/live.py, tests/fuzz/fuzzer.py). Prints the figures: the pour's outcome and wall
time, communicates sent, answerable and answered with not-understood, each agent's rejected
inputs by reason, the router's refusals named, the spoofs the traffic record shows. Exit 0 when
the pour succeeded, no agent died, every answerable fuzz was answered, nothing raised inside an
agent and every forbidden put was refused; 1 otherwise.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from services.fleet.launcher import AGENT_ORDER
from services.runtime.counters import summary
from services.runtime.refusals import summary as refusal_summary
from tests.fuzz.live import IDENTITIES, run_live_fuzz


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="fuzz_live.py", description=__doc__.split("\n\n")[0])
    parser.add_argument("--per-agent", type=int, default=10_000, help="malformed communicates per agent")
    parser.add_argument("--forbidden", type=int, default=500, help="forbidden puts per identity")
    parser.add_argument("--seed", type=int, default=8)
    parser.add_argument("--keep", type=Path, default=None, help="run folder to keep (default: temporary)")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="roco-fuzz-") as tmp:
        run_dir = args.keep or Path(tmp)
        run = run_live_fuzz(run_dir, args.per_agent, args.forbidden, seed=args.seed)
    s = run.summary
    outcome = run.report.kind.value if run.report is not None else "no outcome"
    print(f"pour: {outcome}; whole run {run.seconds:.0f} s wall (fleet start, pour, fuzz, answers)")
    print(f"identities: {', '.join(IDENTITIES)}; fuzzer exit {run.fuzzer_code}, {s.get('seconds')} s")
    print(
        f"malformed communicates sent: {s.get('sent')}; answerable (conversation-id readable): "
        f"{s.get('answerable')}; answered not-understood: {s.get('answered')}"
    )
    for agent in AGENT_ORDER:
        c = run.counters.get(agent)
        print(f"  {agent:6s} {summary(c.counters) if c else 'no counters'}")
    refused = run.refusals.counters.get("refused.put", 0) if run.refusals else 0
    print(f"forbidden puts: {s.get('forbidden')}; refused by the router: {refused}")
    if run.refusals is not None:
        print(f"  router {refusal_summary(run.refusals)}")
    print(f"spoofs recorded (claimed sender ≠ key's sender), by key sender: {run.spoofs_recorded}")
    print(f"agents dead or without liveliness token: {run.dead or 'none'}")
    internal = sum(c.counters.get("rejected.internal", 0) for c in run.counters.values())
    ok = (
        outcome == "succeeded"
        and not run.dead
        and run.fuzzer_code == 0
        and s.get("answered") == s.get("answerable")
        and internal == 0
        and refused == s.get("forbidden")
    )
    print("verdict: " + ("all held" if ok else "FAILED"))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
