"""The gateway on a real router with access control: a JADE-like platform's
request (FIPA SC00084) reaches a_hi as a person's command would and its answers return; one to an
agent it may not address is refused and counted (the gateway's counters, as ``roco status`` asks
them); ``roco sniff`` shows the JADE-named agent's traffic; the router drops what the gateway's
identity may not put (C2, or posing as a_co on C8). One router process (spawned by the
launcher, ended by its PID); a_hi, a stand-in a_co, the gateway and the sniffer are sessions of
this process, each authenticated as itself."""

from __future__ import annotations

import json
import queue
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from services.agents.human_interface.agent import HumanInterface
from services.fleet.launcher import Fleet, free_port
from services.gateway.bridge import GATEWAY, open_gateway, summary
from services.runtime import keys
from services.runtime.agent import Agent
from services.runtime.counters import ask_counters
from services.runtime.session import open_client
from services.runtime.transport import ZenohTransport
from services.security.context import register
from services.sniff.sniffer import sniff
from services.spec.model import default_spec
from shared.fipa_codec import Performative
from shared.fipa_codec.languages.l_hc import CommandOutcome
from tests.agents.human_interface.test_agent import TIMEOUT, ScriptedCo
from tests.support.jade_platform import JADE, JadePlatform


@pytest.fixture
def fleet(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Fleet]:
    monkeypatch.delenv("ROCO_RUN_DIR", raising=False)
    monkeypatch.delenv("ROCO_KM_STORE", raising=False)
    (tmp_path / "logs").mkdir()
    fleet = Fleet(tmp_path, f"tcp/127.0.0.1:{free_port()}", acl=True)
    fleet.start_router()
    try:
        yield fleet
    finally:
        fleet.stop()
        register(fleet.endpoint, None)


@pytest.mark.requirement("R1.4")
def test_a_jade_request_crosses_the_gateway_under_access_control(fleet: Fleet) -> None:
    ep = fleet.endpoint
    agents: list[tuple[Agent, threading.Thread]] = []

    def start(agent: Agent) -> None:
        agent.engine.bind()
        t = threading.Thread(target=agent.engine.run, daemon=True)
        t.start()
        agents.append((agent, t))

    lines: queue.SimpleQueue[str] = queue.SimpleQueue()
    stop, ready = threading.Event(), threading.Event()
    sniffer = threading.Thread(
        target=sniff,
        args=(ep,),
        kwargs=dict(
            agents=None,
            channels={"C8"},
            performatives=None,
            conversation=None,
            out=lines.put,
            stop=stop,
            ready=ready,
        ),
        daemon=True,
    )
    sniffer.start()
    assert ready.wait(TIMEOUT)
    co = ScriptedCo(ZenohTransport([ep], identity="a_co"))
    start(co)
    start(HumanInterface(ZenohTransport([ep], identity="a_hi")))
    port = free_port()
    url = f"http://127.0.0.1:{port}/acc"
    gateway_transport = ZenohTransport([ep], identity=GATEWAY)
    gateway, server = open_gateway(gateway_transport, default_spec(), "127.0.0.1", port, url)
    jade = JadePlatform()
    try:
        assert co.subscribed.wait(TIMEOUT)
        content = json.dumps({"type": "sentence", "text": "bring me the cup"})
        assert jade.request(url, "a_hi", jade.acl("a_hi", content, "C1_jade")) == 200
        request = co.receive(Performative.REQUEST)
        cid = request.msg.conversation_id or ""

        def run(c: ScriptedCo) -> None:
            c.engine.reply(request, Performative.AGREE)
            c.engine.reply(
                request, Performative.INFORM, CommandOutcome(command_id=cid, succeeded=True, detail="done")
            )

        co.do(run)
        assert [jade.next().msg.performative for _ in range(2)] == [Performative.AGREE, Performative.INFORM]

        assert jade.request(url, "a_co", jade.acl("a_co", content, "C2_jade")) == 200
        assert jade.next().msg.performative is Performative.REFUSE
        session = open_client(ep)
        try:
            counters = ask_counters(session, {GATEWAY}, timeout=TIMEOUT)[GATEWAY].counters
        finally:
            session.close()
        assert counters["refused.receiver"] == 1 and counters["forwarded"] == 1
        assert "refused 1 (receiver 1)" in summary(counters)  # roco status's gateway line

        seen: list[str] = []
        wanted = {f"C8  {JADE} → a_hi", f"C8  a_hi → {JADE}"}
        while not all(any(w in line for line in seen) for w in wanted):
            seen.append(lines.get(timeout=TIMEOUT))

        # the router binds the gateway whatever it is told: a put on C2 (to a_co) or as a_co on
        # C8 is dropped; a marker put after them on the same session arrives, so they would have
        keys_seen: queue.SimpleQueue[str] = queue.SimpleQueue()
        watcher = open_client(ep)
        try:
            watcher.declare_subscriber("roco/**", lambda sample: keys_seen.put(str(sample.key_expr)))
            # the router learns of the new subscriber asynchronously: put the marker until one
            # arrives, so that what follows is routed to the watcher if the router lets it pass
            deadline = time.monotonic() + TIMEOUT
            while True:
                gateway_transport.session.put(keys.counters_key(GATEWAY), b"marker")
                try:
                    if keys_seen.get(timeout=0.2) == keys.counters_key(GATEWAY):
                        break
                except queue.Empty:
                    assert time.monotonic() < deadline, "the watcher never saw the gateway's marker"
            while not keys_seen.empty():
                keys_seen.get()
            forbidden = {keys.fipa_key("C2", JADE, "a_co"), keys.fipa_key("C8", "a_co", "a_hi")}
            for key in forbidden:
                gateway_transport.session.put(key, b"x")
            gateway_transport.session.put(keys.counters_key(GATEWAY), b"marker")
            arrived: list[str] = []
            while keys.counters_key(GATEWAY) not in arrived:
                arrived.append(keys_seen.get(timeout=TIMEOUT))
            assert not forbidden & set(arrived)
        finally:
            watcher.close()
    finally:
        stop.set()
        jade.close()
        server.stop()
        gateway.stop()
        for agent, _ in agents:
            agent.engine.stop()
        for agent, t in agents:
            t.join(timeout=TIMEOUT)
            agent.engine.transport.close()
        gateway_transport.close()
        sniffer.join(timeout=TIMEOUT)
