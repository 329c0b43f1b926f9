"""A second new agent, beside the walk-through's watcher, grown into a specification the way
docs/spec.md documents (a requirement, a decomposition step, the agent, its channels, its start),
with every number, group and channel read from the specification it is added to: ``a_sc``
asks a_km (fipa-query in L_WM, as a_hi does on C7) and tells the person things through a_hi
(roco-notify in L_HC, as a foreign agent does on C8). It splits a_km's group, so it can be added
before or after the watcher (which splits a_hi's). Its module is what ``roco spec new-agent``
writes for it with each handler written to log what came (:func:`fill_scratch`); a test names
its requirement (:func:`scratch_test`), as a system's own tests do. tests/integration/test_new_agent.py
adds both to a copy of the checkout and runs the fast part of roco's tests there;
scripts/check_growth.py runs all of them."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

from tests.spec_check.walkthrough import (
    channels_at,
    free_numbers,
    group_of,
    regrouped,
    requirement_test,
    staged,
    started_after,
)

SCRATCH = "a_sc"
PACKAGE = "services.agents.scratch"
"""The scratch agent's folder (its module ``agent.py`` is ``roco spec new-agent``'s)."""
GROUP = "sc"
REQUIREMENT = "a scratch agent asks a_km and tells the person through a_hi"
"""The text of the scratch agent's requirement."""
QUERY_PERFORMATIVES = (
    "query-ref", "query-if", "inform-ref", "inform", "failure", "refuse", "agree", "cancel",
)  # fmt: skip
QUERY_LANGUAGES = ", ".join(f'{p} = "L_WM"' for p in QUERY_PERFORMATIVES)
"""fipa-query's performatives in L_WM, as C7 declares them (each that may be sent has a language)."""


def _parts(text: str) -> tuple[str, str]:
    """The scratch agent's entries for specification ``text`` (the requirement and step; the
    agent and its channels) and a_km's group after the split."""
    data = tomllib.loads(text)
    n = free_numbers(text)
    km = group_of(data, "a_km")
    used = {g for s in data.get("steps", []) for g in (s.get("into") or [])} | {km}
    kept = next(f"{km}{i}" for i in range(2, 100) if f"{km}{i}" not in used)
    moved = "".join(f'  {{ number = {k}, from = "{km}", to = "{kept}" }},\n' for k in channels_at(data, km))
    to_km, to_hi = n.channel, n.channel + 1
    decomposition = f"""[[requirements]]
id = "{n.requirement}"
parent = "R"
text = "{REQUIREMENT}"

[[steps]]
number = {n.step}
requirements = ["{n.requirement}"]
split = "{km}"
into = ["{kept}", "{GROUP}"]
tasks = {{ {kept} = "the knowledge base", {GROUP} = "asks the knowledge base, tells the person" }}
reallocated = [
{moved}]
new_channels = [
  {{ number = {to_km}, ends = ["{GROUP}", "{kept}"], transmits = "questions to the knowledge base" }},
  {{ number = {to_hi}, ends = ["{GROUP}", "{n.hi_group}"], transmits = "notices to the person" }},
]
"""
    agent = f"""[[agents]]
name = "{SCRATCH}"
implementation = "{PACKAGE}.agent:Scratch"
group = "{GROUP}"
job = "scratch: asks a_km, tells the person through a_hi"

[[channels]]
name = "C{to_km}"
ends = ["{SCRATCH}", "a_km"]
transmits = "questions to the knowledge base"
  [[channels.protocols]]
  protocol = "fipa-query"
  initiator = "{SCRATCH}"
  languages = {{ {QUERY_LANGUAGES} }}
  contents = {{ query-ref = ["SparqlQuery"], inform-ref = ["Answer"] }}

[[channels]]
name = "C{to_hi}"
ends = ["{SCRATCH}", "a_hi"]
transmits = "notices to the person"
  [[channels.protocols]]
  protocol = "roco-notify"
  initiator = "{SCRATCH}"
  languages = {{ inform = "L_HC" }}
  contents = {{ inform = ["Notice"] }}
"""
    return decomposition + "\n" + agent, kept


def scratch_spec(path: Path, base: Path) -> Path:
    """Write to ``path`` the specification ``base`` with the scratch agent added: its entries,
    a_km substituting the group kept from the split, and ``a_sc`` started last (it asks a_km
    and a_hi; nobody asks it). Returns ``path``."""
    text = base.read_text()
    parts, kept = _parts(text)
    requirement, rest = parts.split("[[agents]]", 1)

    def edit(spec: str) -> str:
        order = tomllib.loads(spec)["start_order"]
        return started_after(regrouped(spec, "a_km", kept), order[-1], SCRATCH)

    path.write_text(staged(text, requirement, "[[agents]]" + rest, edit=edit))
    return path


def scratch_test(folder: Path, spec_text: str) -> Path:
    """Write the test naming the scratch agent's requirement in specification ``spec_text``
    into ``folder`` (:func:`~tests.spec_check.walkthrough.requirement_test`); returns its path."""
    return requirement_test(folder, spec_text, SCRATCH, REQUIREMENT)


def fill_scratch(module: Path) -> None:
    """Write the handlers ``roco spec new-agent`` left in the scratch agent's ``module``: each
    logs what a_km answered, where the stub raised NotImplementedError."""
    text, n = re.subn(
        r"raise NotImplementedError\(\n(?:\s+\".*\"\n)+\s+\)",
        'self.log.info("a_km answered %s", conv.content)',
        module.read_text(),
    )
    assert n > 0, f"{module}: no handler left to write"
    module.write_text(text)
