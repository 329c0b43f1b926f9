"""ag_ex as an OS process over a Zenoh router on a loopback port (slow), beside the world
process the launcher starts before it: with the jar grasped and lifted, ag_ex holds position
and keeps the jar when a_ta's liveliness token goes away; killed (SIGKILL) or stopped
(SIGTERM) and started again, it attaches to the same world and finds the jar still in the
hand, where it was; the world's time went on (tests/velma/test_world_controller.py follows
the jar cycle by cycle across a kill)."""

from __future__ import annotations

import itertools
import math
import queue
import time
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path

import msgspec
import pytest
import zenoh

from services.fleet.launcher import Fleet, free_port
from services.runtime import keys
from services.runtime.protocol_state import expected_ontology
from services.runtime.session import open_client
from shared.fipa_codec import AgentIdentifier, Communicate, Performative, decode, encode
from shared.fipa_codec.languages import decode_content, encode_content
from shared.fipa_codec.languages.l_ex import CommandResult, Observe
from shared.fipa_codec.languages.l_sd import Observation
from tests.support.grasp import left_jar_grasp, left_jar_lift
from velma.executor.state import RobotSnapshot
from velma.scenario import script_poses

pytestmark = pytest.mark.slow

START = 180.0  # s for ag_ex to come up (it builds the scene; the machine may be busy)
COMMAND = 180.0  # s of wall time for one command's answer


class ATa:
    """a_ta's side of C5 in the test process: requests to ag_ex, its answers and its state."""

    def __init__(self, session: zenoh.Session) -> None:
        self.session = session
        self.replies: queue.SimpleQueue[Communicate] = queue.SimpleQueue()
        self.states: queue.SimpleQueue[RobotSnapshot] = queue.SimpleQueue()
        self._n = itertools.count(1)
        self._run = uuid.uuid4().hex[:8]
        states = msgspec.msgpack.Decoder(RobotSnapshot)
        self._subs = [
            session.declare_subscriber(
                keys.fipa_key("C5", "ag_ex", "a_ta"), lambda s: self.replies.put(decode(s.payload.to_bytes()))
            ),
            session.declare_subscriber(
                keys.state_key("ag_ex"), lambda s: self.states.put(states.decode(s.payload.to_bytes()))
            ),
        ]

    def request(self, command: msgspec.Struct) -> CommandResult | Observation:
        n = next(self._n)
        language, body = encode_content(command)
        msg = Communicate(
            performative=Performative.REQUEST,
            sender=AgentIdentifier("a_ta"),
            receiver=(AgentIdentifier("ag_ex"),),
            content=body,
            language=language,
            ontology=expected_ontology(language),
            protocol="fipa-request",
            conversation_id=f"restart-{self._run}-{n}",
            reply_with=f"r{n}",
        )
        self.session.put(keys.fipa_key("C5", "a_ta", "ag_ex"), encode(msg))
        deadline = time.monotonic() + COMMAND
        while True:
            reply = self.replies.get(timeout=max(0.0, deadline - time.monotonic()))
            if reply.in_reply_to == msg.reply_with:
                assert reply.language is not None
                content = decode_content(reply.language, reply.content)
                assert isinstance(content, CommandResult | Observation), content
                return content

    def ok(self, command: msgspec.Struct) -> CommandResult | Observation:
        result = self.request(command)
        assert not isinstance(result, CommandResult) or result.ok, (command, result)
        return result

    def observe(self) -> Observation:
        obs = self.request(Observe())
        assert isinstance(obs, Observation)
        return obs

    def state(self, until: Callable[[RobotSnapshot], bool], timeout: float = 60.0) -> RobotSnapshot:
        """The first published state (from now on) for which ``until`` holds."""
        deadline = time.monotonic() + timeout
        while True:
            snap = self.states.get(timeout=max(0.0, deadline - time.monotonic()))
            if until(snap):
                return snap

    def forget_states(self) -> None:
        while not self.states.empty():
            self.states.get_nowait()


