"""The Zenoh router process: ``python -m services.runtime.router [--listen EP]... [--connect EP]...``.

The eclipse-zenoh Python package runs a router by itself in mode "router" (no zenohd needed;
platform-notes.md). Defaults: listen on ``ROCO_LISTEN`` or ``tcp/0.0.0.0:7447``; ``--connect``
meshes it with other routers (a deployment over several hosts).
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
import threading
from types import FrameType

import zenoh

from services.runtime.transport import router_config


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="roco-router")
    parser.add_argument("--listen", action="append", default=None)
    parser.add_argument("--connect", action="append", default=None)
    args = parser.parse_args(argv)
    listen = args.listen or [os.environ.get("ROCO_LISTEN", "tcp/0.0.0.0:7447")]
    connect = args.connect or [e for e in os.environ.get("ROCO_CONNECT", "").split(",") if e]
    session = zenoh.open(router_config(listen, connect))
    done = threading.Event()

    def on_signal(signum: int, frame: FrameType | None) -> None:
        done.set()

    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)
    print(f"roco router {session.zid()} listening on {', '.join(listen)}", flush=True)
    done.wait()
    session.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
