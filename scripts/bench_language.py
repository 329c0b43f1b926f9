"""How much of what people say a_hi understands as meant: figures over a corpus of sentences,
each with what it means, in the form of tests/agents/human_interface/corpus.toml (``say``, ``want``,
optionally ``urgent``, ``deadline_s``, ``read``; its header explains ``want``).

Each sentence is read as a_hi reads a line of its own (the stop check first, then language.py's
``interpret``), against the kitchen as O_RoCo states it (test_corpus_words.py ``outcome``), and
counted per group and in all:

- **commands as meant**: of the sentences that mean a command of a_pl's, the share read as that
  command (task, arguments, urgency, deadline; a typo said back);
- **must-refuse handled**: of the sentences to refuse or ask back, the share refused or asked back;
- **wrong commands**: sentences read as a command they do not mean (another task or object, or a
  command where a refusal or a question was meant); the target is 0, and each is printed;
- **typos handled**: of the sentences with a typo (``read``), the share corrected and said back,
  or named;
- **as meant**: every sentence, answered as it means.

Figures, not checks: nothing is asserted (test_corpus_words.py asserts its own corpus). A corpus
kept outside the project (``--file``, any number of times), such as sentences written by people
who did not write the grammar, is measured the same way; by default the project's two:
corpus.toml and other_hands.toml (sentences written by someone who read only README and docs/).

Usage: ``python scripts/bench_language.py [--file corpus.toml ...] [--show-wrong]``
"""

from __future__ import annotations

import argparse
import sys
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from services.agents.human_interface.intents import Command, NotUnderstood  # noqa: E402
from services.agents.planner.domain import TASKS  # noqa: E402
from tests.agents.human_interface.test_corpus_words import (  # noqa: E402
    CORPUS,
    OTHER_HANDS,
    Case,
    as_meant,
    load,
    outcome,
    typo_handled,
)

MUST_REFUSE = ("refuse", "ask", "named")
"""``want`` kinds a_hi must not turn into a command."""


@dataclass
class Tally:
    """The counts of one group of sentences."""

    sentences: int = 0
    as_meant: int = 0
    commands: int = 0
    commands_as_meant: int = 0
    must_refuse: int = 0
    refused: int = 0
    typos: int = 0
    typos_handled: int = 0
    wrong: list[str] = field(default_factory=list)

    def add(self, case: Case, got: object) -> None:
        kind = case.want.split()[0]
        meant = as_meant(case, got)  # type: ignore[arg-type]
        self.sentences += 1
        self.as_meant += meant
        if kind in TASKS:
            self.commands += 1
            self.commands_as_meant += meant
            if isinstance(got, Command) and not meant:
                self.wrong.append(f"{case.say!r}: means {case.want!r}, read as {got.goal}")
        if kind in MUST_REFUSE:
            self.must_refuse += 1
            self.refused += isinstance(got, NotUnderstood)
            if isinstance(got, Command):
                self.wrong.append(f"{case.say!r}: means {case.want!r}, read as {got.goal}")
        if case.read:
            self.typos += 1
            self.typos_handled += typo_handled(case, got)  # type: ignore[arg-type]

    def merge(self, other: Tally) -> None:
        for name in ("sentences", "as_meant", "commands", "commands_as_meant", "must_refuse", "refused"):
            setattr(self, name, getattr(self, name) + getattr(other, name))
        self.typos += other.typos
        self.typos_handled += other.typos_handled
        self.wrong += other.wrong


def _share(n: int, of: int) -> str:
    return f"{n}/{of} ({100 * n / of:.1f} %)" if of else "–"


def measure(paths: list[Path]) -> dict[str, Tally]:
    """The tallies per ``file: group`` of every sentence in ``paths``."""
    tallies: dict[str, Tally] = defaultdict(Tally)
    for path in paths:
        for case in load(path):
            tallies[f"{path.name}: {case.group}"].add(case, outcome(case.say))
    return dict(tallies)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--file", type=Path, action="append", help="a corpus (default: corpus.toml and other_hands.toml)"
    )
    parser.add_argument("--show-wrong", action="store_true", help="print every wrong command")
    args = parser.parse_args()
    paths = args.file or [CORPUS, OTHER_HANDS]
    for path in paths:
        if not path.is_file():
            print(f"bench_language: {path}: no such corpus file", file=sys.stderr)
            return 2
    try:
        tallies = measure(paths)
    except (ValueError, TypeError, KeyError) as exc:
        print(f"bench_language: a corpus file is not in corpus.toml's form: {exc}", file=sys.stderr)
        return 2
    total = Tally()
    print("| group | sentences | commands as meant | must-refuse handled | wrong commands | typos handled |")
    print("|---|---:|---:|---:|---:|---:|")
    for name, t in tallies.items():
        total.merge(t)
        print(
            f"| {name} | {t.sentences} | {_share(t.commands_as_meant, t.commands)} | "
            f"{_share(t.refused, t.must_refuse)} | {len(t.wrong)} | {_share(t.typos_handled, t.typos)} |"
        )
    print(
        f"| **all** | {total.sentences} | {_share(total.commands_as_meant, total.commands)} | "
        f"{_share(total.refused, total.must_refuse)} | {len(total.wrong)} | "
        f"{_share(total.typos_handled, total.typos)} |"
    )
    print(f"\nas meant: {_share(total.as_meant, total.sentences)}; wrong commands: {len(total.wrong)}")
    for line in total.wrong if args.show_wrong else total.wrong[:10]:
        print(f"  wrong: {line}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
