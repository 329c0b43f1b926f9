"""``roco replay`` takes each input when it reached the agent and each peer's token when the agent
saw it, by cause and by the publishers' own timestamps, not when the recorder saw them.

Each record here is a_ta's start rewritten on purpose: a_km subscribes, a_ta agrees and asks ag_ex
for an observation with 3 s to answer (L_EX Observe: a reply-by deadline at 4 s), and passes the
answer on to a_km. Whether ag_ex's answer came before that deadline decides whether a_ta asks
again; whether ag_ex's token appeared before it decides whether a_ta subscribed to ag_ex's
power-ons first. The recorder may see either after a_ta acted on it: ag_ex's answer over a slow
path (a recorder under load, or across the link between two hosts), ag_ex's token because a token
carries no publisher's timestamp and reaches the recorder through the router while the agents
are linked directly."""

from __future__ import annotations

import json
from pathlib import Path

import msgspec
import pytest

from services.recorder.presence import PresenceEvent
from services.replay.driver import one_line, render, replay
from shared.fipa_codec import Communicate, Performative
from shared.fipa_codec.languages.l_ex import Observe, PowerOn, PowerOns
from shared.fipa_codec.languages.l_sd import Observation
from shared.fipa_codec.languages.l_wm import Subscription, WorldUpdate
from tests.support.messages import communicate
from tests.support.recorded_run import STARTED, write_presence, write_recorded_run

DEADLINE = 4.0
"""When a_ta's first observation request expires (s after ``STARTED``)."""


def _sub() -> Communicate:
    return communicate(
        Performative.SUBSCRIBE,
        "a_km",
        "a_ta",
        "fipa-subscribe",
        "km-env",
        Subscription(),
        reply_with="a_km-1",
    )


def _agree() -> Communicate:
    return communicate(
        Performative.AGREE,
        "a_ta",
        "a_km",
        "fipa-subscribe",
        "km-env",
        reply_with="a_ta-1",
        in_reply_to="a_km-1",
    )


def _ask(n: int, at: float, reply_by_s: float, objects: tuple[str, ...] = ()) -> Communicate:
    """a_ta's ``n``-th request of an observation, sent at ``at`` (s after ``STARTED``)."""
    ask = communicate(
        Performative.REQUEST,
        "a_ta",
        "ag_ex",
        "fipa-request",
        f"c-{n}",
        Observe(objects=objects),
        reply_with=f"a_ta-a{n}",
    )
    return msgspec.structs.replace(ask, reply_by=STARTED + at + reply_by_s)


def _seen(n: int) -> Communicate:
    """ag_ex's observation answering a_ta's ``n``-th request."""
    return communicate(
        Performative.INFORM,
        "ag_ex",
        "a_ta",
        "fipa-request",
        f"c-{n}",
        Observation(stamp=0.5, objects=()),
        reply_with=f"ag_ex-o{n}",
        in_reply_to=f"a_ta-a{n}",
    )


def _update() -> Communicate:
    return communicate(
        Performative.INFORM,
        "a_ta",
        "a_km",
        "fipa-subscribe",
        "km-env",
        WorldUpdate(stamp=0.5, objects=(), total_particles=0),
        reply_with="a_ta-u",
        in_reply_to="a_km-1",
    )


def _start(at: float = 1.0) -> list[tuple[float, Communicate, float | None]]:
    """a_km's subscription crossing at ``at`` and what a_ta sends at once: (crossed, communicate,
    sent; None: as it crossed)."""
    return [(at, _sub(), None), (at, _agree(), None), (at, _ask(1, at, 3.0), None)]


def _write(run: Path, traffic: list[tuple[float, Communicate, float | None]], alive: list[str]) -> Path:
    return write_recorded_run(run, [(t, m) for t, m, _ in traffic], alive, [s for _, _, s in traffic])


def _on_two_hosts(run: Path) -> Path:
    """``run`` as a run with a_ta and ag_ex on the robot's host and the recorder, a_km and a_co
    on the brain's (``hosts.json`` as services/hosts/fleet.py writes it)."""
    hosts = {
        "brain": {"processes": ["router_brain", "recorder", "a_km", "a_co"]},
        "robot": {"processes": ["router_robot", "ag_ex", "a_ta"]},
    }
    (run / "hosts.json").write_text(json.dumps({"hosts": hosts}))
    return run


@pytest.mark.parametrize("hosts", ["one", "one, sent again", "two"])
def test_an_answer_a_ta_had_before_its_deadline_goes_in_before_it_though_recorded_after(
    tmp_path: Path, hosts: str
) -> None:
    """ag_ex answers 10 ms before a_ta's deadline and a_ta passes the answer on to a_km at once;
    the recorder sees the answer after the deadline: 56 ms late on one host (under load), or on
    two hosts 20 ms late, as everything a_ta and ag_ex send (a_km's subscription reaches a_ta 20
    ms after it was sent). Taken when the recorder saw it, the replayed a_ta's deadline went
    first and it asked again (in a pour: every later request one behind the record's, the first
    difference "content: recorded LookAt, replayed Observe"). ``sent again``: a_km's subscription
    sent again after the deadline and recorded before the answer, which reached a_ta first."""
    if hosts.startswith("one"):
        traffic = [*_start(), (3.991, _update(), None), (4.046, _seen(1), 3.990)]
        if hosts == "one, sent again":
            traffic.insert(-1, (4.010, _sub(), None))
    else:
        link = 0.020
        start = [(1.0, _sub(), None), (1.0 + 2 * link, _agree(), 1.0 + link)]
        start.append((1.0 + 2 * link, _ask(1, 1.0 + link, 3.0), 1.0 + link))
        at = DEADLINE + link - 0.010  # before the deadline, a_ta's clock (it asked at 1.02 s)
        traffic = [*start, (at + link, _seen(1), at), (at + 0.001 + link, _update(), at + 0.001)]
    run = _write(tmp_path / "run", traffic, ["a_km", "a_co"])
    if hosts == "two":
        _on_two_hosts(run)
    result = replay(run, "a_ta")
    assert result.equal and not result.notes, render(result)
    assert (result.inputs, result.compared) == (3 if hosts == "one, sent again" else 2, 3)


