"""The walk-through of docs/spec.md ("Walk-through: adding an agent") as text edits, as a user
makes them: its TOML snippets added to a specification, its terms module written in the agent's
folder, its Python snippet in place of the handlers ``roco spec new-agent`` writes. Used by
tests/spec_check/test_walkthrough.py (stage by stage) and tests/integration/test_new_agent.py
(in a copy of the checkout, with a fleet).

The document numbers its requirement, step and channels R4, 10, C10 (to a_km) and C11 (to a_hi),
the next free ones of the shipped specification, splits a_hi's group ``hi`` and reallocates its
channels C2, C7, C8 and C9. A specification that has grown since (an agent, a channel, a step
added the documented way) has other numbers, groups and channels; so the snippets are fitted to
the specification they are added to, read through its data (:func:`free_numbers`;
:data:`NEXT` for this checkout's), and stage 2's edits of the shipped entries are made where
the data puts them (:func:`group_edit`), not by matching their text."""

from __future__ import annotations

import json
import re
import sys
import tempfile
import tomllib
from collections.abc import Callable
from dataclasses import dataclass
from functools import cache
from pathlib import Path

import msgspec

from services.spec.decomposition import Decomposition, replay
from services.spec.model import DEFAULT_SPEC

ROOT = Path(__file__).resolve().parents[3]
DOC = ROOT / "docs" / "spec.md"
AGENT = "a_wt"
PACKAGE = "services.agents.watch"
"""The watcher's folder as the document names it (its agent and terms modules)."""
MODULE = f"{PACKAGE}.agent"
TERMS_MODULE = f"{PACKAGE}.terms"
UI = "ui"
"""The group a_hi substitutes once the walk-through split its own (stage 1's ``into``)."""
IMPORTS = (
    "import math\n\n",
    f"from {TERMS_MODULE} import Tipped\n",
    "from shared.fipa_codec.languages.l_wm import SceneChange, SceneSubscription\n",
)
"""What stage 3 imports (docs/spec.md says so beside the snippet): the standard library, the
agent's own terms (among the ``services`` imports), the codec's."""
RESUBSCRIBES = "reply_by_s=2.0, resubscribes=True"
"""What stage 3 adds to the subscription's role (docs/spec.md says so beside the snippet)."""


@dataclass(frozen=True)
class Numbers:
    """A top-level requirement id (``R4``), a decomposition step number, the number of the
    first of the two new channels (to a_km; the one to a_hi is the next), the group a_km
    substitutes (the first channel's other end), the group a_hi substitutes (the one stage 1
    splits) and the channels that end there (stage 1 reallocates each)."""

    requirement: str
    step: int
    channel: int
    km_group: str = "km"
    hi_group: str = "hi"
    hi_channels: tuple[int, ...] = (2, 7, 8, 9)

    @property
    def channel_name(self) -> str:
        """The channel to a_km's ``[[channels]]`` name: ``C10``."""
        return f"C{self.channel}"

    @property
    def notice_channel_name(self) -> str:
        """The channel to a_hi's ``[[channels]]`` name: ``C11``."""
        return f"C{self.channel + 1}"


AS_WRITTEN = Numbers("R4", 10, 10)
"""The numbers, groups and channels the document's snippets carry."""


def group_of(data: dict[str, object], agent: str) -> str:
    """The group ``agent`` substitutes in a specification's parsed ``data``."""
    agents = data.get("agents", [])
    assert isinstance(agents, list)
    return str(next(a["group"] for a in agents if a["name"] == agent))


def channels_at(data: dict[str, object], group: str) -> tuple[int, ...]:
    """The numbers of the channels that end at ``group`` after the last decomposition step of
    a specification's parsed ``data`` (services/spec/decomposition.py ``replay``)."""
    parts = {k: data[k] for k in ("system", "requirements", "steps") if k in data}
    states = replay(msgspec.convert(parts, Decomposition))
    final = states[-1].channels if states else {}
    return tuple(sorted(k for k, c in final.items() if group in c.ends))


def free_numbers(spec_text: str) -> Numbers:
    """The next free top-level requirement (``R<n>``), step and channel numbers of a
    specification's text (one past the largest of each; a channel's number from the steps'
    ``new_channels`` and the ``[[channels]]`` names), the groups a_km and a_hi substitute there
    and the channels that end at a_hi's."""
    data = tomllib.loads(spec_text)
    tops = [int(m[1]) for r in data.get("requirements", []) if (m := re.fullmatch(r"R(\d+)", r["id"]))]
    steps = [int(s["number"]) for s in data.get("steps", [])]
    made = [int(c["number"]) for s in data.get("steps", []) for c in s.get("new_channels", [])]
    named = [int(m[1]) for c in data.get("channels", []) if (m := re.fullmatch(r"C(\d+)", c["name"]))]
    top, step, channel = (max(numbers, default=0) + 1 for numbers in (tops, steps, made + named))
    hi_group = group_of(data, "a_hi")
    return Numbers(f"R{top}", step, channel, group_of(data, "a_km"), hi_group, channels_at(data, hi_group))


