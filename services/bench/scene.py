"""The kitchen the planning and knowledge benchmarks give a_km, and how they give it: as a_ta
does, in a_km's C6 fipa-subscribe conversation (FIPA SC00035), after agreeing to it.

:func:`kitchen_update` is the default kitchen of ``roco run`` (velma/model/kitchen.xml in its
home posture with the content settled: ``velma.model.scene.initial_state``) as ag_ex's
ground truth observes it (``velma.executor.ground_truth``), turned into the inform a_ta
sends for an observation (``services.agents.task_executor.agent.observed_update``). A run's
camera estimates these poses (docs/bench/observe.md); plan #1 a_pl makes from them has the same
leaf states and actions (tests/bench/plan1_leaves.txt is a camera run's, and
services/bench/plan_check.py makes it from this scene).

:class:`SceneSource` plays a_ta's participant part on a Zenoh session: it answers a_km's
``subscribe`` with ``agree``, then ``inform`` with the scene (a_km re-sends the subscribe
until agreed, so a_km may start before or after it), and asks a_km over C6 (fipa-query, as
a_ta may) what it knows of the scene's objects.
"""

from __future__ import annotations

import itertools
import queue
import threading
import time
from typing import Any

from services.bench.setup_check import SetupRefused
from services.runtime import keys
from shared.fipa_codec import AgentIdentifier, Communicate, Performative, decode, encode
from shared.fipa_codec.batch import unpack
from shared.fipa_codec.languages import decode_content, encode_content
from shared.fipa_codec.languages.l_wm import Answer, ObjectQuery, WorldUpdate

KM_SUBSCRIPTION = "km-environment"
"""The conversation-id of a_km's subscription (services/agents/knowledge/agent.py ``setup``)."""
SCENE_OBJECTS = ("jar", "bowl")
"""The objects of the pour whose poses a_km must know before a figure is taken."""


def kitchen_update() -> WorldUpdate:
    """The C6 inform a_ta sends a_km for its first observation of the default kitchen (module
    docstring): every known object's pose and content, the grippers' grip frames, stamp 0 s.
    Takes about a second (compiling the kitchen, settling its content)."""
    from services.agents.task_executor.agent import observed_update
    from velma.executor.ground_truth import GroundTruth
    from velma.model.scene import initial_state, load_kitchen

    model = load_kitchen()
    return observed_update(GroundTruth(model).observe(initial_state(model)))


def communicate(
    sender: str, receiver: str, perf: Performative, content: Any = None, **kw: Any
) -> Communicate:
    """A communicate of O_RoCo with ``content`` (an L_* term, or None: empty) msgpack-encoded;
    ``kw`` its other FIPA parameters (protocol, conversation_id, reply_with, in_reply_to)."""
    language, body = encode_content(content) if content is not None else (None, b"")
    return Communicate(
        performative=perf,
        sender=AgentIdentifier(sender),
        receiver=(AgentIdentifier(receiver),),
        content=body,
        language=language,
        encoding="msgpack" if language else None,
        ontology="O_RoCo" if language else None,
        **kw,
    )


