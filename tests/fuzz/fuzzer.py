"""A fuzzer process: ``python -m tests.fuzz.fuzzer ENDPOINT COUNT [SEED] [--identity NAME]…
[--forbidden N] [--answers-timeout S]``.

Without ``--identity`` (a fleet without access control): one Zenoh client session puts
``COUNT`` malformed communicates (tests/fuzz/strategies.py :func:`flood`) to each of the six
agents, interleaved, on keys ``roco/fipa/<C>/<legitimate sender>/<agent>``.

With ``--identity NAME`` (repeatable; a fleet with access control): an attacker who stole
agent NAME's credentials. One session per identity, authenticated as NAME, puts ``COUNT``
malformed communicates to each agent NAME may send to (:func:`targets`), on NAME's own keys —
all the router lets it use —, and ``N`` (``--forbidden``) more on keys it may not use (posing as
another agent, or on a channel it does not own), which the router must refuse. It listens on
NAME's inbox and waits up to ``S`` s (default 120) until every answerable fuzz (one whose
conversation-id the agent can read) was answered with not-understood.

Puts use congestion control *block* (none is dropped on the way). Prints ``sent AGENT N`` per
agent and, with identities, one line ``summary {json}`` (sent, answerable, answered, missing,
forbidden, seconds); exits 0, or 1 when an answerable fuzz went unanswered.
"""

from __future__ import annotations

import argparse
import json
import queue
import random
import sys
import time

import zenoh

from services.runtime import keys
from services.runtime.session import open_client
from services.spec.model import default_spec
from shared.fipa_codec import DecodeError, Performative, decode
from shared.fipa_codec.batch import unpack
from tests.fuzz.strategies import AGENTS, flood, targets


def forbidden_keys(identity: str) -> list[str]:
    """Keys ``identity`` may not put on: every route of the specification with another sender
    (posing as it), and ``identity`` as sender to agents it has no channel with."""
    spec = default_spec()
    routes = [(c.name, a, b) for c in spec.channels for a, b in (c.ends, c.ends[::-1])]
    posing = [keys.fipa_key(c, s, r) for c, s, r in routes if s != identity and {s, r} <= set(AGENTS)]
    own = next(c for c, s, _ in routes if s == identity)
    reach = targets(identity)
    strangers = [keys.fipa_key(own, identity, r) for r in AGENTS if r != identity and r not in reach]
    return sorted(set(posing + strangers))


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="fuzzer")
    parser.add_argument("endpoint")
    parser.add_argument("count", type=int)
    parser.add_argument("seed", type=int, nargs="?", default=8)
    parser.add_argument("--identity", action="append", default=[])
    parser.add_argument("--forbidden", type=int, default=0)
    parser.add_argument("--answers-timeout", type=float, default=120.0)
    args = parser.parse_args(argv)
    rng = random.Random(args.seed)
    if not args.identity:
        return _as_everyone(args.endpoint, args.count, rng)
    return _as_identities(args, rng)


def _as_everyone(endpoint: str, count: int, rng: random.Random) -> int:
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


def _as_identities(args: argparse.Namespace, rng: random.Random) -> int:
    t0 = time.monotonic()
    answers: queue.SimpleQueue[bytes] = queue.SimpleQueue()
    sessions = {n: open_client(args.endpoint, wait_for_router=True, identity=n) for n in args.identity}
    pending: set[str] = set()
    sent: dict[str, int] = {}
    forbidden = 0
    try:

        def on_answer(sample: zenoh.Sample) -> None:
            for p in unpack(sample.payload.to_bytes()):  # a batch (one step's answers): each
                answers.put(p)

        for name, session in sessions.items():
            session.declare_subscriber(keys.inbox_key(name), on_answer)
        plan = [(name, agent) for name in sessions for agent in targets(name)]
        off_limits = {name: forbidden_keys(name) for name in sessions}
        every = max(1, (args.count * len(plan)) // args.forbidden) if args.forbidden else 0
        n = 0
        for _ in range(args.count):
            for name, agent in plan:
                f = flood(agent, rng, sender=name)
                sessions[name].put(f.key, f.payload, congestion_control=zenoh.CongestionControl.BLOCK)
                sent[agent] = sent.get(agent, 0) + 1
                if f.cid is not None:
                    pending.add(f.cid)
                n += 1
                if every and n % every == 0 and forbidden < args.forbidden * len(sessions):
                    for who, s in sessions.items():  # one forbidden put per identity
                        key = rng.choice(off_limits[who])
                        s.put(key, f.payload, congestion_control=zenoh.CongestionControl.BLOCK)
                        forbidden += 1
        answerable = len(pending)
        deadline = time.monotonic() + args.answers_timeout
        while pending and (left := deadline - time.monotonic()) > 0:
            try:
                payload = answers.get(timeout=left)
            except queue.Empty:
                break
            try:
                msg = decode(payload)
            except DecodeError:
                continue
            if msg.performative is Performative.NOT_UNDERSTOOD and msg.conversation_id is not None:
                pending.discard(msg.conversation_id)
    finally:
        for session in sessions.values():
            session.close()
    for agent, count in sent.items():
        print(f"sent {agent} {count}", flush=True)
    summary = {
        "identities": args.identity,
        "sent": sum(sent.values()),
        "answerable": answerable,
        "answered": answerable - len(pending),
        "missing": sorted(pending)[:10],
        "forbidden": forbidden,
        "seconds": round(time.monotonic() - t0, 1),
    }
    print("summary " + json.dumps(summary), flush=True)
    return 1 if pending else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
