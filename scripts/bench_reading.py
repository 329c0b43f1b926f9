"""a_hi's reading time against the length of a line: from 10 characters to the bound
(``MAX_LINE_CHARS``, services/runtime/human.py), and beyond it.

Builds a :class:`HumanInterface` on an in-memory bus (no a_co, no a_km: every line is read at
once with the kitchen's words, as when a_km is away) and times, with ``time.perf_counter``,
``repeats`` lines (after 3 warm-up ones) from their arrival to what a_hi does with them: the
stop check on a_hi's thread (``HumanInterface._on_input``, stop.py), then for a line within the
bound its parse in a_hi's reader thread (reading.py: language.py, lark's Earley parser; the
wait for it included) and a_hi acting on it (``_act_on_read``: the request to a_co or the
one-line answer); for a longer line its refusal, or its stop. Lines of three shapes, each cut
to the length (at a word):

- ``command``: "please please … pour the jar into the bowl" (the run of "please" is one token,
  grammar.py ``FOLDED``: a short command at any length);
- ``polite``: "please robot please robot … pour the jar into the bowl" (a token per word:
  parsed in full up to language.py's ``MAX_READ_TOKENS``, the slowest line read; past it,
  refused unparsed);
- ``words``: "the jar is on the table and the bowl …" (not understood at its second sentence);
- ``stop``: the same words ending "oh no, stop!" (a stop, found by the stop check alone);
- ``typo``: "please please … pour the jar itno the bowl" (a typo: corrected and read once more).

:func:`measure` returns, per shape and length, p50 / p99 in milliseconds, the stop check's
phrase look-ups (its work: linear in the length, and bounded beyond the bound) and what a_hi
did with the line (used by ``roco bench``'s ``reading`` part). Figures, not checks: nothing is
asserted.

Usage: ``python scripts/bench_reading.py [--repeats 50]``
"""

from __future__ import annotations

import argparse
import itertools
import logging
import statistics
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import benchlib  # noqa: E402  (scripts/benchlib.py, beside this file)

from services.agents.human_interface.agent import HumanInterface  # noqa: E402
from services.agents.human_interface.intents import Command, NotUnderstood, StatusRequest, Stop  # noqa: E402
from services.agents.human_interface.reading import Reading  # noqa: E402
from services.bench.messaging import percentile  # noqa: E402
from services.runtime.human import MAX_LINE_CHARS, HumanInput  # noqa: E402
from services.runtime.memory_transport import MemoryBus  # noqa: E402

LENGTHS = (10, 30, 100, 299, 312, MAX_LINE_CHARS, 4228, 100_000)
"""Line lengths (characters); 299: a ``polite`` line of ``MAX_READ_TOKENS`` tokens, the longest
parsed, and 312 two tokens past it."""
WORDS = "the jar is on the table and the bowl is next to it, "
SHAPES = {
    "command": ("please ", "pour the jar into the bowl"),
    "polite": ("please robot ", "pour the jar into the bowl"),
    "words": (WORDS, ""),
    "stop": (WORDS, "oh no, stop!"),
    "typo": ("please ", "pour the jar itno the bowl"),
}
READ_S = 60.0
TOO_MANY = "That is too long for one request"
"""How language.py's refusal of a line of more than ``MAX_READ_TOKENS`` tokens begins."""
EXPECTED = {"command": "read: a command", "polite": "read: a command", "typo": "read: a command"}
"""What a_hi must make of a line of these shapes that holds its whole command, within both
bounds (characters and tokens): the benchmark checks it, so that it times the work it names."""
"""s to wait for the reader thread to be done with one line."""


@dataclass(frozen=True)
class ReadingRow:
    """One shape and length: a_hi's time from a line's arrival to acting on it (ms)."""

    shape: str
    chars: int
    """the line's length (characters), as cut at a word"""
    p50_ms: float
    p99_ms: float
    lookups: int
    """the stop check's phrase look-ups on the line (stop.py ``StopWords.examined``)"""
    answer: str
    """what a_hi did: ``stop`` (found by the stop check), ``refused: too long``, or ``read: ``
    and the reader's outcome (``a command``, ``not understood``, …)"""


