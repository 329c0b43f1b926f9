"""The walk-through of docs/spec.md ("Walk-through: adding an agent") as text edits, as a user
makes them: its TOML snippets added to a specification, its Python snippet in place of the
handlers ``roco spec new-agent`` writes. Used by tests/spec_check/test_walkthrough.py (stage by
stage) and tests/integration/test_new_agent.py (in a copy of the checkout, with a fleet)."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]
DOC = ROOT / "docs" / "spec.md"
AGENT = "a_wt"
MODULE = "services.agents.watch.agent"
GROUP_EDIT = {'group = "hi"': 'group = "ui"'}
"""Stage 2's edit of a_hi's entry: it substitutes ``ui`` now."""
IMPORTS = (
    "import math\n\n",
    "from shared.fipa_codec.languages.l_wm import Answer, ObjectInfo, SceneQuery\n",
)
"""What stage 3 imports (docs/spec.md says so beside the snippet)."""


def snippet(n: int, kind: str = "toml", doc: Path = DOC) -> str:
    """Walk-through snippet ``n`` of ``doc`` (a fenced block ```` ```KIND walkthrough-N ````)."""
    m = re.search(rf"```{kind} walkthrough-{n}\n(.*?)```", doc.read_text(), re.S)
    assert m, f"{doc} lost walk-through snippet {n}"
    return m.group(1)


def staged(text: str, *parts: str, edits: dict[str, str] | None = None) -> str:
    """Specification ``text`` with ``parts`` added (requirements and steps before the agents,
    as in the shipped file; the rest at its end) and each of ``edits`` made once."""
    for old, new in (edits or {}).items():
        assert text.count(old) == 1, old
        text = text.replace(old, new)
    head, tail = text.split("\n[[agents]]", 1)
    decomposition = "\n".join(p for p in parts if "[[steps]]" in p or "[[requirements]]" in p)
    rest = "\n".join(p for p in parts if p not in decomposition)
    return head + "\n" + decomposition + "\n[[agents]]" + tail + "\n" + rest


def fill(module: Path, doc: Path = DOC) -> None:
    """Write stage 3 into the agent ``roco spec new-agent`` wrote at ``module``: snippet 3 in
    place of ``_periodically`` and the handlers (the end of the class), and its imports."""
    text = module.read_text()
    start = text.index("    def _periodically(self) -> None:")
    text = text[:start] + snippet(3, "python", doc)
    future = "from __future__ import annotations\n\n"
    assert text.count(future) == 1 and text.count("from shared.fipa_codec import Performative") == 1
    text = text.replace(future, future + IMPORTS[0])
    line = next(
        x
        for x in text.splitlines(keepends=True)
        if x.startswith("from shared.fipa_codec import Performative")
    )
    text = text.replace(line, line + IMPORTS[1])
    module.write_text(text)
