"""The cost of access control and TLS: pub/sub round trip through a router process.

    python scripts/measure_security.py [--n 2000] [--size 200]

For each of: TCP without access control, TCP with user/password and the ACL, mutual TLS with
user/password and the ACL, a router is spawned by the launcher on a free loopback port; a_pl
puts a payload of ``size`` bytes on C4 to a_km, a_km's echo thread puts it back, a_pl waits for
it (``n`` round trips after 200 warm-up ones). Also the time to open a session. Prints p50/p99
round trip in µs and session open in ms per setting (docs/security.md, "Cost").
"""

from __future__ import annotations

import argparse
import queue
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


import zenoh

from services.fleet.launcher import Fleet, free_port
from services.runtime import keys
from services.runtime.session import open_client
from services.security.context import register

ROUTES_S = 30.0
"""How long the first echo may take (the routes being put in place), s."""


class Unanswered(RuntimeError):
    """The echo did not come back: the setting measured is not working; no figure."""


def measure(acl: bool, tls: bool, n: int, size: int) -> dict[str, float]:
    """Round trips and session opening against one router; µs / ms."""
    with tempfile.TemporaryDirectory() as tmp:
        run_dir = Path(tmp)
        (run_dir / "logs").mkdir()
        fleet = Fleet(run_dir, f"tcp/127.0.0.1:{free_port()}", acl=acl, tls=tls)
        fleet.start_router()
        try:
            t0 = time.perf_counter()
            pl = open_client(fleet.endpoint, identity="a_pl")
            open_ms = (time.perf_counter() - t0) * 1e3
            km = open_client(fleet.endpoint, identity="a_km")
            to_km: queue.SimpleQueue[bytes | None] = queue.SimpleQueue()
            back: queue.SimpleQueue[bytes] = queue.SimpleQueue()
            km.declare_subscriber(keys.inbox_key("a_km"), lambda s: to_km.put(s.payload.to_bytes()))
            pl.declare_subscriber(keys.inbox_key("a_pl"), lambda s: back.put(s.payload.to_bytes()))

            def echo() -> None:  # not from the callback: zenoh calls from callbacks have deadlocked
                while (p := to_km.get()) is not None:
                    km.put(keys.fipa_key("C4", "a_km", "a_pl"), p)

            worker = threading.Thread(target=echo, daemon=True)
            worker.start()
            try:
                out = keys.fipa_key("C4", "a_pl", "a_km")
                payload = b"x" * size
                deadline = time.monotonic() + ROUTES_S
                while True:  # until the routes are in place
                    pl.put(out, payload)
                    try:
                        back.get(timeout=0.2)
                        break
                    except queue.Empty:
                        if time.monotonic() > deadline:
                            raise Unanswered(
                                f"no echo within {ROUTES_S:.0f} s (refused by the router?)"
                            ) from None
                rtts = []
                for i in range(n + 200):
                    t = time.perf_counter()
                    pl.put(out, payload)
                    try:
                        back.get(timeout=10)
                    except queue.Empty:
                        raise Unanswered(f"round trip {i + 1} not answered within 10 s") from None
                    if i >= 200:
                        rtts.append((time.perf_counter() - t) * 1e6)
            finally:
                to_km.put(None)
                worker.join()
                pl.close()
                km.close()
        finally:
            fleet.stop()
            register(fleet.endpoint, None)
    q = statistics.quantiles(rtts, n=100)
    return {"p50_us": q[49], "p99_us": q[98], "open_ms": open_ms}


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--n", type=int, default=2000)
    parser.add_argument("--size", type=int, default=200)
    args = parser.parse_args()
    settings: list[tuple[str, bool, bool]] = [
        ("tcp, no access control", False, False),
        ("tcp, usrpwd + ACL", True, False),
        ("mTLS, usrpwd + ACL", True, True),
    ]
    print(f"{'setting':26s} {'p50 µs':>8s} {'p99 µs':>8s} {'open ms':>8s}")
    for name, acl, tls in settings:
        try:
            r = measure(acl, tls, args.n, args.size)
        except (Unanswered, zenoh.ZError) as exc:  # no echo, or a session refused
            print(f"roco: measure_security: {name}: {exc}", file=sys.stderr)
            return 1
        print(f"{name:26s} {r['p50_us']:8.0f} {r['p99_us']:8.0f} {r['open_ms']:8.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
