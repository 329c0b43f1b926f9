"""A delaying TCP relay: ``python -m services.hosts.relay --listen ADDR:PORT --to ADDR:PORT
--delay-ms D --jitter-ms J [--count FILE]``.

Used where the kernel has no ``sch_netem`` (no ``tc … netem``) to put a one-way delay of
``D ± J`` ms on each direction of the link between two routers: it accepts connections on
``--listen`` and forwards each to ``--to``, holding every chunk it reads for a delay drawn
uniformly from ``[D − J, D + J]`` before writing it on.

Simplifications (named in docs/deploy.md): the delay is per chunk read (one or more TCP
segments), not per packet; a chunk is never released before the one read before it (TCP
delivers bytes in order, so jitter that would reorder is absorbed as extra delay); the relay's
own TCP connections add nothing the link does not have (both ends are on one machine). Loss is
not the relay's: :mod:`services.hosts.link` drops packets on the link itself (nftables), and
TCP's retransmissions then cost what they cost on a real lossy link.

With ``--count FILE`` it measures what crosses: the bytes it forwards each way (the routers'
TLS stream: Zenoh's frames with the communicates, liveliness and keep-alives, TLS's records;
not TCP/IP's headers), summed per second of wall time and appended to FILE as one JSON object
per second in which anything crossed: ``{"t": POSIX s (the second's start), "up": bytes
client → server, "down": bytes server → client}``. In the two hosts (services/hosts/fleet.py)
the client is the robot's router: ``up`` is robot → brain. ``roco spec what-if`` predicts it
(docs/spec.md).
"""

from __future__ import annotations

import argparse
import asyncio
import json
import math
import random
import signal
import sys
import time
from collections import defaultdict
from pathlib import Path

CHUNK = 65536
QUEUE_CHUNKS = 256
"""Chunks held per direction before the reader waits (back-pressure, ≈ 16 MiB at most)."""
UP, DOWN = "up", "down"
"""The directions counted: client → server, server → client."""


class Counter:
    """Bytes forwarded per direction and second (:data:`UP`, :data:`DOWN`); :meth:`flush`
    appends the seconds that are over to ``path`` (None: nothing is counted)."""

    def __init__(self, path: Path | None) -> None:
        self.path = path
        self.seconds: dict[int, dict[str, int]] = defaultdict(lambda: {UP: 0, DOWN: 0})

    def add(self, direction: str, n: int) -> None:
        if self.path is not None:
            self.seconds[math.floor(time.time())][direction] += n

    def flush(self, *, everything: bool = False) -> None:
        """Append the seconds before the current one (``everything``: all) to the file."""
        if self.path is None:
            return
        now = math.floor(time.time())
        done = sorted(s for s in self.seconds if everything or s < now)
        if not done:
            return
        lines = "".join(json.dumps({"t": s, **self.seconds.pop(s)}) + "\n" for s in done)
        with self.path.open("a") as f:
            f.write(lines)


async def _pump(
    reader: asyncio.StreamReader,
    writer: asyncio.StreamWriter,
    delay_s: float,
    jitter_s: float,
    count: tuple[Counter, str] | None = None,
) -> None:
    held: asyncio.Queue[tuple[float, bytes]] = asyncio.Queue(QUEUE_CHUNKS)

    async def release() -> None:
        while True:
            due, data = await held.get()
            if not data:
                break
            wait = due - time.monotonic()
            if wait > 0:
                await asyncio.sleep(wait)
            writer.write(data)
            await writer.drain()
            if count is not None:
                count[0].add(count[1], len(data))

    releaser = asyncio.create_task(release())
    last = 0.0
    try:
        while True:
            data = await reader.read(CHUNK)
            due = max(
                last, time.monotonic() + max(0.0, random.uniform(delay_s - jitter_s, delay_s + jitter_s))
            )
            last = due
            await held.put((due, data))
            if not data:
                break
        await releaser
    except (ConnectionError, asyncio.CancelledError):
        pass
    finally:
        releaser.cancel()
        writer.close()


async def _serve(
    listen: tuple[str, int], to: tuple[str, int], delay_s: float, jitter_s: float, counter: Counter
) -> None:
    async def on_client(cr: asyncio.StreamReader, cw: asyncio.StreamWriter) -> None:
        try:
            ur, uw = await asyncio.open_connection(*to)
        except OSError:
            cw.close()
            return
        await asyncio.gather(
            _pump(cr, uw, delay_s, jitter_s, (counter, UP)), _pump(ur, cw, delay_s, jitter_s, (counter, DOWN))
        )

    async def flush_each_second() -> None:
        while True:
            await asyncio.sleep(1.0)
            counter.flush()

    server = await asyncio.start_server(on_client, *listen)
    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGTERM, signal.SIGINT):
        loop.add_signal_handler(sig, stop.set)
    print(
        f"roco relay {listen[0]}:{listen[1]} → {to[0]}:{to[1]}, "
        f"delay {delay_s * 1e3:.0f} ± {jitter_s * 1e3:.0f} ms",
        flush=True,
    )
    flusher = asyncio.create_task(flush_each_second())
    async with server:
        await stop.wait()
    flusher.cancel()
    counter.flush(everything=True)


def _addr(text: str) -> tuple[str, int]:
    host, _, port = text.rpartition(":")
    if not host or not port.isdigit():
        raise argparse.ArgumentTypeError(f"not ADDR:PORT: {text!r}")
    return host, int(port)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="roco-relay", description=__doc__.splitlines()[0])
    parser.add_argument("--listen", type=_addr, required=True)
    parser.add_argument("--to", type=_addr, required=True)
    parser.add_argument("--delay-ms", type=float, default=0.0)
    parser.add_argument("--jitter-ms", type=float, default=0.0)
    parser.add_argument("--count", type=Path, default=None, help="append the bytes forwarded per second here")
    args = parser.parse_args(argv)
    if args.delay_ms < 0 or args.jitter_ms < 0:
        parser.error("delay and jitter are ≥ 0")
    counter = Counter(args.count)
    asyncio.run(_serve(args.listen, args.to, args.delay_ms / 1e3, args.jitter_ms / 1e3, counter))
    return 0


if __name__ == "__main__":
    sys.exit(main())
