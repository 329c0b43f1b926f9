"""SPADE side of ``roco bench`` part 3: the same request/inform ping-pong and one-way
throughput as roco's messaging benchmark, between two SPADE agents in two processes through
SPADE's own XMPP server (``spade run``, pyjabber), all on this host.

Runs in the SPADE virtual environment (``.bench/spade-venv``, made by ``roco bench``), never
in roco's. Two processes, started by services/bench/spade.py:

- ``--role responder``: agent ``responder@localhost`` answers each ``request`` with an
  ``inform`` carrying the same body, and counts ``inform``s of the throughput test; when it
  has them all (or nothing came for 3 s) it tells the initiator the count and the time from
  the first to the last (``time.perf_counter``) in an ``inform`` whose thread is "tput-done".
  Prints ``ready`` on stdout once its agent has started.
- ``--role initiator``: agent ``initiator@localhost`` does ``--warmup`` then ``--round-trips``
  ping-pongs (send a ``request``, await the ``inform``; the time is taken around both), then
  sends ``--messages`` ``inform``s as fast as ``send`` returns and waits for the responder's
  count. Prints one JSON object: samples (s), count, span (s), versions.

Messages: ``spade.message.Message`` with ``metadata`` performative and protocol
(fipa-request / fipa-subscribe as in roco), ``body`` a string of ``--size`` characters.
Agents in separate processes, so SPADE's in-container shortcut (direct delivery between agents
of one process) does not apply: every message goes through the XMPP server. Registration:
``auto_register=True`` (XEP-0077 in-band registration against the in-memory database).

Usage (normally through ``roco bench --only spade``):
``python scripts/bench_spade.py --role responder --port 5222``
"""

from __future__ import annotations

import argparse
import asyncio
import json
import sys
import time
from importlib.metadata import version
from typing import Any

import spade
from spade.agent import Agent
from spade.behaviour import CyclicBehaviour, OneShotBehaviour
from spade.message import Message

STALL_S = 3.0


class Responder(Agent):
    """Answers requests; counts throughput informs."""

    expected = 0

    class Serve(CyclicBehaviour):
        async def on_start(self) -> None:
            self.count = 0
            self.first = 0.0
            self.last = 0.0

        async def run(self) -> None:
            agent: Any = self.agent
            timeout = STALL_S if self.count else 60.0
            msg = await self.receive(timeout=timeout)
            if msg is None:
                if self.count:
                    await self._report(agent)
                return
            if msg.get_metadata("performative") == "request":
                reply = msg.make_reply()
                reply.set_metadata("performative", "inform")
                reply.body = msg.body
                await self.send(reply)
                return
            now = time.perf_counter()
            if self.count == 0:
                self.first = now
            self.count += 1
            self.last = now
            if self.count >= agent.expected:
                await self._report(agent)

        async def _report(self, agent: Any) -> None:
            done = Message(to=f"initiator@{agent.jid.domain}", thread="tput-done")
            done.set_metadata("performative", "inform")
            done.body = json.dumps({"count": self.count, "span_s": self.last - self.first})
            await self.send(done)
            self.count = 0

    async def setup(self) -> None:
        self.add_behaviour(self.Serve())


class Initiator(Agent):
    """Does the ping-pong and the throughput test, then prints the figures."""

    settings: dict[str, int]
    result: dict[str, Any]

    class Drive(OneShotBehaviour):
        async def run(self) -> None:
            agent: Any = self.agent
            s = agent.settings
            to = f"responder@{agent.jid.domain}"
            body = "x" * s["size"]
            samples = []
            for i in range(s["warmup"] + s["round_trips"]):
                msg = Message(to=to, body=body)
                msg.set_metadata("performative", "request")
                msg.set_metadata("protocol", "fipa-request")
                t0 = time.perf_counter()
                await self.send(msg)
                answer = await self.receive(timeout=30)
                if answer is None:
                    agent.result = {"error": f"no inform to request {i} within 30 s"}
                    return
                if i >= s["warmup"]:
                    samples.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            for _ in range(s["messages"]):
                msg = Message(to=to, body=body)
                msg.set_metadata("performative", "inform")
                msg.set_metadata("protocol", "fipa-subscribe")
                await self.send(msg)
            sent_s = time.perf_counter() - t0
            done = await self.receive(timeout=120)
            if done is None:
                agent.result = {"error": "no count from the responder within 120 s"}
                return
            agent.result = {"samples_s": samples, "sent_s": sent_s, **json.loads(done.body)}

    async def setup(self) -> None:
        self.result = {}
        self.drive = self.Drive()
        self.add_behaviour(self.drive)


async def responder(port: int, messages: int) -> None:
    agent = Responder("responder@localhost", "bench", port=port)
    agent.expected = messages
    await agent.start(auto_register=True)
    print("ready", flush=True)
    while agent.is_alive():
        await asyncio.sleep(1)  # SPADE's idiom for an agent that runs until stopped


async def initiator(port: int, settings: dict[str, int]) -> None:
    agent = Initiator("initiator@localhost", "bench", port=port)
    agent.settings = settings
    await agent.start(auto_register=True)
    await agent.drive.join()
    result = {
        **agent.result,
        "spade": version("spade"),
        "pyjabber": version("pyjabber"),
        "slixmpp": version("slixmpp-multiplatform"),
        "python": sys.version.split()[0],
    }
    print(json.dumps(result), flush=True)
    await agent.stop()


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--role", choices=("responder", "initiator"), required=True)
    ap.add_argument("--port", type=int, default=5222)
    ap.add_argument("--size", type=int, default=200)
    ap.add_argument("--warmup", type=int, default=50)
    ap.add_argument("--round-trips", type=int, default=1000)
    ap.add_argument("--messages", type=int, default=5000)
    args = ap.parse_args()
    if args.role == "responder":
        spade.run(responder(args.port, args.messages))
    else:
        settings = {
            "size": args.size,
            "warmup": args.warmup,
            "round_trips": args.round_trips,
            "messages": args.messages,
        }
        spade.run(initiator(args.port, settings))
    return 0


if __name__ == "__main__":
    sys.exit(main())
