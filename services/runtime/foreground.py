"""A bridge process in the foreground (``roco gateway``, ``roco ros2``): one-line logging on
stderr unless the program it runs in set its own, SIGINT and SIGTERM as its stop, one ``roco:``
line when it cannot start, a summary of its counters when it stops."""

from __future__ import annotations

import logging
import signal
import sys
import threading
from collections.abc import Callable
from types import FrameType

from services.runtime.log_format import OneLineFormatter

Counters = dict[str, int]


def run_until_stopped(
    name: str,
    serve: Callable[[threading.Event], Counters],
    errors: tuple[type[Exception], ...],
    summary: Callable[[Counters], str],
) -> int:
    """Call ``serve(stop)`` until SIGINT or SIGTERM sets ``stop``; print ``roco <name>:
    stopped; <summary(counters)>`` and return 0, or, when ``serve`` raises one of ``errors``
    (it could not start), ``roco: <name>: <error>`` on stderr and return 1."""
    if not logging.getLogger().handlers:  # run inside another program: its logging stays as it is
        handler = logging.StreamHandler(sys.stderr)
        handler.setFormatter(OneLineFormatter())
        logging.basicConfig(level=logging.INFO, handlers=[handler])
    stop = threading.Event()

    def on_signal(signum: int, frame: FrameType | None) -> None:
        stop.set()

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    try:
        counters = serve(stop)
    except errors as exc:
        print(f"roco: {name}: {exc}", file=sys.stderr)
        return 1
    print(f"roco {name}: stopped; {summary(counters)}", flush=True)
    return 0
