"""a_hi's reader: the parse of a person's lines in a thread of its own, so that a stop is never
held back by the line before it.

Reading a 1,000-character line takes a_hi ≈ 0.25 s (``scripts/bench_reading.py``); read in the
agent's own thread, a stop that arrives meanwhile would wait for it. :class:`LineReader` reads
the lines given to it one after the other, in order, in one daemon thread, and calls
``on_done`` (from that thread) after each; the agent's thread goes on meanwhile, checks every
new line for a stop (stop.py) and marks the readings still under way ``stopped``. The two
threads share a line's :class:`Dialogue`: only the reader changes it while the line is read, and
the agent's thread resets its question of a stopped reading once the reader is done with it.
"""

from __future__ import annotations

import logging
import queue
import threading
from collections.abc import Callable
from dataclasses import dataclass

from services.agents.human_interface import inflection, similarity
from services.agents.human_interface.language import Dialogue, Intent, NotUnderstood, interpret
from services.agents.human_interface.task_grammar import Grammar
from services.agents.human_interface.vocabulary import Vocabulary
from services.runtime.agent import HumanInput

log = logging.getLogger(__name__)


@dataclass
class Reading:
    """A line given to the reader: ``outcome`` (the intent, or why it was not understood) once
    ``done``; ``stopped``: a stop came after it, so a_hi drops it instead of acting on it."""

    event: HumanInput
    dialogue: Dialogue
    done: bool = False
    outcome: Intent | NotUnderstood | None = None
    stopped: bool = False


class LineReader:
    """One daemon thread that reads lines with ``grammar`` (language.py :func:`interpret`), in
    the order :meth:`read` is called, and calls ``on_done()`` after each. Never raises from the
    thread: an error of the parse becomes a :class:`NotUnderstood` outcome (and is logged)."""

    def __init__(self, grammar: Grammar, on_done: Callable[[], None]) -> None:
        self.grammar = grammar
        self.on_done = on_done
        self._lines: queue.SimpleQueue[tuple[Reading, Vocabulary]] = queue.SimpleQueue()
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        """Start the reader's thread (if not started), which first loads the word-similarity
        model (similarity.py, ≈ 0.4 s) and the table of verb forms (inflection.py), so that the
        first line read does not wait for them."""
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name="a_hi-reader", daemon=True)
            self._thread.start()

    def read(self, reading: Reading, vocabulary: Vocabulary) -> None:
        """Read ``reading``'s line with ``vocabulary`` after the lines given before it."""
        self.start()
        self._lines.put((reading, vocabulary))

    def _run(self) -> None:
        try:
            similarity.load()
            inflection.load()
        except (ImportError, OSError):  # each line needing it is then refused, and logged
            log.exception("the word-similarity model or the verb forms did not load")
        while True:
            reading, vocabulary = self._lines.get()
            event = reading.event
            outcome: Intent | NotUnderstood
            try:
                outcome = interpret(
                    event.text,
                    priority=event.priority,
                    vocabulary=vocabulary,
                    dialogue=reading.dialogue,
                    grammar=self.grammar,
                )
            except NotUnderstood as exc:
                outcome = exc
            except Exception:  # a fault of the parse must not end the reader: the line is refused
                log.exception("reading %r failed", event.text[:80])
                outcome = NotUnderstood("I could not read that line; please say it differently.")
            reading.outcome = outcome
            reading.done = True
            self.on_done()
