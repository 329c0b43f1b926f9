"""ag_ex on the communication side (paper §5.3): the participant of fipa-request on C5.

It hands each L_EX command from a_ta to the hard-timing executor (``velma.executor``), whose
1 kHz control loop runs in a process of its own, and answers with the result: ``inform`` with
an L_EX CommandResult (or an L_SD Observation for ``observe``), or ``failure`` with the
CommandResult that says why. Results come back through the agent's receptor buffer; nothing
here blocks the loop. ``ROCO_REALTIME=1`` paces the loop to wall time.

a_ta's ``cancel`` (FIPA SC00026 §2; paper §3.2 safe interruption) halts its command
(velma/executor/loop.py ``ControlLoop.cancel``) and is answered ``inform`` with the
CommandResult ``halted`` (L_EX ``HALTED``) once the robot is at rest, or ``failure`` carrying
the command's own result when it ended before the halt began or the loop cannot be reached.

Besides C5, ag_ex publishes ``RobotSnapshot`` (msgpack) on ``roco/state/ag_ex`` every
``STATE_PUBLISH_S`` s; writes ``<ROCO_RUN_DIR>/ag_ex_timing.json`` every ``TIMING_FILE_PERIOD`` s
and at stop, ``ag_ex_perception.jsonl`` (each camera Observation beside the ground truth, for
the report; ``ROCO_PERCEPTION=truth`` answers from the physics) and ``ag_ex_ledger.jsonl``
(velma/executor/ledger.py: a request whose command ended in an earlier ag_ex is answered from
it, not run again); logs to Rerun with ``ROCO_RERUN=1``; holds position in joint impedance,
hands as they are, when a_ta's liveliness token goes away; re-attaches a new loop when the
world process (velma/world/) is started anew, telling a_ta by ``PowerOn`` (fipa-subscribe on
C5); and watches with the head camera while a_ta subscribes to it (fipa-subscribe on C5, L_EX
``Watch``: services/agents/executor/watching.py, velma/executor/watch.py). How and why:
docs/executor.md ("A halt", "When a_ta disappears", "The world as its own process",
"Restart", "The watch") and docs/recovery.md.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import msgspec

from services.agents.executor.watching import Frame, WatchService
from services.runtime.agent import FSM, Agent, Behaviour, Received, Transport, encode_sim_time, keys
from services.runtime.roles import PARTICIPANT, Conversation, handles, participant
from services.spec.model import SystemSpec
from services.spec.names import C5, FIPA_REQUEST, FIPA_SUBSCRIBE, L_EX, L_SD
from shared.fipa_codec import Performative
from shared.fipa_codec.languages.l_ex import (
    COMMANDS,
    HALTED,
    CommandResult,
    PowerOn,
    PowerOns,
    Watch,
    command_name,
)
from shared.fipa_codec.languages.l_sd import Observation
from shared.settings import Settings
from velma.executor.capture import PERCEPTION_LOG, WorldCapture
from velma.executor.ledger import LEDGER_FILE, Answer, Ledger, Recalled, recall
from velma.world.files import LinkWatch
from velma.world.mode import world_in_process

STATE_PUBLISH_S = 0.05
"""s between robot-state publications on Zenoh (20 Hz); the loop writes the state it reads every
``STATE_PERIOD`` cycles (velma/executor/loop_wire.py)."""
TIMING_FILE_PERIOD = 5.0  # s between writes of ag_ex_timing.json
TIMING_FILE = "ag_ex_timing.json"
WORLD_WAIT_S = 120.0
"""How long (s) ag_ex waits for the world process to name its link."""


@dataclass(frozen=True)
class Done:
    """A command's result from the loop, with the request it answers."""

    request: Conversation
    result: CommandResult | Observation
    world: str = ""
    """The world the loop that answered was attached to ("": none named)."""


@dataclass
class Running:
    """What ag_ex keeps of a request it passed to the executor (``Conversation.data``): the
    command's name, the executor's ``token`` for it (None: the executor cannot cancel) and
    a_ta's ``cancel`` awaiting its answer (None: none)."""

    command: str
    token: object | None = None
    cancel: Received | None = None


