"""Write a_hi's table of verb forms (services/agents/human_interface/verb_forms.json) from
LemmInflect's inflection tables (the ``lemminflect`` package, a dev dependency): every form
(past, participle, -s, -ing) of each one-word verb a_hi's grammar begins a command with
(tasks.toml and grammar.py, as ``default_grammar`` compiles them) and of the verbs that take
"you" and a bare verb after them (:data:`TELLING`: "I'm watching you pour …"), each mapped to
its base forms. a_hi reads the table, not LemmInflect, so that the 33 MiB of LemmInflect's
tables stay out of its process (services/agents/human_interface/inflection.py).

tests/agents/human_interface/test_verb_forms.py checks that the shipped table is this script's
output; after a verb is added to tasks.toml or grammar.py, run it again.

Usage: ``python scripts/verb_forms.py [--check]`` (``--check``: exit 1, saying so, when the
shipped table differs, writing nothing).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from services.agents.human_interface.inflection import TABLE  # noqa: E402
from services.agents.human_interface.task_grammar import default_grammar  # noqa: E402

TELLING = ("see", "watch", "hear", "notice", "feel", "observe", "let", "make", "help", "have")
"""Verbs of perceiving or causing, which take an object and a bare verb ("I saw you pour …")."""
FORMS = ("VBD", "VBN", "VBZ", "VBG")
"""Penn Treebank tags of the forms kept: past, past participle, third person -s, -ing."""


def verbs() -> list[str]:
    """The one-word verbs whose forms the table holds (module docstring), sorted."""
    grammar = default_grammar()
    first = {phrase[0] for phrase, kind in grammar.phrases.items() if kind in grammar.verb_kinds}
    return sorted(first | set(TELLING))


def table() -> dict[str, list[str]]:
    """Each form (lower case) and the base forms it is of, sorted; a verb's base form is left
    out (a_hi knows it)."""
    from lemminflect import getAllInflections

    out: dict[str, set[str]] = {}
    for verb in verbs():
        for tag, forms in getAllInflections(verb, upos="VERB").items():
            if tag in FORMS:
                for form in forms:
                    if form != verb:
                        out.setdefault(form.lower(), set()).add(verb)
    return {form: sorted(base) for form, base in sorted(out.items())}


def main() -> int:
    """Write the table (or, with ``--check``, say whether it is current); the exit status: 0, or
    1 when ``--check`` finds it out of date."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--check", action="store_true", help="only say whether the shipped table is current")
    args = ap.parse_args()
    text = "{\n" + ",\n".join(f"{json.dumps(k)}: {json.dumps(v)}" for k, v in table().items()) + "\n}\n"
    if args.check:
        current = TABLE.exists() and TABLE.read_text() == text
        state = "current" if current else "out of date: run scripts/verb_forms.py"
        print(f"{TABLE.relative_to(ROOT)}: {state}")
        return 0 if current else 1
    TABLE.write_text(text)
    print(f"wrote {TABLE.relative_to(ROOT)}: {text.count(chr(10)) - 2} forms")
    return 0


if __name__ == "__main__":
    sys.exit(main())