def _jar(obs: Observation) -> tuple[float, float, float]:
    return next(o.pose.position for o in obs.objects if o.name == "jar")


@pytest.fixture
def fleet(tmp_path: Path) -> Iterator[tuple[Fleet, zenoh.Session]]:
    (tmp_path / "logs").mkdir()
    # forged traffic and tokens from the test: no access control (tested in tests/security/)
    # the ground truth perceives (ROCO_PERCEPTION=truth): the test follows the jar in the hand,
    # where the head camera does not localise it (docs/bench/observe.md)
    env = {"ROCO_PERCEPTION": "truth"}
    f = Fleet(tmp_path, f"tcp/127.0.0.1:{free_port()}", acl=False, env=env)
    f.start_router()
    session = open_client(f.endpoint)
    try:
        yield f, session
    finally:
        session.close()
        f.stop()


def _start_ag_ex(f: Fleet, session: zenoh.Session, a_ta: ATa) -> RobotSnapshot:
    """Start ag_ex and wait for its first published state (its loop runs)."""
    a_ta.forget_states()
    f.start_agents(["ag_ex"])
    f.wait_alive(session, ["ag_ex"], timeout=START)
    return a_ta.state(lambda s: True, timeout=START)


def test_the_world_survives_a_restart_of_ag_ex(fleet: tuple[Fleet, zenoh.Session]) -> None:
    f, session = fleet
    a_ta = ATa(session)
    token = session.liveliness().declare_token(keys.alive_key("a_ta"))
    first = _start_ag_ex(f, session, a_ta)
    assert first.held_object == {"right": None, "left": None}

    # grasp the jar with the left hand and lift it 10 cm (as tests/velma/test_velma_control.py)
    start = a_ta.observe()
    jar0 = _jar(start)
    poses = script_poses(start)
    for command in (*left_jar_grasp(poses), left_jar_lift(poses)):
        a_ta.ok(command)
    lifted = a_ta.observe()
    jar_up = _jar(lifted)
    assert jar_up[2] - jar0[2] > 0.07

    # a_ta's liveliness token goes away: ag_ex holds position and keeps the jar
    token.undeclare()
    held = a_ta.state(lambda s: s.holding == "a_ta lost")
    later = a_ta.state(lambda s: s.sim_time >= held.sim_time + 1.0)
    assert later.holding == "a_ta lost" and later.held_object["left"] == "jar"
    # joint impedance at the measured joints: the payload sags the hand by ≈ 1 cm, the jar with it
    assert math.dist(later.grip["left"].position, held.grip["left"].position) < 0.02
    jar_held = _jar(a_ta.observe())
    assert math.dist(jar_held, jar_up) < 0.02 and jar_held[2] - jar0[2] > 0.06

    # killed, started again: the same world, the jar still in the hand, where it was
    world = f.processes["world"]
    for how in ("SIGKILL", "SIGTERM"):
        proc = f.processes["ag_ex"]
        before = a_ta.observe()
        before_jar = _jar(before)
        if how == "SIGKILL":
            proc.kill()
        else:
            proc.terminate()
        assert proc.wait(timeout=60) is not None
        back = _start_ag_ex(f, session, a_ta)
        assert back.held_object["left"] == "jar", (how, back)  # read from the world's hand
        assert back.sim_time >= before.stamp, how  # the simulation went on from where it was
        jar_now = _jar(a_ta.observe())
        # the new controller takes the arm at its measured joints: the payload sags it ≈ 1 cm
        # (20.5 mm seen once in a loaded full suite); a dropped jar falls tens of cm
        assert math.dist(jar_now, before_jar) < 0.03, (how, jar_now, before_jar)
        assert jar_now[2] - jar0[2] > 0.05, how  # not back on the shelf
        assert world.poll() is None and f.processes["world"] is world, how  # never restarted