NEXT = free_numbers(DEFAULT_SPEC.read_text())
"""The walk-through's numbers in this checkout's specification."""


def renumbered(text: str, to: Numbers) -> str:
    """A snippet's ``text`` with :data:`AS_WRITTEN`'s requirement, step and two channel numbers
    replaced by ``to``'s (the steps' other channel numbers are kept), the new channel's end at
    a_km's group by ``to``'s, and the split of a_hi's group with its reallocations by ``to``'s
    (each channel that ends there moved to ``ui``)."""
    was = AS_WRITTEN
    text = text.replace(f'ends = ["wt", "{was.km_group}"]', f'ends = ["wt", "{to.km_group}"]')
    text = text.replace(f'split = "{was.hi_group}"', f'split = "{to.hi_group}"')
    moved = "".join(f'  {{ number = {k}, from = "{to.hi_group}", to = "{UI}" }},\n' for k in to.hi_channels)
    text = re.sub(r"(?ms)^reallocated = \[\n.*?^\]\n", lambda _: f"reallocated = [\n{moved}]\n", text)
    text = text.replace(f'"{was.requirement}"', f'"{to.requirement}"')
    text = re.sub(rf"(?m)^number = {was.step}$", f"number = {to.step}", text)
    numbers = {was.channel + k: to.channel + k for k in (0, 1)}
    text = re.sub(
        r"\{ number = (\d+), ends",
        lambda m: f"{{ number = {numbers.get(int(m[1]), int(m[1]))}, ends",
        text,
    )
    return re.sub(r"\bC(\d+)\b", lambda m: f"C{numbers.get(int(m[1]), int(m[1]))}", text)


def snippet(n: int | str, kind: str = "toml", doc: Path = DOC, numbers: Numbers | None = None) -> str:
    """Walk-through snippet ``n`` of ``doc`` (a fenced block ```` ```KIND walkthrough-N ````;
    ``terms``: the agent's terms module), renumbered to ``numbers`` (default :data:`NEXT`)."""
    m = re.search(rf"```{kind} walkthrough-{n}\n(.*?)```", doc.read_text(), re.S)
    assert m, f"{doc} lost walk-through snippet {n}"
    return renumbered(m.group(1), numbers or NEXT)


def regrouped(text: str, agent: str, group: str) -> str:
    """Specification ``text`` with ``agent`` substituting ``group``: the ``group`` line of its
    own ``[[agents]]`` table changed (found by the table's ``name``, whatever the file holds
    around it)."""
    for m in re.finditer(r"(?m)^\[\[agents\]\]\n", text):
        following = re.search(r"(?m)^\[", text[m.end() :])
        end = m.end() + following.start() if following else len(text)
        table = text[m.start() : end]
        if re.search(rf'(?m)^name = "{agent}"$', table):
            changed, n = re.subn(r'(?m)^group = "[^"]*"$', f'group = "{group}"', table)
            assert n == 1, table
            return text[: m.start()] + changed + text[end:]
    raise AssertionError(f"no [[agents]] table names {agent}")


def started_after(text: str, agent: str, new: str) -> str:
    """Specification ``text`` with ``new`` in ``start_order`` right after ``agent`` (the list
    read from the data, written back on one line)."""
    order = list(tomllib.loads(text)["start_order"])
    order.insert(order.index(agent) + 1, new)
    line = f"start_order = {json.dumps(order)}"
    changed, n = re.subn(r"(?ms)^start_order = \[.*?\]$", lambda _: line, text)
    assert n == 1, "start_order"
    return changed


def group_edit(text: str) -> str:
    """Stage 2's edits of the shipped entries: a_hi substitutes ``ui`` now, and the watcher,
    which asks a_hi, starts right after it (the agent started last waits for every other to be
    healthy, so none may ask it: services/deploy/compose.py ``_check_readiness``)."""
    return started_after(regrouped(text, "a_hi", UI), "a_hi", AGENT)


def staged(text: str, *parts: str, edit: Callable[[str], str] | None = None) -> str:
    """Specification ``text`` with ``parts`` added (requirements and steps before the agents,
    as in the shipped file; the rest at its end), then ``edit`` applied (e.g. :func:`group_edit`)."""
    if edit is not None:
        text = edit(text)
    head, tail = text.split("\n[[agents]]", 1)
    decomposition = "\n".join(p for p in parts if "[[steps]]" in p or "[[requirements]]" in p)
    rest = "\n".join(p for p in parts if p not in decomposition)
    return head + "\n" + decomposition + "\n[[agents]]" + tail + "\n" + rest


TERMS_PACKAGE = "walkthrough_watch"
"""The package the walk-through's terms module is imported as in a test process of this
checkout (:func:`shared_terms`): one ``Tipped`` class per process, so that loading the grown
specification again registers nothing new (shared/fipa_codec/languages/base.py ``extend``
skips a term it has)."""


