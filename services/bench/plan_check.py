"""The plan the planning benchmark must time: plan #1 of the pour, as ``roco run "pour the jar
into the bowl"`` makes it.

:func:`expected_plan` makes it in this process with the agents' own code: a_km
(``KnowledgeManager``) holding the default kitchen (``services.bench.scene.kitchen_update``,
applied to its world model directly, not through the protocol the benchmark checks) and a_pl
(``Planner``) on an in-memory bus (services/runtime/memory_transport.py), asked for
``pour(jar, bowl)`` as a_co asks (C3 fipa-request, L_HFSM ground task network).
:func:`leaf_signature` says what two plans must share to be the same plan: their leaf states
in order, each with its path and action (the command and arm, or what is perceived,
asserted or checked), not the numbers (targets, durations) that follow from the exact poses.
tests/bench/plan1_leaves.txt holds the signature of plan #1 taken from a real run's traffic;
tests/bench/test_bench.py checks that :func:`expected_plan` still makes it.
"""

from __future__ import annotations

import contextlib
import queue
import threading
from collections.abc import Iterator

from services.bench.scene import communicate, kitchen_update
from services.bench.setup_check import SetupRefused
from services.runtime import keys
from services.runtime.agent import Agent
from shared.fipa_codec import Communicate, Performative, decode, encode
from shared.fipa_codec.languages import decode_content
from shared.fipa_codec.languages.l_ex import command_name
from shared.fipa_codec.languages.l_hc import TaskAtom
from shared.fipa_codec.languages.l_hfsm import (
    Assert,
    CheckContent,
    Execute,
    GroundTaskNetwork,
    HierarchicalPlan,
    Perceive,
    PlanNode,
)
from shared.fipa_codec.languages.l_wm import AnyQuery, HypotheticalQuery, WorldUpdate

POUR = TaskAtom("pour", ("jar", "bowl"))
Query = AnyQuery | HypotheticalQuery
"""An L_WM query a_pl sends a_km (fipa-query, C4)."""


def pour_request(n: int) -> bytes:
    """a_co's C3 fipa-request to a_pl for plan #1 of ``pour(jar, bowl)``, conversation
    ``bench-<n>`` (also its reply-with), encoded."""
    cid = f"bench-{n}"
    gtn = GroundTaskNetwork(task_id=cid, tasks=(POUR,))
    msg = communicate(
        "a_co",
        "a_pl",
        Performative.REQUEST,
        gtn,
        protocol="fipa-request",
        conversation_id=cid,
        reply_with=cid,
    )
    return encode(msg)


def _action(node: PlanNode) -> str:
    action = node.action
    if isinstance(action, Execute):
        arm = getattr(action.command, "arm", None)
        return f"{command_name(action.command)}{f' {arm}' if arm else ''}"
    if isinstance(action, Perceive):
        return f"perceive {' '.join(action.objects) or 'scene'}"
    if isinstance(action, Assert):
        return f"assert {action.subject} {action.relation} {action.object}".rstrip()
    if isinstance(action, CheckContent):
        return f"check_content {action.container}"
    return type(action).__name__


def leaf_signature(plan: HierarchicalPlan) -> tuple[str, ...]:
    """One line per leaf state of ``plan``, in execution order: ``<path>: <action>`` (module
    docstring), then ``complete: <True|False>``."""
    return (*(f"{path}: {_action(node)}" for path, node in plan.root.leaves()), f"complete: {plan.complete}")


@contextlib.contextmanager
def _running(*agents: Agent) -> Iterator[None]:
    """``agents`` bound and each running on a thread of its own inside the block; stopped and
    joined after it."""
    threads = [threading.Thread(target=a.engine.run, name=a.name, daemon=True) for a in agents]
    for a in agents:
        a.engine.bind()
    for t in threads:
        t.start()
    try:
        yield
    finally:
        for a in agents:
            a.engine.stop()
        for t in threads:
            t.join(timeout=5)


