"""What the agents raised during a run, in one line: their error counters (a handler or a
transition function that raised, services/runtime/roles/ and agent.py) and the agents that
exited by themselves and were started again (services/scenario/runner.py).

The counters come from every agent's last counters report (services/runtime/counters.py,
``counters.json`` of a run folder); an agent started again counts from zero, so what the
process before it counted is in its log only (``logs/<agent>.log``: "stopping; counters …").
"""

from __future__ import annotations

from collections.abc import Mapping

RAISED = ("handler_errors", "behaviour_errors")
"""The counters of exceptions an agent caught and went on from: a handler of a communicate
(``handler_errors``) and a behaviour's transition function (``behaviour_errors``)."""

_WORDS = {"handler_errors": "handler error", "behaviour_errors": "behaviour error"}


def raised(counters: Mapping[str, int]) -> dict[str, int]:
    """The :data:`RAISED` counters above zero in one agent's ``counters``, by name."""
    return {k: counters[k] for k in RAISED if counters.get(k, 0) > 0}


def raised_by_agent(by_agent: Mapping[str, Mapping[str, int]]) -> dict[str, dict[str, int]]:
    """:func:`raised` of each agent's counters in ``by_agent``, for the agents that raised,
    in name order."""
    return {a: r for a, c in sorted(by_agent.items()) if (r := raised(c))}


def _counted(n: int, what: str) -> str:
    return f"{n} {what}{'s' if n != 1 else ''}"


def log_of(name: str) -> str:
    """The log of a fleet's process ``name`` in its run folder: ``logs/<name>.log``; a router
    writes only ``logs/<name>.stderr`` (services/fleet/launcher.py)."""
    return f"logs/{name}.stderr" if name.startswith("router") else f"logs/{name}.log"


def raised_text(by_agent: Mapping[str, Mapping[str, int]], crashed: Mapping[str, list[int]]) -> str:
    """One clause per agent that raised or exited, with its log:
    ``2 handler errors in a_ta: see logs/a_ta.log; a_co exited (code 70) and was started again:
    see logs/a_co.log``. ``by_agent``: :func:`raised_by_agent`; ``crashed``: each agent's exit
    codes of the exits nobody asked for. Empty when there is nothing to say."""
    parts = []
    for agent, found in sorted(by_agent.items()):
        counts = " and ".join(_counted(n, _WORDS.get(k, k)) for k, n in found.items() if n > 0)
        if counts:
            parts.append(f"{counts} in {agent}: see logs/{agent}.log")
    for agent, codes in sorted(crashed.items()):
        if codes:
            times = "" if len(codes) == 1 else f" {len(codes)} times"
            which = ", ".join(str(c) for c in codes)
            parts.append(f"{agent} exited{times} (code {which}) and was started again: see {log_of(agent)}")
    return "; ".join(parts)
