"""A fuzzer process: ``python -m tests.fuzz.fuzzer ENDPOINT COUNT [SEED]``.

Opens its own Zenoh client session on ``ENDPOINT`` and puts ``COUNT`` malformed communicates
(tests/fuzz/strategies.py :func:`flood`) to each of the six agents, interleaved, on keys
``roco/fipa/<C>/<legitimate sender>/<agent>``, with congestion control *block* (none is
dropped on the way). Prints one line ``sent N`` per agent at the end and exits 0.
"""

from __future__ import annotations

import random
import sys

import zenoh

from services.runtime.session import open_client
from tests.fuzz.strategies import AGENTS, flood


def main(argv: list[str]) -> int:
    endpoint, count = argv[0], int(argv[1])
    rng = random.Random(int(argv[2]) if len(argv) > 2 else 8)
    session = open_client(endpoint, wait_for_router=True)
    sent = dict.fromkeys(AGENTS, 0)
    try:
        for _ in range(count):
            for agent in AGENTS:
                f = flood(agent, rng)
                session.put(f.key, f.payload, congestion_control=zenoh.CongestionControl.BLOCK)
                sent[agent] += 1
    finally:
        session.close()
    for agent, n in sent.items():
        print(f"sent {agent} {n}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
