"""The router's restart is survived by every agent (docs/recovery.md, "Router restart").

A router on a loopback port is SIGKILLed by its PID and a new one is started on the same
endpoint. Client sessions configured by ``client_config`` reconnect by themselves, Zenoh
declares their subscribers and liveliness tokens again, and communication and the white pages
come back; real agent processes (a_km, a_pl) answer a planning request again without being
restarted. Every wait polls a condition against a deadline.
"""

from __future__ import annotations

import itertools
import json
import os
import queue
import signal
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
import zenoh

from services.fleet.launcher import Fleet, free_port
from services.runtime import keys
from services.runtime.session import alive_agents
from services.runtime.transport import ZenohTransport
from services.runtime.zenoh_config import CONNECT_RETRY, client_config
from shared.fipa_codec import AgentIdentifier, Communicate, Performative, decode, encode
from shared.fipa_codec.languages import decode_content, encode_content
from shared.fipa_codec.languages.l_hfsm import GroundTaskNetwork, HierarchicalPlan, TaskAtom

BACK_WITHIN_S = 10.0
"""Deadline for communication and liveliness to come back once the new router listens (the
retry schedule alone needs ≤ 1 s; the rest is margin for a loaded 2-core machine)."""


def wait_for(condition: Callable[[], bool], timeout: float, what: str, step: float = 0.02) -> float:
    """Poll ``condition`` until it holds; returns the seconds it took. Fails the test with
    ``what`` after ``timeout`` s."""
    t0 = time.monotonic()
    while not condition():
        if time.monotonic() - t0 > timeout:
            pytest.fail(f"not within {timeout:.0f} s: {what}")
        time.sleep(step)
    return time.monotonic() - t0


def kill_router(fleet: Fleet) -> None:
    """SIGKILL the fleet's router by its PID and reap it."""
    proc = fleet.processes["router"]
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait(timeout=10)


def zenoh_json(conf: zenoh.Config, key: str) -> object:
    return json.loads(conf.get_json(key))


@pytest.fixture
def fleet(tmp_path: Path) -> Iterator[Fleet]:
    (tmp_path / "logs").mkdir()
    # the transport's mechanics on keys outside the specification, the test playing a_co:
    # without access control (tested in tests/security/)
    f = Fleet(tmp_path, f"tcp/127.0.0.1:{free_port()}", acl=False)
    f.start_router()
    try:
        yield f
    finally:
        f.stop()


def test_client_config_reconnects_quickly() -> None:
    """Both client flavours (agents wait for the router, tools fail fast) carry the retry
    schedule that bounds reconnection after a router restart."""
    for wait in (True, False):
        conf = client_config(["tcp/127.0.0.1:7447"], wait_for_router=wait)
        assert zenoh_json(conf, "connect/retry") == CONNECT_RETRY
        assert zenoh_json(conf, "scouting/multicast/enabled") is False
    assert CONNECT_RETRY["period_max_ms"] <= 1000


def test_sessions_survive_router_restarts(fleet: Fleet) -> None:
    """Two transports as the agents use them: A subscribes and announces, B publishes and
    watches. After each of two router restarts, B's puts reach A again, B's watch sees A's
    token come back, and a liveliness query (also from a session opened after the restart)
    finds it."""
    a = ZenohTransport([fleet.endpoint])
    b = ZenohTransport([fleet.endpoint])
    try:
        received: set[bytes] = set()
        seen: list[tuple[str, bool]] = []
        lock = threading.Lock()

        def on_put(_key: str, payload: bytes) -> None:
            with lock:
                received.add(payload)

        def on_alive(key: str, alive: bool) -> None:
            with lock:
                seen.append((key, alive))

        a.subscribe("test/restart/a", on_put)
        a.announce(keys.alive_key("t_a"))
        b.watch(keys.alive_key("t_a"), on_alive)
        counter = itertools.count()

        def delivered(tag: bytes) -> Callable[[], bool]:
            def check() -> bool:  # re-sent on every poll: puts while disconnected are lost
                b.publish("test/restart/a", tag + b"/" + str(next(counter)).encode())
                with lock:
                    return any(p.startswith(tag + b"/") for p in received)

            return check

        def last_alive() -> bool | None:
            with lock:
                return seen[-1][1] if seen else None

        wait_for(delivered(b"before"), BACK_WITHIN_S, "B's put reaches A")
        wait_for(lambda: last_alive() is True, BACK_WITHIN_S, "B's watch sees A's token")
        wait_for(lambda: "t_a" in alive_agents(b.session), BACK_WITHIN_S, "liveliness get finds A")

        for restart in (1, 2):
            kill_router(fleet)
            # the loss is noticed at once (the killed process's sockets close): A looks gone
            wait_for(lambda: last_alive() is False, BACK_WITHIN_S, "B's watch sees A's token go")
            fleet.start_router()
            tag = f"after-{restart}".encode()
            took = wait_for(delivered(tag), BACK_WITHIN_S, f"B's put reaches A after restart {restart}")
            wait_for(lambda: last_alive() is True, BACK_WITHIN_S, f"A's token is back (restart {restart})")
            wait_for(lambda: "t_a" in alive_agents(b.session), BACK_WITHIN_S, "liveliness get finds A")
            fresh = zenoh.open(client_config([fleet.endpoint], wait_for_router=False))
            try:
                assert "t_a" in alive_agents(fresh), "a session opened after the restart sees A"
            finally:
                fresh.close()
            print(f"restart {restart}: communication back {took:.2f} s after the router listened")
    finally:
        a.close()
        b.close()


