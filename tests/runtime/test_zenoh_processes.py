"""Agents as separate OS processes over a Zenoh router on a loopback port: liveliness,
fipa-query answered, malformed bytes answered with not-understood, `roco status`."""

from __future__ import annotations

import queue
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
import zenoh

from services.fleet.launcher import Fleet, free_port
from services.runtime import keys
from services.runtime.session import alive_agents, open_client
from shared.fipa_codec import AgentIdentifier, Communicate, Performative, decode, encode
from shared.fipa_codec.languages import decode_content, encode_content
from shared.fipa_codec.languages.l_wm import Answer, ObjectQuery


@pytest.fixture
def fleet(tmp_path: Path) -> Iterator[tuple[Fleet, zenoh.Session]]:
    (tmp_path / "logs").mkdir()
    # forged traffic and tokens from the test: no access control (tested in tests/security/)
    f = Fleet(tmp_path, f"tcp/127.0.0.1:{free_port()}", acl=False)
    f.start_router()
    session = open_client(f.endpoint)
    f.start_agents(["a_km"])
    try:
        f.wait_alive(session, ["a_km"], timeout=60)
        yield f, session
    finally:
        session.close()
        f.stop()


def test_agent_process_answers_queries_and_rejects_garbage(fleet: tuple[Fleet, zenoh.Session]) -> None:
    f, session = fleet
    replies: queue.SimpleQueue[Communicate] = queue.SimpleQueue()
    session.declare_subscriber(
        keys.fipa_key("C4", "a_km", "a_pl"), lambda s: replies.put(decode(s.payload.to_bytes()))
    )
    lang, body = encode_content(ObjectQuery("jar"))
    q = Communicate(
        performative=Performative.QUERY_REF,
        sender=AgentIdentifier("a_pl"),
        receiver=(AgentIdentifier("a_km"),),
        content=body,
        language=lang,
        ontology="O_RoCo",
        protocol="fipa-query",
        conversation_id="c",
        reply_with="q1",
    )
    key = keys.fipa_key("C4", "a_pl", "a_km")
    session.put(key, b"\xc1not msgpack")
    nu = replies.get(timeout=10)
    assert nu.performative is Performative.NOT_UNDERSTOOD and b"malformed" in nu.content
    session.put(key, encode(q))
    answer = replies.get(timeout=10)
    assert answer.performative is Performative.INFORM_REF and answer.in_reply_to == "q1"
    content = decode_content(answer.language, answer.content)
    assert isinstance(content, Answer) and content.objects[0].name == "jar"
    assert f.processes["a_km"].poll() is None  # still running after bad input


def test_liveliness_and_status_command(fleet: tuple[Fleet, zenoh.Session]) -> None:
    f, session = fleet
    assert "a_km" in alive_agents(session)
    out = subprocess.run(
        [sys.executable, "-m", "services.cli", "status", "--router", f.endpoint],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert out.returncode == 1  # the other agents are absent
    assert "a_km      alive" in out.stdout and "a_co      absent" in out.stdout
    f.processes["a_km"].terminate()
    f.processes["a_km"].wait(timeout=10)
    assert "a_km" not in alive_agents(session)


def test_status_without_router_is_one_clear_line() -> None:
    out = subprocess.run(
        [sys.executable, "-m", "services.cli", "status", "--router", f"tcp/127.0.0.1:{free_port()}"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert out.returncode == 1
    assert out.stderr.strip().startswith("roco: no router answers at tcp/127.0.0.1:")
    assert len(out.stderr.strip().splitlines()) == 1
