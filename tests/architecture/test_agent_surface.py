"""An agent's author sees a small surface (services/runtime/agent.py): the declarations, the
hooks and a small context; everything else is its engine's (services/runtime/engine.py). The
surface is frozen here, and a round trip between two agents enters agent.py at most twice:
once in each agent's step that hands what arrived to its handlers (``handle_received``)."""

from __future__ import annotations

import sys
from collections.abc import Callable
from pathlib import Path
from types import FrameType
from typing import Any

from services.runtime import agent as agent_module
from services.runtime.memory_transport import MemoryBus
from services.spec_check.code_check import runtime_names
from tests.support.role_agents import SPEC, P, Scripted
from tests.support.role_initiator import Initiator
from tests.support.role_participant import Participant

MOST_INHERITED = 20
AUTHOR_SURFACE = frozenset(
    {
        # declarations (``name`` is the subclass's own: the base declares only its type)
        "ROLES",
        "NOTE",
        "period",
        "RECEIVE_INLINE",
        # hooks the engine calls
        "build_fsm",
        "setup",
        "peer_changed",
        "persist",
        "on_restored",
        # the context of the agent's code
        "engine",
        "log",
        "roles",
        "counters",
        "note",
        "sources",
        "peers",
        "r",
        "post",
        "emit",
        "handle_received",
    }
)
"""Every public name an agent's class inherits from ``Agent``: a name more is a decision (and a
line here), not a drift."""
AGENT_PY = str(Path(agent_module.__file__).resolve())


def test_an_agent_inherits_the_frozen_surface_and_no_more() -> None:
    public = {n for n in runtime_names() if not n.startswith("_")}
    assert public == AUTHOR_SURFACE
    assert len(AUTHOR_SURFACE) <= MOST_INHERITED


def entries_into_agent_py(work: Callable[[], object]) -> list[str]:
    """The functions of services/runtime/agent.py called from outside it while ``work`` runs
    (on this thread), in order."""
    entered: list[str] = []

    def profile(frame: FrameType, event: str, arg: Any) -> None:
        if event != "call" or frame.f_code.co_filename != AGENT_PY:
            return
        caller = frame.f_back
        if caller is None or caller.f_code.co_filename != AGENT_PY:
            entered.append(frame.f_code.co_name)

    sys.setprofile(profile)
    try:
        work()
    finally:
        sys.setprofile(None)
    return entered


def test_a_round_trip_enters_agent_py_at_most_twice() -> None:
    bus = MemoryBus()
    ini, par = Initiator(bus.transport(), SPEC), Participant(bus.transport(), SPEC)
    for a in (ini, par):
        a.engine.bind()
    for a in (ini, par):  # setup, liveliness, the first steps
        a.engine.drive()
    ini.do(lambda a: a.roles.open("C1", "fipa-query", None, performative=P.QUERY_REF))
    ini.engine.drive()  # opens the conversation: the query-ref is on the bus, in a_p's inbox
    assert par.engine._inbox

    def round_trip() -> None:
        par.engine.drive()  # a_p takes the query-ref in, its handler replies inform-ref
        ini.engine.drive()  # a_i takes the inform-ref in and hands it to its handler

    entered = entries_into_agent_py(round_trip)
    protocol, said, _conv = ini.seen.get_nowait()
    assert (protocol, said) == ("fipa-query", "inform-ref")
    assert entered == ["handle_received", "handle_received"]
    assert len(entered) <= 2


def test_the_trace_sees_an_agent_that_keeps_by_hand_enter_once_more_per_step() -> None:
    """The planted fault: an agent whose class defines ``persist`` again is called after every
    step; the trace counts it."""

    class KeepingParticipant(Participant):
        def persist(self) -> None:
            super().persist()

    class KeepingInitiator(Initiator):
        def persist(self) -> None:
            super().persist()

    bus = MemoryBus()
    ini = KeepingInitiator(bus.transport(), SPEC)
    par = KeepingParticipant(bus.transport(), SPEC)
    for a in (ini, par):
        a.engine.bind()
    for a in (ini, par):
        a.engine.drive()
    ini.do(lambda a: a.roles.open("C1", "fipa-query", None, performative=P.QUERY_REF))
    ini.engine.drive()
    entered = entries_into_agent_py(lambda: (par.engine.drive(), ini.engine.drive()))
    assert entered.count("persist") >= 2 and len(entered) > 2


assert issubclass(Initiator, Scripted) and issubclass(Participant, Scripted)