def test_a_token_recorded_after_the_communicates_it_caused_appears_before_them(tmp_path: Path) -> None:
    """ag_ex's token appears at 3.98 s: a_ta subscribes to ag_ex's power-ons and sends its request
    again at once, then its deadline passes at 4 s and it asks anew. The recorder sees the token
    at 4.02 s, after all three (it sees ag_ex's answer 60 ms late too: that late it may see
    anything). Taken when the recorder saw it, the replayed a_ta asked anew before it subscribed;
    taken no later than the first communicate to ag_ex it may have caused, it reproduces."""
    token = 3.98
    subscribe = communicate(
        Performative.SUBSCRIBE,
        "a_ta",
        "ag_ex",
        "fipa-subscribe",
        "ta-power-ons",
        PowerOns(),
        reply_with="a_ta-p",
        reply_by=STARTED + token + 5.0,
    )
    agree = communicate(
        Performative.AGREE,
        "ag_ex",
        "a_ta",
        "fipa-subscribe",
        "ta-power-ons",
        reply_with="ag_ex-p1",
        in_reply_to="a_ta-p",
    )
    on = communicate(
        Performative.INFORM,
        "ag_ex",
        "a_ta",
        "fipa-subscribe",
        "ta-power-ons",
        PowerOn(world="w1"),
        reply_with="ag_ex-p2",
        in_reply_to="a_ta-p",
    )
    start = _start()
    traffic = [
        *start,
        (token, subscribe, None),
        (token, start[2][1], None),  # the request again, as ag_ex's token appeared
        (DEADLINE, _ask(2, DEADLINE, 3.0), None),
        (4.011, agree, None),
        (4.011, on, None),
        (4.56, _seen(2), 4.5),
        (4.501, _update(), None),
    ]
    run = _write(tmp_path / "run", traffic, ["a_km", "a_co"])
    first = PresenceEvent(name="a_km", alive=True, t=STARTED, seq=0, incarnation="test", snapshot=True)
    write_presence(
        run,
        [
            first,
            msgspec.structs.replace(first, name="a_co"),
            PresenceEvent(name="ag_ex", alive=True, t=STARTED + 4.02, seq=6, incarnation="test"),
        ],
    )
    result = replay(run, "a_ta")
    assert result.equal, render(result)
    assert result.compared == 5 and result.copies == (1, 1), render(result)


def _crossed(tmp_path: Path, again: tuple[str, ...]) -> Path:
    """ag_ex's answer sent 10 ms before a_ta's deadline but reaching a_ta after it, 30 ms after it
    was sent (when the recorder saw it): a_ta asked anew at its deadline (for ``again``) and
    took the late answer as its first observation."""
    traffic = [
        *_start(),
        (DEADLINE, _ask(2, DEADLINE, 3.0, again), None),
        (4.020, _seen(1), 3.990),
        (4.021, _update(), None),
    ]
    return _write(tmp_path / "run", traffic, ["a_km", "a_co"])


def test_an_answer_that_crossed_the_deadline_is_taken_when_the_recorder_saw_it_as_only_that_reproduces(
    tmp_path: Path,
) -> None:
    """The record allows the answer before the deadline (its timestamp) and after (the
    recorder's time); only the second reproduces the run, and the replay says it took it."""
    result = replay(_crossed(tmp_path, ()), "a_ta")
    assert result.equal and result.undecided is None, render(result)
    (note,) = [n for n in result.notes if "taken as reaching a_ta when the recorder saw it" in n]
    assert note.startswith("#4 ag_ex → a_ta inform (fipa-request) ") and "at 4.020 s, not at 3.990 s" in note


def test_a_replay_that_differs_in_either_order_says_it_cannot_decide_the_order(tmp_path: Path) -> None:
    """As above, but the record's second request asks for the jar: in the order by the answer's
    timestamp a_ta does not ask again, in the other it asks for the whole scene. The replay
    differs either way, and says it cannot decide when the answer came instead of reporting the
    differences of one order as findings."""
    result = replay(_crossed(tmp_path, ("jar",)), "a_ta")
    assert not result.equal and result.differences, render(result)
    assert result.undecided is not None and result.undecided.startswith(
        "whether #4 ag_ex → a_ta inform (fipa-request) reached a_ta at 3.990 s (sent then, by its path)"
    ), render(result)
    assert one_line(result).startswith("a_ta: cannot decide whether #4 ")
    assert "cannot decide the order of the run (1 difference(s) in the order taken)" in render(result)