class SceneSource:
    """a_ta's participant part of a_km's C6 fipa-subscribe on a Zenoh ``session`` (module
    docstring). ``agree_first`` False plants the broken set-up (the inform sent at once, in the
    conversation a_km has not had agreed): for the tests that see the bench refuse it."""

    def __init__(self, session: Any, update: WorldUpdate, *, agree_first: bool = True) -> None:
        self.session = session
        self.update = update
        self.agree_first = agree_first
        self.informed = threading.Event()
        self._answers: queue.SimpleQueue[Communicate] = queue.SimpleQueue()
        self._ids = itertools.count(1)
        self._lock = threading.Lock()
        self._sub = session.declare_subscriber(keys.inbox_key("a_ta"), self._on_sample)

    def start(self) -> None:
        """Call once a_km is alive. The planted broken set-up sends its inform now."""
        if not self.agree_first:
            self._put(
                communicate(
                    "a_ta",
                    "a_km",
                    Performative.INFORM,
                    self.update,
                    protocol="fipa-subscribe",
                    conversation_id=KM_SUBSCRIPTION,
                    reply_with="a_ta-scene",
                )
            )
            self.informed.set()

    def _put(self, msg: Communicate) -> None:
        self.session.put(keys.fipa_key("C6", "a_ta", "a_km"), encode(msg))

    def _on_sample(self, sample: Any) -> None:  # a zenoh.Sample: a batch of communicates
        for raw in unpack(sample.payload.to_bytes()):
            msg = decode(raw)
            if msg.performative is Performative.SUBSCRIBE and self.agree_first:
                with self._lock:
                    self._agree_and_inform(msg)
            elif msg.protocol == "fipa-query":
                self._answers.put(msg)

    def _agree_and_inform(self, subscribe: Communicate) -> None:
        """As a_ta's ``_on_subscribe``: agree to the subscription, then inform the scene; a
        repeated subscribe (a_km's retry crossing the agree) is agreed to again, informed once."""
        n = next(self._ids)
        for perf, content in ((Performative.AGREE, None), (Performative.INFORM, self.update)):
            if perf is Performative.INFORM and self.informed.is_set():
                break
            self._put(
                communicate(
                    "a_ta",
                    "a_km",
                    perf,
                    content,
                    protocol="fipa-subscribe",
                    conversation_id=subscribe.conversation_id,
                    in_reply_to=subscribe.reply_with,
                    reply_with=f"a_ta-{perf.value}-{n}",
                )
            )
        self.informed.set()

    def ask(self, query: Any, timeout: float = 30.0) -> Communicate:
        """Ask a_km ``query`` (an L_WM query, query-ref over C6) and return its answer. Raises
        SetupRefused when none comes within ``timeout`` s."""
        cid = f"a_ta-scene-query-{next(self._ids)}"
        self._put(
            communicate(
                "a_ta",
                "a_km",
                Performative.QUERY_REF,
                query,
                protocol="fipa-query",
                conversation_id=cid,
                reply_with=cid,
            )
        )
        deadline = time.monotonic() + timeout
        while True:
            try:
                msg = self._answers.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                raise SetupRefused(
                    f"a_km did not answer {type(query).__name__} within {timeout:.0f} s"
                ) from None
            if msg.conversation_id == cid:
                return msg

    def wait_known(self, timeout: float = 60.0) -> dict[str, str]:
        """Wait for the scene to be sent, then ask a_km of each of :data:`SCENE_OBJECTS` (a_km
        answers in the order it takes its input: after it applied an update that came before).
        Returns what is missing, by object: {} when a_km knows every pose. Raises SetupRefused
        when the subscription was not agreed within ``timeout`` s."""
        if not self.informed.wait(timeout):
            raise SetupRefused(f"a_km did not subscribe to a_ta's updates within {timeout:.0f} s")
        missing = {}
        for name in SCENE_OBJECTS:
            why = pose_unknown(self.ask(ObjectQuery(name)), name)
            if why:
                missing[name] = why
        return missing

    def close(self) -> None:
        self._sub.undeclare()


def pose_unknown(answer: Communicate, name: str) -> str:
    """Why ``answer`` (a_km's to ``ObjectQuery(name)``) does not give ``name``'s pose; "" when
    it does."""
    if answer.performative is not Performative.INFORM_REF:
        reason = answer.content[:120].decode("utf-8", "replace") if not answer.language else ""
        return f"{answer.performative.value} {reason}".strip()
    got = decode_content(answer.language, answer.content) if answer.language else None
    if not isinstance(got, Answer) or not any(o.name == name and o.pose is not None for o in got.objects):
        return "no pose"
    return ""


def require_known(missing: dict[str, str]) -> None:
    """Raise SetupRefused naming what a_km does not know (``missing``, from
    :meth:`SceneSource.wait_known`); nothing when it is empty."""
    if missing:
        told = ", ".join(f"{n} ({why})" for n, why in missing.items())
        raise SetupRefused(f"a_km does not know the scene after it was given: {told}")