def plan_request(conversation: str) -> Communicate:
    lang, body = encode_content(
        GroundTaskNetwork(task_id=conversation, tasks=(TaskAtom("pour", ("jar", "bowl")),), plan_index=1)
    )
    return Communicate(
        performative=Performative.REQUEST,
        sender=AgentIdentifier("a_co"),
        receiver=(AgentIdentifier("a_pl"),),
        content=body,
        language=lang,
        ontology="O_RoCo",
        protocol="fipa-request",
        conversation_id=conversation,
        reply_with=f"{conversation}-q",
    )


def test_agent_pair_answers_after_router_restart(fleet: Fleet) -> None:
    """a_km and a_pl as OS processes; the test plays a_co. a_pl answers a planning request
    (for which it queries a_km over the router) before and after the router is SIGKILLed and
    started again; neither agent process is restarted."""
    session = zenoh.open(client_config([fleet.endpoint]))
    try:
        replies: queue.SimpleQueue[Communicate] = queue.SimpleQueue()
        sub = session.declare_subscriber(
            keys.fipa_key("C3", "a_pl", "a_co"), lambda s: replies.put(decode(s.payload.to_bytes()))
        )
        fleet.start_agents(["a_km", "a_pl"])
        fleet.wait_alive(session, ["a_km", "a_pl"], timeout=60)
        pids = {n: fleet.processes[n].pid for n in ("a_km", "a_pl")}

        def plan(conversation: str, timeout: float) -> HierarchicalPlan:
            """Request a plan (again every 2 s: a request put while the router is away is
            lost) until a_pl's answer to it arrives."""
            request = encode(plan_request(conversation))
            deadline = time.monotonic() + timeout
            next_send = 0.0
            while time.monotonic() < deadline:
                if time.monotonic() >= next_send:
                    session.put(keys.fipa_key("C3", "a_co", "a_pl"), request)
                    next_send = time.monotonic() + 2.0
                try:
                    answer = replies.get(timeout=0.1)
                except queue.Empty:
                    continue
                if answer.in_reply_to != f"{conversation}-q" or answer.performative is Performative.AGREE:
                    continue
                assert answer.performative is Performative.INFORM, answer
                assert answer.language is not None
                content = decode_content(answer.language, answer.content)
                assert isinstance(content, HierarchicalPlan)
                return content
            pytest.fail(f"no plan from a_pl for {conversation} within {timeout:.0f} s")

        assert plan("before", 60).km_queries > 0
        kill_router(fleet)
        fleet.start_router()
        t0 = time.monotonic()
        fleet.wait_alive(session, ["a_km", "a_pl"], timeout=BACK_WITHIN_S)
        after = plan("after", 60)
        assert after.km_queries > 0  # a_pl reached a_km through the new router
        print(f"agents alive again and plan answered {time.monotonic() - t0:.2f} s after restart")
        assert {n: fleet.processes[n].pid for n in pids} == pids
        assert all(fleet.processes[n].poll() is None for n in pids), fleet.dead()
        sub.undeclare()
    finally:
        session.close()