@cache
def shared_terms() -> Path:
    """The folder, put first on ``sys.path`` once per process, that holds the walk-through's
    terms module (snippet ``terms`` of this checkout's document) as
    ``TERMS_PACKAGE.terms``: what a specification grown here names (:func:`entries`) and the
    agents written here import (:func:`fill`). A subprocess that loads such a specification
    needs it on its PYTHONPATH."""
    root = Path(tempfile.mkdtemp(prefix="roco-walkthrough-"))
    write_terms(root / TERMS_PACKAGE)
    sys.path.insert(0, str(root))
    return root


def entries(
    doc: Path = DOC, numbers: Numbers | None = None, agent: str = MODULE, terms: str | None = None
) -> str:
    """Stage 2's specification entries (snippet 2 of ``doc``, numbered ``numbers``) with the
    agent's implementation module ``agent`` and its terms module ``terms`` (default: the
    process's :func:`shared_terms`, ``TERMS_PACKAGE.terms``)."""
    if terms is None:
        shared_terms()
        terms = f"{TERMS_PACKAGE}.terms"
    return snippet(2, doc=doc, numbers=numbers).replace(MODULE, agent).replace(TERMS_MODULE, terms)


def walkthrough_spec(
    path: Path, base: Path = DEFAULT_SPEC, doc: Path = DOC, terms: str | None = None
) -> Path:
    """Write to ``path`` the specification ``base`` with ``doc``'s walk-through stages 1 and 2
    (the new agent a_wt, its protocol and its channels, numbered :func:`free_numbers` of
    ``base``; its terms module ``terms``, by default the process's :func:`shared_terms`: loading
    the specification imports it); returns ``path``."""
    text = base.read_text()
    numbers = free_numbers(text)
    stages = (snippet(1, doc=doc, numbers=numbers), entries(doc, numbers, terms=terms))
    path.write_text(staged(text, *stages, edit=group_edit))
    return path


def write_terms(folder: Path, doc: Path = DOC) -> Path:
    """Write stage 2's terms module (snippet ``terms`` of ``doc``) as ``folder``/terms.py, the
    folder made if it is not there (the agent's folder before ``roco spec new-agent``); returns
    its path."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "terms.py"
    path.write_text(snippet("terms", "python", doc))
    return path


def fill(module: Path, doc: Path = DOC, numbers: Numbers | None = None, terms: str | None = None) -> None:
    """Write stage 3 into the agent ``roco spec new-agent`` wrote at ``module``: snippet 3 (its
    channel numbered ``numbers``, default :data:`NEXT`) in place of ``_periodically`` and the
    handlers (the end of the class), its imports (``Tipped`` from the terms module ``terms``,
    by default the process's :func:`shared_terms`), and :data:`RESUBSCRIBES` in its
    subscription's role."""
    text = module.read_text()
    start = text.index("    def _periodically(self) -> None:")
    text = text[:start] + snippet(3, "python", doc, numbers)
    channel = (numbers or NEXT).channel_name
    role = f"initiator({channel}, FIPA_SUBSCRIBE, L_WM)"
    assert text.count(role) == 1, role
    text = text.replace(role, role[:-1] + ", " + RESUBSCRIBES + ")")
    future = "from __future__ import annotations\n\n"
    agents = [
        x for x in text.splitlines(keepends=True) if x.startswith("from services.runtime.agent import ")
    ]
    assert text.count(future) == 1 and len(agents) == 1, agents
    agent = agents[0]
    assert text.count("from shared.fipa_codec import Performative") == 1
    text = text.replace(future, future + IMPORTS[0])
    if terms is None:
        shared_terms()
        terms = f"{TERMS_PACKAGE}.terms"
    text = text.replace(agent, IMPORTS[1].replace(TERMS_MODULE, terms) + agent)
    line = next(
        x
        for x in text.splitlines(keepends=True)
        if x.startswith("from shared.fipa_codec import Performative")
    )
    text = text.replace(line, line + IMPORTS[2])
    module.write_text(text)


REQUIREMENT_TEST = '''"""{agent}'s requirement, named by a test as docs/spec.md asks of a new agent."""

import pytest


@pytest.mark.requirement("{requirement}")
def test_{agent}_is_in_the_specification() -> None:
    from services.spec.model import default_spec

    assert "{agent}" in [a.name for a in default_spec().agents]
'''
"""A test module marking a new agent's requirement (``roco spec trace``, test_trace.py)."""


def requirement_test(folder: Path, spec_text: str, agent: str, text: str) -> Path:
    """Write a test module naming the requirement of specification ``spec_text`` whose text
    begins with ``text`` (the one ``agent`` was added for) into ``folder``, as
    ``test_<agent>_requirement.py``; returns its path. Raises ValueError unless exactly one
    requirement's text begins so."""
    data = tomllib.loads(spec_text)
    (requirement,) = [r["id"] for r in data["requirements"] if r["text"].startswith(text)]
    path = folder / f"test_{agent}_requirement.py"
    path.write_text(REQUIREMENT_TEST.format(requirement=requirement, agent=agent))
    return path


WATCHER_REQUIREMENT = "warn the person when a thing of the kitchen is knocked over"
"""The text of the walk-through's requirement (its stage 1 snippet)."""