class Disturbance(msgspec.Struct, frozen=True, forbid_unknown_fields=True):
    """What ``roco/sim/disturb`` carries (JSON): move free body ``object`` by ``delta``
    (world, m) and turn it by ``tilt`` (rad) about the world's x axis through its origin (a
    knock that tips it over). A disturbance of the simulated world — a person moving an
    object — used by scenarios and ``roco disturb``; a real robot has no such input."""

    object: str
    delta: tuple[float, float, float]
    tilt: float = 0.0


@dataclass(frozen=True)
class Began:
    """The loop started the command of executor token ``token`` at ``sim_time`` (s)."""

    token: object
    command: str
    sim_time: float


@dataclass(frozen=True)
class Ended:
    """The loop ended the command of executor token ``token`` at ``sim_time`` (s) with
    ``outcome`` (velma/executor/ledger.py ``outcome_of``) and ``result`` (None: not known)."""

    token: object
    command: str
    sim_time: float
    outcome: str
    result: Answer | None = None


@dataclass(frozen=True)
class PeerChange:
    """A commanding agent's liveliness token appeared (``alive``) or disappeared."""

    agent: str
    alive: bool


class ExecutorAgent(Agent):
    name = "ag_ex"
    ROLES = (participant(C5, FIPA_REQUEST, L_EX, L_SD), participant(C5, FIPA_SUBSCRIBE, L_EX, L_SD))
    period = STATE_PUBLISH_S

    def make_executor(self) -> Any:
        """The hard-timing executor this agent serves: velma's loop in its own process, paced
        to wall time when ROCO_REALTIME=1; ROCO_SEED (default 0) jitters the jar's content,
        ROCO_POSE_SEED (unset: none) randomises the jar and bowl poses; the loop publishes
        the whole simulation state for the watch (the camera perceives) and Rerun's head
        camera (``camera_wanted``)."""
        from velma.executor import ExecutorProcess
        from velma.executor.capture import perception_mode

        read = Settings.from_env(only=("seed", "pose_seed", "realtime"))  # ValueError: a bad seed
        world = self._world_link() if world_in_process() else None
        rerun_camera = self.engine.hooks.camera_wanted() if self.engine.hooks else False
        return ExecutorProcess(
            realtime=read.realtime,
            seed=read.seed,
            pose_seed=read.pose_seed,
            world_state=rerun_camera or perception_mode() == "camera",
            perception=None,  # ROCO_PERCEPTION, else velma/executor/capture.py DEFAULT_PERCEPTION
            perception_log=self._perception_sink(),
            camera_idle_s=None,  # ROCO_CAMERA_IDLE_S, else velma/executor/camera_process.py DEFAULT_IDLE_S
            world_link=world,
        )

    @staticmethod
    def _world_link() -> str:
        """The robot link of the run's world process, as it writes it
        in the run folder once it runs (velma/world/files.py ``link_name``). Raises RuntimeError
        without a run folder, or when no world names its link within ``WORLD_WAIT_S``."""
        from velma.world.files import link_name

        run_dir = Settings.from_env(only=("run_dir",)).run_dir
        if run_dir is None:
            variable = Settings.env_name("run_dir")
            raise RuntimeError(f"the world process names its link in {variable}, which is not set")
        deadline = time.monotonic() + WORLD_WAIT_S
        while (name := link_name(run_dir)) is None:
            if time.monotonic() > deadline:
                raise RuntimeError(f"no world named its link in {run_dir} within {WORLD_WAIT_S:.0f} s")
            time.sleep(0.05)
        return name

    @staticmethod
    def _perception_sink() -> Callable[[list[dict[str, Any]]], None] | None:
        """Appends perception records as JSON lines to ``<ROCO_RUN_DIR>/ag_ex_perception.jsonl``
        (None when ROCO_RUN_DIR is unset). Called from the executor's delivery thread only."""
        run_dir = Settings.from_env(only=("run_dir",)).run_dir
        if run_dir is None:
            return None
        path = run_dir / PERCEPTION_LOG

        def write(records: list[dict[str, Any]]) -> None:
            with path.open("a", encoding="utf-8") as f:
                f.writelines(json.dumps(r) + "\n" for r in records)

        return write

    def __init__(self, transport: Transport, spec: SystemSpec | None = None) -> None:
        """ag_ex's memory (paper §3.2: the agent's internal memory), then the runtime's
        (:class:`~services.runtime.agent.Agent`), which builds the FSM, then what needs the
        runtime: the executor (:meth:`make_executor`; its errors raised), the agents that
        command ag_ex, the watch of the world's link and a viewer's robot."""
        self.ledger: Ledger | None = None
        self.ledger_runs: dict[object, str] = {}
        """Executor token → conversation-id of each command with the loop (for the ledger)."""
        self.recalled: dict[str, Recalled] = {}
        """Conversation-id → command an earlier ag_ex's loop ended, with its result (the ledger)."""
        self.camera_feed: Any = None
        """The head camera's images on Zenoh (``_start_feed``), or None."""
        self.watchers: dict[str, Conversation] = {}
        """Per agent, its subscription to the robot's power-ons (L_EX ``PowerOns``)."""
        self.alive_peers: set[str] = set()  # commanding agents whose liveliness token is present
        self._next_state = 0.0  # when the robot's state is next published (time.monotonic s)
        self._next_timing_file = 0.0  # when the timing file is next written (time.monotonic s)
        self._encode = msgspec.msgpack.Encoder().encode  # the robot's state for its key
        super().__init__(transport, spec)
        self.watch = WatchService(self.post, self.log)
        """The watch a_ta subscribed to (L_EX ``Watch``), served through the receptor buffer."""
        self.executor = self.make_executor()
        self.commanders = self._commanders()
        self.link_watch = self._link_watch()
        self.rerun = self.engine.hooks.robot(self.name) if self.engine.hooks else None  # a viewer

    def build_fsm(self) -> FSM:
        return FSM(
            [
                Behaviour(
                    "serve",
                    self._serve,
                    terminal=lambda: False,
                    doc="pass a_ta's commands to the control loop; answer with their results; "
                    "hold position when a_ta is gone",
                )
            ],
        )

    @property
    def attached_world(self) -> str:
        """The name of the world link the executor's loop is attached to ("": none)."""
        return str(getattr(self.executor, "world_link", "") or "")

    def _link_watch(self) -> LinkWatch | None:
        """Watches the run folder for a world started anew (docs/executor.md); None without a
        world process or a run folder."""
        run_dir = Settings.from_env(only=("run_dir",)).run_dir
        if not self.attached_world or run_dir is None:
            return None
        return LinkWatch(run_dir, self.attached_world)

    def _watch_world(self) -> None:
        """Reattach when the world was started anew (``link_watch``)."""
        renewed = self.link_watch.renewed() if self.link_watch is not None else None
        if renewed is not None:
            self._reattach(renewed)

    def _reattach(self, name: str) -> None:
        """The world was started anew under link ``name``: end the loop of the old one and
        start one attached to the new one (docs/executor.md). A loop that does not start is
        logged; the next world started anew is tried again."""
        old = self.attached_world
        self.counters["world_restarts"] += 1
        self.log.warning(
            "the world started anew (the robot's power cycle: link %s, before %s): a fresh kitchen; "
            "ending the control loop of the old one and attaching a new one",
            name,
            old,
        )
        rerun = self.rerun
        if rerun is not None:
            rerun.stop_camera()
        self._stop_feed()
        self.executor.stop()  # open commands end "stopped"
        self.recalled.clear()  # results of commands in the old kitchen
        self.ledger_runs.clear()
        try:
            self.executor = self.make_executor()
            self._hook_ledger()
            self.executor.start()
        except RuntimeError as exc:  # the world gone again, or a loop that did not start
            self.log.error("no control loop for the new world %s: %s", name, exc)
            return
        self.log.info("control loop attached to the new world (link %s)", self.attached_world)
        self._start_camera()
        self._start_feed()
        self.watch.rearm(self.executor)
        for watcher in self.watchers.values():
            watcher.reply(Performative.INFORM, PowerOn(world=self.attached_world))

    def _commanders(self) -> tuple[str, ...]:
        """Agents that initiate conversations with ag_ex (from the specification)."""
        return tuple(
            sorted(
                {
                    cp.initiator
                    for ch in self.engine.spec.channels
                    if self.name in ch.ends
                    for cp in ch.protocols
                    if cp.initiator != self.name
                }
            )
        )

    def _open_ledger(self) -> None:
        """Keep the ledger in the run folder when there is one and the executor reports its
        starts and ends (``on_start``, ``on_end``: ``ExecutorProcess``); else none."""
        run_dir = Settings.from_env(only=("run_dir",)).run_dir
        if run_dir is None or not hasattr(self.executor, "on_start") or not hasattr(self.executor, "on_end"):
            return
        self.recalled = recall(run_dir / LEDGER_FILE)  # OSError: ag_ex does not start without it
        self.ledger = Ledger(run_dir / LEDGER_FILE)
        self._hook_ledger()
        self.log.info(
            "ledger of executed commands: %s (this ag_ex: %s; %d ended before it)",
            self.ledger.path,
            self.ledger.life,
            len(self.recalled),
        )

    def _hook_ledger(self) -> None:
        """Have the executor report its starts and ends to the ledger (when there is one)."""
        if self.ledger is None:
            return
        self.executor.on_start = lambda token, name, t: self.post(Began(token, name, t))
        self.executor.on_end = lambda token, name, t, outcome, result=None: self.post(
            Ended(token, name, t, outcome, result)
        )

    def setup(self) -> None:
        self._open_ledger()
        self.executor.start()
        self._start_camera()
        self._start_feed()
        for peer in self.commanders:
            self.engine.transport.watch(keys.alive_key(peer), self._on_liveliness(peer))
        decoder = msgspec.json.Decoder(Disturbance)

        def on_disturb(_key: str, payload: bytes) -> None:  # Zenoh thread: enqueue only
            try:
                self.post(decoder.decode(payload))
            except msgspec.DecodeError as exc:
                self.log.warning("ignored malformed disturbance: %s", exc)

        self.engine.transport.subscribe(keys.SIM_DISTURB, on_disturb)

    def _start_camera(self) -> None:
        """Rerun: the head camera, rendered in a thread of this process (never in the loop's)
        from the whole simulation state the loop copies (``world_state``), when the hooks want
        it (``camera_wanted``: the loop copies the state for the watch too)."""
        world = getattr(self.executor, "world", None)
        wanted = self.engine.hooks.camera_wanted() if self.engine.hooks else False
        if (
            self.rerun is not None
            and world is not None
            and wanted
            and getattr(self.executor, "world_state", False)
        ):
            self.rerun.start_camera(
                world,
                seed=getattr(self.executor, "seed", 0),
                pose_seed=getattr(self.executor, "pose_seed", None),
            )

    def _start_feed(self) -> None:
        """The head camera's images on Zenoh for ``roco ros2 --camera`` (services/agents/executor/
        camera_feed.py): rendered in a thread of this process from the world state the loop
        copies, only while a subscriber matches; none without the world state or a Zenoh session."""
        world = getattr(self.executor, "world", None)
        transport = getattr(self.engine.transport, "inner", self.engine.transport)  # under the fault layer
        session = getattr(transport, "session", None)
        if world is None or session is None or not getattr(self.executor, "world_state", False):
            return
        from services.agents.executor.camera_feed import CameraPublisher

        executor = self.executor
        try:
            self.camera_feed = CameraPublisher(
                session,
                world,
                Settings.from_env(only=("camera_hz",)).camera_hz,
                seed=getattr(executor, "seed", 0),
                pose_seed=getattr(executor, "pose_seed", None),
            )
        except Exception:  # the robot goes on without the feed
            self.log.exception("the camera feed could not start")

    def _stop_feed(self) -> None:
        """End the camera feed before the executor's world state goes away (idempotent)."""
        feed, self.camera_feed = getattr(self, "camera_feed", None), None
        if feed is not None:
            feed.close()

    def _on_liveliness(self, peer: str) -> Callable[[str, bool], None]:
        def changed(_key: str, alive: bool) -> None:  # Zenoh thread: enqueue only
            self.post(PeerChange(peer, alive))

        return changed

    def close(self) -> None:
        rerun = getattr(self, "rerun", None)
        if rerun is not None:  # Rerun: the camera reads the loop's shared memory: stop it first
            rerun.stop_camera()
        self._stop_feed()
        self._write_timing_file()
        self.executor.stop()
        if self.ledger is not None:
            self.ledger.close()
        if rerun is not None:  # Rerun: close ag_ex's part of the run's recording
            rerun.close()

    @handles(FIPA_REQUEST, PARTICIPANT, Performative.REQUEST)
    def _on_request(self, conv: Conversation) -> None:
        command = conv.content
        if command is None or type(command) not in COMMANDS.values():
            what = type(command).__name__ if command is not None else "no content"
            conv.refuse_with(Performative.REFUSE, f"not an L_EX command: {what}")
            return
        if self._answer_from_ledger(conv, command_name(command)):
            return
        running = Running(command_name(command))
        conv.data = running
        world = self.attached_world
        running.token = self.executor.submit(
            command, lambda result, req=conv: self.post(Done(req, result, world))
        )
        self.track(running.token, conv)

    def _answer_from_ledger(self, conv: Conversation, name: str) -> bool:
        """Answer ``conv`` with the result an earlier ag_ex's loop gave its command ``name``
        (``recalled``), after a ``replayed`` line: a WorldCapture through the executor's
        ``replay`` (rendered, as the loop's own), else at once. False (run it) when the ledger
        has no ended command ``name`` of the conversation, or a capture and no ``replay``."""
        known = self.recalled.get(conv.conversation_id)
        replay = getattr(self.executor, "replay", None)
        if (
            known is None
            or known.command != name
            or (isinstance(known.answer, WorldCapture) and replay is None)
        ):
            return False
        self._note_replayed(conv.conversation_id, name, known.sim_time)
        self.log.info(
            "%s (conversation %s) ended at sim time %.3f s in an earlier ag_ex: answered from the ledger",
            name,
            conv.conversation_id,
            known.sim_time,
        )
        answer = known.answer
        if isinstance(answer, WorldCapture) and replay is not None:
            running = Running(name)
            conv.data = running
            running.token = replay(name, answer, lambda result, req=conv: self.post(Done(req, result)))
            return True
        ok = not isinstance(answer, CommandResult) or answer.ok
        conv.reply(Performative.INFORM if ok else Performative.FAILURE, answer)
        return True

    def _note_replayed(self, conversation: str, name: str, sim_time: float) -> None:
        """The ledger's ``replayed`` line of ``conversation``'s command ``name`` (counted, as
        ``answered_from_ledger``); one that cannot be written is counted and logged as in
        ``_note``."""
        self.counters["answered_from_ledger"] += 1
        if self.ledger is None:
            return
        try:
            self.ledger.replayed(conversation, name, sim_time)
        except OSError as exc:
            self.counters["ledger_errors"] += 1
            self.log.error("ledger line of %s (conversation %s) not written: %s", name, conversation, exc)

    def track(self, token: object, conv: Conversation) -> None:
        """Name ``conv``'s conversation-id in the ledger lines of the executor's ``token``."""
        if self.ledger is not None:
            self.ledger_runs[token] = conv.conversation_id

    def _note(self, event: Began | Ended) -> None:
        """The ledger's line of ``event`` (a command the loop began or ended), fsync-ed; a token
        the agent does not know is written under conversation "?". A line that cannot be
        written is counted (``ledger_errors``) and logged: the robot goes on, and the judges
        find the run missing."""
        if self.ledger is None:
            return
        conversation = self.ledger_runs.get(event.token, "?")  # forgotten when answered
        try:
            if isinstance(event, Began):
                self.ledger.started(conversation, event.command, event.sim_time)
            else:
                self.ledger.ended(conversation, event.command, event.sim_time, event.outcome, event.result)
        except OSError as exc:
            self.counters["ledger_errors"] += 1
            self.log.error(
                "ledger line of %s (conversation %s) not written: %s", event.command, conversation, exc
            )

    @handles(FIPA_SUBSCRIBE, PARTICIPANT, Performative.SUBSCRIBE)
    def _on_subscribe(self, conv: Conversation) -> None:
        """a_ta subscribes to the robot's power-ons (``PowerOns``) or has it watch (``Watch``:
        services/agents/executor/watching.py)."""
        if isinstance(conv.content, Watch):
            self.watch.subscribe(conv, conv.content, self.executor)
            return
        if not isinstance(conv.content, PowerOns):
            conv.refuse_with(Performative.REFUSE, "not an L_EX PowerOns or Watch subscription")
            return
        self._power_ons(conv)

    def _power_ons(self, conv: Conversation) -> None:
        """a_ta subscribes to the robot's power-ons: agreed, then told the current one (when the
        loop is attached to a world process) and each new one (``_reattach``)."""
        self.watchers[conv.peer] = conv
        conv.reply(Performative.AGREE)
        if self.attached_world:
            conv.reply(Performative.INFORM, PowerOn(world=self.attached_world))

    @handles(FIPA_SUBSCRIBE, PARTICIPANT, Performative.CANCEL)
    def _on_subscription_cancel(self, conv: Conversation) -> None:
        if self.watchers.get(conv.peer) is conv:
            del self.watchers[conv.peer]
        self.watch.cancelled(conv, self.executor)
        conv.reply(Performative.INFORM)

    @handles(FIPA_REQUEST, PARTICIPANT, Performative.CANCEL)
    def _on_cancel(self, conv: Conversation) -> None:
        """a_ta cancels a request it made: the executor is asked to halt its command (module
        docstring); the cancel is answered when the command's result comes (``_answer``)."""
        running, cancel = conv.data, conv.last
        if not isinstance(running, Running) or cancel is None:  # no command of it is with the loop
            conv.refuse_with(Performative.FAILURE, "nothing to cancel: no command of this request runs")
            return
        running.cancel = cancel
        halt = getattr(self.executor, "cancel", None)
        asked = halt is not None and running.token is not None and bool(halt(running.token))
        if asked:
            self.counters["halts"] += 1
        self.log.info(
            "halt: cancel of %s (conversation %s) at wall time %.6f: %s",
            running.command,
            conv.conversation_id,
            time.time(),
            "passed to the loop" if asked else "the loop cannot halt it (it has ended); its result answers",
        )

    def _answer(self, event: Done) -> None:
        """Answer the request ``event`` ended. While a_ta's cancel of it waits, the answer is the
        cancel's (FIPA SC00026 §2): ``inform`` with the result of a halted command (cancelled),
        ``failure`` with the result of one that ended otherwise (could not cancel: it had ended;
        an Observation cannot be a failure's content, so that failure says so in words). Else
        ``inform``, or ``failure`` for a CommandResult that is not ok."""
        conv, result = event.request, event.result
        if event.world:  # the world the loop that ran it was attached to
            result = msgspec.structs.replace(result, world=event.world)
        running = conv.data if isinstance(conv.data, Running) else None
        if running is not None:
            self.ledger_runs.pop(running.token, None)
        cancel = running.cancel if running is not None else None
        if running is None or cancel is None:
            ok = not isinstance(result, CommandResult) or result.ok
            conv.reply(Performative.INFORM if ok else Performative.FAILURE, result)
            return
        running.cancel = None
        halted = isinstance(result, CommandResult) and result.reason == HALTED
        self.log.info(
            "halt: %s %s at sim time %.3f s (wall time %.6f): the cancel is answered",
            running.command,
            "at rest" if halted else "ended before the halt",
            result.sim_time if isinstance(result, CommandResult) else result.stamp,
            time.time(),
        )
        if halted:
            conv.reply(Performative.INFORM, result, to=cancel)
        elif isinstance(result, CommandResult):
            conv.reply(Performative.FAILURE, result, to=cancel)
        else:
            conv.refuse_with(Performative.FAILURE, "could not cancel: the observation was made", to=cancel)

    def _serve(self) -> None:
        self.handle_received()
        while self.r:
            self._act_on(self.r.popleft())
        self._watch_world()
        now = time.monotonic()
        if now >= self._next_state:
            self._next_state = now + STATE_PUBLISH_S
            self._publish_state()
        if now >= self._next_timing_file:
            self._next_timing_file = now + TIMING_FILE_PERIOD
            self._write_timing_file()

    def _act_on(self, event: object) -> None:
        """Act on one event of the receptor buffer (from the executor, the transport's threads)."""
        if isinstance(event, Done):
            if self.rerun is not None and isinstance(event.result, Observation):  # Rerun
                self.rerun.observation(event.result)
            self._answer(event)
        elif isinstance(event, Began | Ended):
            self._note(event)
        elif isinstance(event, PeerChange):
            self._peer_changed(event)
        elif isinstance(event, Disturbance):
            self._disturb(event)
        elif isinstance(event, Frame):
            self.watch.inform(event, self.attached_world)

    def _disturb(self, event: Disturbance) -> None:
        displace = getattr(self.executor, "displace", None)
        try:
            done = bool(displace(event.object, event.delta, event.tilt)) if displace is not None else False
        except (KeyError, ValueError) as exc:
            self.log.warning("disturbance not applied: %s", exc)
            return
        self.counters["disturbances"] += 1
        snapshot = getattr(self.executor, "snapshot", None)
        snap = snapshot() if snapshot is not None else None
        self.log.info(
            "the world: %s moved by %s m, tilted %.2f rad%s%s",
            event.object,
            event.delta,
            event.tilt,
            "" if done else " (not applied)",
            # the latest robot state's time: at most STATE_PERIOD cycles before the loop takes it
            f" at robot time {snap.sim_time:.3f} s" if snap is not None else "",
        )

    def _peer_changed(self, event: PeerChange) -> None:
        if event.alive:
            if event.agent not in self.alive_peers:
                self.log.info("%s is alive", event.agent)
            self.alive_peers.add(event.agent)
            return
        self.alive_peers.discard(event.agent)
        self.watch.drop(event.agent, self.executor)
        hold = getattr(self.executor, "hold", None)
        asked = bool(hold(f"{event.agent} lost")) if hold is not None else False
        self.counters["holds"] += 1
        self.log.warning(
            "%s lost (liveliness token gone): %s",
            event.agent,
            "bringing the motion to rest, then holding position in joint impedance, hands as they are"
            if asked
            else "could not ask the loop to hold",
        )
        self._publish_state()

    def _publish_state(self) -> None:
        snapshot = getattr(self.executor, "snapshot", None)
        snap = snapshot() if snapshot is not None else None
        if snap is not None:
            self.emit(keys.state_key(self.name), self._encode(snap))
            self.emit(keys.SIM_CLOCK, encode_sim_time(snap.sim_time))  # the fleet's clock
            if self.rerun is not None:  # Rerun, at the state rate (20 Hz)
                self.rerun.snapshot(snap)

    def _write_timing_file(self) -> None:
        run_dir = Settings.from_env(only=("run_dir",)).run_dir
        timing = getattr(self.executor, "timing", None)
        if run_dir is None or timing is None:
            return
        try:
            stats = timing()
        except RuntimeError:
            return
        path = run_dir / TIMING_FILE
        tmp = path.with_suffix(".tmp")
        tmp.write_text(json.dumps(msgspec.to_builtins(stats), indent=1))
        tmp.replace(path)
