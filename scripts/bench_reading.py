"""a_hi's reading time against the length of a line: from 10 characters to the bound
(``MAX_LINE_CHARS``, services/runtime/human.py), and beyond it.

Builds a :class:`HumanInterface` on an in-memory bus (no a_co, no a_km: every line is read at
once with the kitchen's words, as when a_km is away) and times, with ``time.perf_counter``,
``--repeats`` calls (after 3 warm-up calls) of what a_hi does on its thread when a line arrives
(``HumanInterface._on_input``): the stop check (stop.py), then for a line within the bound the
parse (language.py, lark's Earley parser) and the request to a_co or the one-line answer; for
a longer line its refusal, or its stop. Lines of three shapes, each cut to the length (at a word):

- ``command``: "please please … pour the jar into the bowl" (parsed in full: the slowest);
- ``words``: "the jar is on the table and the bowl …" (refused at its second sentence);
- ``stop``: the same words ending "oh no, stop!" (a stop, found by the stop check alone).

Prints p50 / p99 in milliseconds per shape and length, and the stop check's phrase look-ups
(its work: linear in the length, and bounded beyond the bound). Figures, not checks: nothing is
asserted.

Usage: ``python scripts/bench_reading.py [--repeats 50]``
"""

from __future__ import annotations

import argparse
import logging
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import benchlib  # noqa: E402  (scripts/benchlib.py, beside this file)

from services.agents.human_interface.agent import HumanInterface  # noqa: E402
from services.runtime.human import MAX_LINE_CHARS, HumanInput  # noqa: E402
from services.runtime.memory_transport import MemoryBus  # noqa: E402

LENGTHS = (10, 30, 100, 300, MAX_LINE_CHARS, 4228, 100_000)
WORDS = "the jar is on the table and the bowl is next to it, "
SHAPES = {
    "command": ("please ", "pour the jar into the bowl"),
    "words": (WORDS, ""),
    "stop": (WORDS, "oh no, stop!"),
}


def line(shape: str, length: int) -> str:
    """A line of ``shape`` of at most ``length`` characters, its end kept, cut at a word."""
    pad, end = SHAPES[shape]
    full = pad * (length // len(pad) + 1) + end
    text = full[-length:]
    if full[-length - 1].isalnum() and text[0].isalnum() and " " in text:  # a word cut in two
        text = text[text.find(" ") + 1 :]
    return text.lstrip(" ,")


def reset(hi: HumanInterface) -> None:
    """Forget what the last line started (its request to a_co, its reports), so that every
    call reads against the same state."""
    for c in hi.commands.values():
        c.conversation.abandon()
    hi.commands.clear()
    hi.asked.clear()
    hi.stops.clear()
    hi._y.clear()


def timed(hi: HumanInterface, text: str, repeats: int, warmup: int = 3) -> list[float]:
    """Milliseconds per :meth:`HumanInterface._on_input` of ``text``."""
    out = []
    for n in range(warmup + repeats):
        event = HumanInput(text=text, request_id=f"b{n}")
        t0 = time.perf_counter()
        hi._on_input(event)
        elapsed = (time.perf_counter() - t0) * 1e3
        reset(hi)
        if n >= warmup:
            out.append(elapsed)
    return out


def p99(ms: list[float]) -> float:
    ordered = sorted(ms)
    return ordered[min(len(ordered) - 1, round(0.99 * (len(ordered) - 1)))]


def main() -> int:
    parser = argparse.ArgumentParser(description="a_hi's reading time against line length")
    parser.add_argument("--repeats", type=int, default=50, help="timed calls per shape and length")
    args = parser.parse_args()
    logging.getLogger("a_hi").setLevel(logging.ERROR)  # "a_co is not known to be alive", per command
    print(benchlib.machine(("lark",)))
    hi = HumanInterface(MemoryBus().transport())
    hi.bind()
    hi._on_input(HumanInput(text="stop", request_id="warm-up"))  # the kitchen's words, loaded once
    reset(hi)
    print(f"bound: {MAX_LINE_CHARS:,} characters; {args.repeats} calls each")
    print(f"{'shape':<8} {'chars':>8} {'p50 ms':>9} {'p99 ms':>9} {'look-ups':>9}  answer")
    for shape in SHAPES:
        for length in LENGTHS:
            text = line(shape, length)
            before = hi.stop_words.examined
            stop = hi.stop_words.match(text)
            work = hi.stop_words.examined - before
            ms = timed(hi, text, args.repeats)
            if stop is not None:
                answer = "stop"
            elif len(text) > MAX_LINE_CHARS:
                answer = "refused: too long"
            else:
                answer = "read"
            p50 = statistics.median(ms)
            print(f"{shape:<8} {len(text):>8,} {p50:>9.3f} {p99(ms):>9.3f} {work:>9}  {answer}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