def _answer(answers: queue.SimpleQueue[bytes], timeout: float) -> Communicate:
    """a_pl's first answer to the plan request that is not its ``agree``. Raises SetupRefused
    when none comes within ``timeout`` s."""
    while True:
        try:
            msg = decode(answers.get(timeout=timeout))
        except queue.Empty:
            raise SetupRefused(f"a_pl made no plan in this process within {timeout:.0f} s") from None
        if msg.performative is not Performative.AGREE:
            return msg


def _plan_one(update: WorldUpdate | None, timeout: float) -> tuple[Communicate, list[bytes]]:
    """a_pl's answer to the plan request for plan #1 (module docstring), a_km knowing ``update``
    (default: the default kitchen), and what a_pl sent a_km on C4 meanwhile (encoded)."""
    from services.agents.knowledge.agent import KnowledgeManager
    from services.agents.planner.agent import Planner
    from services.runtime.memory_transport import MemoryBus

    bus = MemoryBus()
    km, pl = KnowledgeManager(bus.transport()), Planner(bus.transport())
    km.world.apply(update if update is not None else kitchen_update())
    answers: queue.SimpleQueue[bytes] = queue.SimpleQueue()
    asked: list[bytes] = []
    bus.subscribe(keys.fipa_key("C3", "a_pl", "a_co"), lambda _k, p: answers.put(p))
    bus.subscribe(keys.fipa_key("C4", "a_pl", "a_km"), lambda _k, p: asked.append(p))
    try:
        with _running(km, pl):
            bus.publish(keys.fipa_key("C3", "a_co", "a_pl"), pour_request(0))
            msg = _answer(answers, timeout)
    finally:
        km.close()
    return msg, asked


def expected_plan(update: WorldUpdate | None = None, timeout: float = 60.0) -> HierarchicalPlan:
    """Plan #1 of the pour made in this process (module docstring) with a_km knowing
    ``update`` (default: the default kitchen). Raises SetupRefused when a_pl answers without a
    plan or not within ``timeout`` s."""
    msg, _ = _plan_one(update, timeout)
    plan = decode_content(msg.language, msg.content) if msg.language else None
    if not isinstance(plan, HierarchicalPlan):
        raise SetupRefused(
            f"a_pl made no plan in this process: {msg.performative.value} {msg.content[:120]!r}"
        )
    return plan


def plan1_queries(update: WorldUpdate | None = None, timeout: float = 60.0) -> tuple[Query, ...]:
    """Every L_WM query a_pl sends a_km for plan #1, in order (the check of its steps in the
    hypothetical state, paper §5.7, among them), made in this process as :func:`expected_plan`
    makes the plan. Raises SetupRefused when a_pl made no plan."""
    msg, asked = _plan_one(update, timeout)
    if msg.performative is not Performative.INFORM:
        raise SetupRefused(f"a_pl made no plan in this process: {msg.performative.value}")
    out = []
    for payload in asked:
        sent = decode(payload)
        content = decode_content(sent.language, sent.content) if sent.language else None
        if sent.performative is Performative.QUERY_REF and isinstance(content, Query):
            out.append(content)
    return tuple(out)


def plan1_check(queries: tuple[Query, ...]) -> HypotheticalQuery:
    """The HypotheticalQuery among plan #1's ``queries`` (:func:`plan1_queries`). Raises
    SetupRefused when there is none."""
    for q in queries:
        if isinstance(q, HypotheticalQuery):
            return q
    raise SetupRefused("a_pl sent a_km no HypotheticalQuery for plan #1 in this process")


def require_same(timed: HierarchicalPlan, expected: HierarchicalPlan) -> None:
    """Raise SetupRefused (one line: the leaf counts and the first leaf that differs) unless
    ``timed`` has ``expected``'s :func:`leaf_signature`."""
    got, want = leaf_signature(timed), leaf_signature(expected)
    if got == want:
        return
    at = next(
        (i for i, (g, w) in enumerate(zip(got, want, strict=False)) if g != w), min(len(got), len(want))
    )

    def leaf(lines: tuple[str, ...]) -> str:
        return repr(lines[at]) if at < len(lines) else "(none)"

    first = f"leaf {at + 1}: {leaf(got)}, expected {leaf(want)}"
    raise SetupRefused(
        f"the timed plan is not plan #1 of the pour: {len(got) - 1} leaves, expected {len(want) - 1}; {first}"
    )