def line(shape: str, length: int) -> str:
    """A line of ``shape`` of at most ``length`` characters, its end kept, cut at a word."""
    pad, end = SHAPES[shape]
    full = pad * (length // len(pad) + 1) + end
    text = full[-length:]
    if full[-length - 1].isalnum() and text[0].isalnum() and " " in text:  # a word cut in two
        text = text[text.find(" ") + 1 :]
    return text.lstrip(" ,")


_IDS = itertools.count()
"""Request ids: each line opens a conversation of its own (FIPA SC00061: a conversation-id names
one conversation)."""


def reset(hi: HumanInterface) -> None:
    """Forget what the last line started (its request to a_co, its reports), so that every
    call reads against the same state."""
    for c in hi.commands.values():
        c.conversation.forget()
    hi.commands.clear()
    hi.asked.clear()
    hi.stops.clear()
    hi.reading.clear()
    hi.engine.y.clear()


def handle(hi: HumanInterface, event: HumanInput, read: threading.Event) -> list[Reading]:
    """What a_hi does with ``event``: the stop check and, for a line given to the reader, the
    wait for the reader (``read`` is set by its ``on_done``) and acting on the line. Returns
    the readings a_hi acted on."""
    read.clear()
    hi._on_input(event)
    given = list(hi.reading)
    if given:
        if not read.wait(READ_S):
            raise RuntimeError(f"a_hi's reader was not done with a line within {READ_S:.0f} s")
        hi._act_on_read()
    return given


def timed(hi: HumanInterface, text: str, repeats: int, read: threading.Event, warmup: int = 3) -> list[float]:
    """Milliseconds from handing ``text`` to :meth:`HumanInterface._on_input` to a_hi acting on
    it (:func:`handle`), ``repeats`` times after ``warmup``."""
    out = []
    for n in range(warmup + repeats):
        event = HumanInput(text=text, request_id=f"b{next(_IDS)}")  # a new conversation each
        t0 = time.perf_counter()
        handle(hi, event, read)
        elapsed = (time.perf_counter() - t0) * 1e3
        reset(hi)
        if n >= warmup:
            out.append(elapsed)
    return out


def answer(text: str, stop: bool, readings: list[Reading]) -> str:
    """What a_hi did with ``text`` (see :attr:`ReadingRow.answer`)."""
    if stop:
        return "stop"
    if len(text) > MAX_LINE_CHARS:
        return "refused: too long"
    outcomes = [r.outcome for r in readings]
    if not outcomes:
        return "read: nothing"
    if any(isinstance(o, NotUnderstood) and str(o).startswith(TOO_MANY) for o in outcomes):
        return "refused: too many tokens"
    named = {Command: "a command", Stop: "a stop", StatusRequest: "a status request"}
    return "read: " + ", ".join(
        "not understood" if isinstance(o, NotUnderstood) else named.get(type(o), type(o).__name__)
        for o in outcomes
    )


def measure(repeats: int, on_row: Callable[[ReadingRow], None] | None = None) -> list[ReadingRow]:
    """a_hi's reading time for every shape and length (``SHAPES``, ``LENGTHS``), ``repeats``
    timed lines each after 3 warm-up ones (see the module's docstring); ``on_row`` is called
    with each row as it is measured."""
    log = logging.getLogger("a_hi")
    level = log.level
    log.setLevel(logging.ERROR)  # "a_co is not known to be alive", per command
    read = threading.Event()
    try:
        hi = HumanInterface(MemoryBus().transport())
        hi.engine.bind()
        hi.setup()  # what a_hi's loop does first: the person's face, the reader (its models loaded)
        hi.reader.on_done = read.set  # in place of posting ReadDone to a_hi's own (unstarted) loop
        handle(hi, HumanInput(text="stop", request_id="warm-up"), read)  # the kitchen's words, loaded once
        reset(hi)
        rows = []
        for shape in SHAPES:
            for length in LENGTHS:
                text = line(shape, length)
                before = hi.stop_words.examined
                stop = hi.stop_words.match(text)
                work = hi.stop_words.examined - before
                readings = handle(hi, HumanInput(text=text, request_id=f"what{next(_IDS)}"), read)
                did = answer(text, stop is not None, readings)
                whole = SHAPES[shape][1] in text and len(text) <= MAX_LINE_CHARS  # the command in full
                if whole and shape in EXPECTED and not did.startswith("refused") and did != EXPECTED[shape]:
                    raise RuntimeError(f"a_hi made {did!r} of the {shape} line of {len(text)} characters")
                reset(hi)
                ms = timed(hi, text, repeats, read)
                p50, p99 = statistics.median(ms), percentile(ms, 99)
                rows.append(ReadingRow(shape, len(text), p50, p99, work, did))
                if on_row is not None:
                    on_row(rows[-1])
        return rows
    finally:
        log.setLevel(level)


def main() -> int:
    parser = argparse.ArgumentParser(description="a_hi's reading time against line length")
    parser.add_argument("--repeats", type=int, default=50, help="timed lines per shape and length")
    args = parser.parse_args()
    print(benchlib.machine(("lark",)))
    print(f"bound: {MAX_LINE_CHARS:,} characters; {args.repeats} lines each")
    print(f"{'shape':<8} {'chars':>8} {'p50 ms':>9} {'p99 ms':>9} {'look-ups':>9}  answer")

    def row(r: ReadingRow) -> None:
        print(f"{r.shape:<8} {r.chars:>8,} {r.p50_ms:>9.3f} {r.p99_ms:>9.3f} {r.lookups:>9}  {r.answer}")

    measure(args.repeats, row)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
