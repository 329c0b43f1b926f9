"""Cost of the fault layer (services/runtime/faults.py) per publication.

Measures, in this process:

1. ``publish`` through a :class:`FaultyTransport` with no fault active against the wrapped
   transport's own ``publish``, on a transport whose ``publish`` does nothing (the layer's
   own cost, ns per call);
2. the same with a fault configured on the channel that (almost) never fires
   (``drop=1e-9``: the path every publication takes while faults are on);
3. a subscriber callback through the layer's partition guard against a direct call;
4. ``publish`` of a 600 B communicate over real Zenoh (a router and a client session in
   this process, loopback TCP on a free port) with and without the layer (µs per call).

Each figure is the fastest of ``--repeats`` loops of ``--n`` calls, the variants compared
taking turns in each repeat.

Usage: ``python scripts/bench_faults.py [--n 1000000] [--repeats 7]``
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from services.fleet.launcher import free_port  # noqa: E402
from services.runtime import keys  # noqa: E402
from services.runtime.faults import FaultSettings, FaultyTransport, MessageFaults  # noqa: E402
from services.runtime.transport import AliveCallback, Callback, ZenohTransport  # noqa: E402
from services.runtime.zenoh_config import router_config  # noqa: E402
from shared.fipa_codec import Performative, encode  # noqa: E402
from tests.support.messages import communicate  # noqa: E402

KEY = keys.fipa_key("C4", "a_km", "a_pl")


class NullTransport:
    """A transport that does nothing (keeps the last subscription's callback)."""

    def __init__(self) -> None:
        self.callback: Callback | None = None

    def publish(self, key: str, payload: bytes) -> None:
        pass

    def subscribe(self, key_expr: str, callback: Callback) -> None:
        self.callback = callback

    def announce(self, key: str) -> None:
        pass

    def watch(self, key_expr: str, callback: AliveCallback) -> None:
        pass

    def close(self) -> None:
        pass


def per_call(fns: list[Callable[[], None]], n: int, repeats: int) -> list[float]:
    """Seconds per call of each of ``fns``: the fastest of ``repeats`` loops of ``n`` calls,
    the functions taking turns in every repeat (so that load from elsewhere hits all alike)."""
    best = [float("inf")] * len(fns)
    for _ in range(repeats):
        for i, fn in enumerate(fns):
            t0 = time.perf_counter()
            for _ in range(n):
                fn()
            best[i] = min(best[i], (time.perf_counter() - t0) / n)
    return best


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--n", type=int, default=1_000_000)
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args()
    n, r = args.n, args.repeats
    payload = encode(communicate(Performative.INFORM, "a_km", "a_pl", "fipa-query", "c1", content=b"x" * 480))
    print(f"payload {len(payload)} B; {n} calls × {r} repeats, fastest loop, per call")

    null = NullTransport()
    wrapped = FaultyTransport(NullTransport(), "a_km", control=False)
    armed = FaultyTransport(
        NullTransport(), "a_km", FaultSettings(channels={"C4": MessageFaults(drop=1e-9)}), control=False
    )
    base, idle, on = per_call(
        [
            lambda: null.publish(KEY, payload),
            lambda: wrapped.publish(KEY, payload),
            lambda: armed.publish(KEY, payload),
        ],
        n,
        r,
    )
    print(
        f"1. null transport publish: direct {base * 1e9:6.1f} ns, through the layer (no fault) "
        f"{idle * 1e9:6.1f} ns: +{(idle - base) * 1e9:.1f} ns"
    )
    print(
        f"2. with a fault armed on the channel (never firing): {on * 1e9:6.1f} ns: "
        f"+{(on - base) * 1e9:.1f} ns"
    )
    for t in (wrapped, armed):
        t.close()

    inner = NullTransport()
    guarded = FaultyTransport(inner, "a_km", control=False)
    sink: list[bytes] = []

    def cb(_k: str, p: bytes) -> None:
        sink.append(p)
        sink.clear()

    guarded.subscribe(KEY, cb)
    g = inner.callback
    assert g is not None
    direct_cb, guard_cb = per_call([lambda: cb(KEY, payload), lambda: g(KEY, payload)], n, r)
    print(
        f"3. subscriber callback: direct {direct_cb * 1e9:6.1f} ns, "
        f"through the guard {guard_cb * 1e9:6.1f} ns: "
        f"+{(guard_cb - direct_cb) * 1e9:.1f} ns"
    )
    guarded.close()

    import zenoh

    endpoint = f"tcp/127.0.0.1:{free_port()}"
    router = zenoh.open(router_config([endpoint]))
    zt = ZenohTransport([endpoint])
    zn = max(n // 50, 1000)
    layered_t = FaultyTransport(zt, "a_km", control=False)
    plain, layered = per_call(
        [lambda: zt.publish(KEY, payload), lambda: layered_t.publish(KEY, payload)], zn, r
    )
    print(
        f"4. Zenoh put ({zn} calls): direct {plain * 1e6:6.2f} µs, through the layer (no fault) "
        f"{layered * 1e6:6.2f} µs ({(layered - plain) / plain * 100:+.1f} %)"
    )
    layered_t.close()
    router.close()


if __name__ == "__main__":
    main()
