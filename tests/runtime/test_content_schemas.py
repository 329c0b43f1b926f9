"""The specification's content schemas (``contents`` per performative on a channel protocol)
hold at run time: an agent's own code cannot send a term the specification does not list
(SpecViolation), and a received one is answered with not-understood."""

from __future__ import annotations

import pytest

from services.runtime.agent import SpecViolation
from services.runtime.memory_transport import MemoryBus
from shared.fipa_codec import Performative
from shared.fipa_codec.languages.l_wm import Answer, WorldUpdate


def test_sending_a_term_the_specification_does_not_list_raises() -> None:
    from services.agents.knowledge.agent import KnowledgeManager

    km = KnowledgeManager(MemoryBus().transport())
    with pytest.raises(
        SpecViolation, match="inform-ref to a_pl in fipa-query may carry Answer, not WorldUpdate"
    ):
        km.engine.send(
            "a_pl", Performative.INFORM_REF, WorldUpdate(stamp=0.0, objects=()), protocol="fipa-query"
        )
    assert km.counters["send_violations"] == 1
    km.close()


def test_the_listed_term_passes_the_content_check() -> None:
    from services.agents.knowledge.agent import KnowledgeManager

    km = KnowledgeManager(MemoryBus().transport())
    kinds = [k for k in km.engine.interface.sends if k.receiver == "a_pl" and k.performative == "inform-ref"]
    assert kinds and all(k.contents == ("Answer",) for k in kinds)
    assert type(Answer()).__name__ in kinds[0].contents
    km.close()
