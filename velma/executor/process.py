"""ag_ex's hard-timing executor, its communication side: ``ExecutorProcess`` starts the 1 kHz
control loop in a process of its own (paper §5.3; velma/executor/loop_process.py) and talks to
it only through lock-free bounded hand-offs in shared memory (velma.executor.handoff), whose
messages, blocks and constants are in velma/executor/loop_wire.py.

Why a process: in one Python process the loop thread shares the interpreter lock with Zenoh's
callback threads and the agent's behaviours; a thread switch can hold the loop for the whole
switch interval (5 ms). In its own process the loop competes only for a CPU, which
``enter_realtime`` (SCHED_FIFO, a CPU of its own) settles where the OS permits it.

Hand-offs (all non-blocking on the loop's side):

- commands: ``SpscRing`` communication side → loop (``Submit``, ``Cancel``, ``Hold``, ``Safe``,
  ``Displace``, ``Pace``, ``Shutdown``), polled once per cycle (up to ``INBOX_PER_CYCLE``
  messages): a ``Cancel`` halts its command in the cycle that takes it
  (velma/executor/loop.py ``ControlLoop.cancel``); a ``Submit`` carries its command's bytes,
  which the loop decodes with the L_EX commands of its own process (``COMMANDS``), answering
  one it does not know with the failure ``not an executor command in the loop's process: NAME``;
- results: ``SpscRing`` loop → communication side (``Ready``, ``Started``, ``Done``,
  ``Halting``, ``Fault``), plus one byte on a non-blocking pipe (a doorbell) so that the reader
  thread sleeps until there is news; ``Started`` says when (simulation) the loop started a
  command and ``Done`` when it ended (both passed to the ``on_start`` and ``on_end`` hooks, for
  ag_ex's ledger, velma/executor/ledger.py); ``Halting`` says when (wall clock and simulation)
  the loop began a halt, and is logged here;
- robot state: two ``LatestValue`` blocks (sequence locks), the numbers rewritten every
  ``STATE_PERIOD`` cycles (from C++ with the compiled plant), the names when they change
  (velma/executor/state_block.py);
- world state (only when asked, ``world_state=True``: for the watch, velma/executor/watch.py,
  and the head camera of the Rerun recording): the simulation time and MuJoCo's whole ``qpos``
  (robot, objects, particles) as raw float64 in a second ``LatestValue``, rewritten every
  ``WORLD_PERIOD`` cycles (≈ 1.4 µs per write: a copy of 1.4 kB); whoever renders it does so
  in another process;
- timing: the ``DeadlineMonitor``'s arrays live in shared memory; the communication side
  computes percentiles from them, never the loop; with a world process, the world's own
  timing counts are read here from its link (velma/world/timing.py);

Observe: the loop answers an Observe with a ``WorldCapture`` (velma/executor/capture.py:
the requested names, sim time and a copy of ``qpos``); on this side ``ResultDelivery``
(velma/executor/delivery.py), a worker thread, renders the head camera and localises, and
delivers every result in the loop's order (an Observation is never overtaken by a later
command's result). The loop never renders or fits. ``perception="truth"`` (ROCO_PERCEPTION)
makes the loop answer with the ground truth instead (tests).

Watch (``ExecutorProcess.watch``, velma/executor/watch.py): while on, a thread of this side
makes a watch frame of the world state every ``period_s`` of robot time and puts it through the
same ``ResultDelivery`` (in order with the results; at most one in flight), and, when the loop
runs as fast as possible, the loop is paced to at most ``watch_pace`` × wall time (``Pace``;
ROCO_WATCH_PACE): in simulation a camera frame costs wall time, so a watched robot runs at the
camera's pace. ``unwatch`` ends it and the fast pace returns. Real-time pacing is unchanged.

The loop process ends when asked (``Shutdown``), on SIGTERM or SIGINT, when its parent process
disappears (checked every second) or when it is killed; the communication side then answers
every open command with ``failure``.
"""

from __future__ import annotations

import collections
import itertools
import logging
import multiprocessing
import multiprocessing.connection
import os
import threading
import time
from collections.abc import Callable
from multiprocessing import shared_memory

import msgspec
import numpy as np

from shared.fipa_codec.languages.l_ex import CommandResult, ExecutorCommand, command_name
from shared.fipa_codec.languages.l_sd import Observation
from shared.settings import Settings
from velma.executor.camera_process import CameraProcess, CameraSpec
from velma.executor.camera_process import camera_idle_s as camera_idle_s_of_env
from velma.executor.capture import WorldCapture, perception_mode
from velma.executor.delivery import RecordSink, ResultDelivery
from velma.executor.handoff import LatestValue, SpscRing, new_block, remove_orphans, shared_view
from velma.executor.ledger import STOPPED, outcome_of
from velma.executor.loop_process import loop_main
from velma.executor.loop_wire import (
    DEFAULT_SPIN,
    DT,
    LOOP_PROCESS_NAME,
    SLOT_SIZE,
    SLOTS,
    START,
    START_TIMEOUT,
    STATE_CAPACITY,
    TIMING_REFRESH,
    WORLD_CAPACITY,
    Cancel,
    Displace,
    Done,
    FromLoop,
    Halting,
    Hold,
    LoopConfig,
    Pace,
    Ready,
    Safe,
    Shutdown,
    Started,
    Submit,
    WorldState,
)
from velma.executor.state import RobotSnapshot, snapshot_of
from velma.executor.state_block import StateReader
from velma.executor.timing import DEFAULT_WINDOW, DeadlineMonitor, TimingStats
from velma.executor.watch import Watcher, check_period
from velma.realtime import RealtimeSetup
from velma.world.link import LinkError, RobotLink
from velma.world.timing import WorldTiming

log = logging.getLogger(__name__)

OnDone = Callable[[CommandResult | Observation], None]
OnFrame = Callable[[Observation], None]
"""Called with each watch frame's Observation (``ExecutorProcess.watch``)."""
WATCH_TOKEN = 0
"""The delivery token of watch frames (commands' tokens count from 1)."""
OnStart = Callable[[int, str, float], None]
"""``(token, command name, sim_time s)`` of a command the loop started."""
OnEnd = Callable[[int, str, float, str, CommandResult | Observation | WorldCapture], None]
"""``(token, command name, sim_time s, outcome, result)`` of a command the loop ended (velma/
executor/ledger.py ``outcome_of``; ``result``: the loop's own, an Observe's WorldCapture before
it is rendered)."""


# ---------------------------------------------------------------------- communication side
class ExecutorProcess:
    """The executor with its loop in a separate process; same interface as
    ``velma.executor.Executor`` (``start``, ``stop``, ``submit``, ``cancel``, ``hold``,
    ``snapshot``, ``timing``).

    ``seed`` and ``pose_seed`` select the scene (``velma.executor.runtime.Runtime``).
    ``realtime`` paces the loop to wall time; ``realtime_priority`` then asks for SCHED_FIFO
    and a CPU of its own (``cpu``, default the last one; see ``enter_realtime``); ``spin`` (s)
    is how long before each release the loop busy-waits instead of sleeping; ``pin=False``
    keeps SCHED_FIFO but lets the loop run on any CPU. ``on_done`` callbacks run on this
    side's reader thread, once per command. ``start`` raises ``RuntimeError`` if the loop process
    does not come up within ``START_TIMEOUT`` s. ``world_state`` makes the loop publish the
    whole simulation state every ``WORLD_PERIOD`` cycles (read with ``world``).

    ``perception`` ``camera`` or ``truth`` (None: ``ROCO_PERCEPTION``, else
    ``DEFAULT_PERCEPTION`` of velma/executor/capture.py); with
    the camera renders and localises in a process of its own (velma/executor/camera_process.py:
    started at ``start``, not waited for; ended after ``camera_idle_s`` s without a result,
    None: ``ROCO_CAMERA_IDLE_S``, and started again when the next command ends or an Observe
    comes); ``perception_log`` receives each camera Observation's records beside the truth
    (velma/executor/perception_log.py).

    ``world_link`` names the robot link of a world process (velma/world/): the loop is then
    the controller of that world (velma/executor/world_link.py), which keeps the kitchen when
    the loop ends; a loop that starts again attaches to it and finds the robot as it is.
    Without it the physics runs in the loop and ends with it.

    ``watch_pace`` (None: ROCO_WATCH_PACE): the pace (robot s per wall s) a loop that runs as
    fast as possible keeps while a watch is on (``watch``; module docstring).
    """

    def __init__(
        self,
        *,
        realtime: bool = False,
        seed: int = 0,
        pose_seed: int | None = None,
        realtime_priority: bool = True,
        spin: float = DEFAULT_SPIN,
        cpu: int | None = None,
        pin: bool = True,
        window: int = DEFAULT_WINDOW,
        world_state: bool = False,
        perception: str | None = None,
        perception_log: RecordSink | None = None,
        camera_idle_s: float | None = None,
        world_link: str | None = None,
        watch_pace: float | None = None,
    ) -> None:
        self.perception = perception_mode(
            None if perception is None else {Settings.env_name("perception"): perception}
        )
        self.camera_idle_s = camera_idle_s_of_env() if camera_idle_s is None else camera_idle_s
        self.watch_pace = (
            Settings.from_env(only=("watch_pace",)).watch_pace if watch_pace is None else watch_pace
        )
        self._watcher: Watcher | None = None
        self._on_frame: OnFrame | None = None
        self.perception_log = perception_log
        self._delivery: ResultDelivery[int] | None = None
        self.realtime = realtime
        self.world_state = world_state
        self.world_link = world_link or ""
        self.seed = seed
        self.pose_seed = pose_seed
        self.realtime_priority = realtime_priority
        self.spin = spin
        self.cpu = cpu
        self.pin = pin
        self.window = window
        self.setup: RealtimeSetup | None = None
        self.control_law = ""
        """Which impedance law the loop runs (``compiled`` or ``python``), once it is ready."""
        self.plant = ""
        """Where the cycle's MuJoCo side runs (``compiled`` or ``python``), once it is ready."""
        self._timing_cache: tuple[float, TimingStats] | None = None
        self.exit_reason: str | None = None
        self._callbacks: dict[int, tuple[OnDone, str]] = {}
        self.halts: collections.deque[Halting] = collections.deque(maxlen=64)
        """The latest halts the loop began (``Halting``, oldest first), as logged."""
        self.on_start: OnStart | None = None
        """Called on the reader thread when the loop starts a command (before its ``on_done``)."""
        self.on_end: OnEnd | None = None
        """Called on the reader thread when the loop ends a command, before its ``on_done``;
        not for the answers this side makes up (a full ring, a loop that is gone)."""
        self._tokens = itertools.count(1)
        self._lock = threading.Lock()
        self._ready = threading.Event()
        self._proc: multiprocessing.process.BaseProcess | None = None
        self._reader: threading.Thread | None = None
        self._bell: multiprocessing.connection.Connection | None = None
        self._commands: SpscRing | None = None
        self._results: SpscRing | None = None
        self._state: LatestValue | None = None
        self._state_names: LatestValue | None = None
        self._state_reader: StateReader | None = None
        self._world: LatestValue | None = None
        self._mon_shm: shared_memory.SharedMemory | None = None
        self._monitor: DeadlineMonitor | None = None
        self._world_counts: RobotLink | None = None  # the world's link, read for its timing
        self._decode = msgspec.msgpack.Decoder(FromLoop).decode
        self._encode = msgspec.msgpack.Encoder().encode

    # ------------------------------------------------------------------ lifecycle
    def start(self, timeout: float = START_TIMEOUT) -> None:
        """Spawn the loop process and wait until it runs (idempotent)."""
        if self._proc is not None:
            return
        orphans = remove_orphans()  # the blocks of an ag_ex that was killed
        if orphans:
            log.info("removed %d shared memory block(s) of processes that are gone", len(orphans))
        self._commands = SpscRing.create(SLOTS, SLOT_SIZE)
        self._results = SpscRing.create(SLOTS, SLOT_SIZE)
        self._state = LatestValue.create(STATE_CAPACITY)
        self._state_names = LatestValue.create(STATE_CAPACITY)
        self._state_reader = StateReader(self._state, self._state_names)
        self._world = LatestValue.create(WORLD_CAPACITY) if self.world_state else None
        self._mon_shm = new_block(DeadlineMonitor.nbytes(self.window))
        shared_view(self._mon_shm)[:] = bytes(self._mon_shm.size)
        self._monitor = DeadlineMonitor(
            DT, realtime=self.realtime, window=self.window, buffer=self._mon_shm.buf
        )
        cfg = LoopConfig(
            realtime=self.realtime,
            seed=self.seed,
            pose_seed=self.pose_seed,
            realtime_priority=self.realtime_priority,
            spin=self.spin,
            cpu=self.cpu,
            pin=self.pin,
            commands=self._commands.name,
            results=self._results.name,
            state=self._state.name,
            state_names=self._state_names.name,
            monitor=self._mon_shm.name,
            window=self.window,
            parent_pid=os.getpid(),
            world=self._world.name if self._world is not None else "",
            camera=self.perception == "camera",
            world_link=self.world_link,
        )
        camera = None
        if cfg.camera:
            spec = CameraSpec(
                seed=self.seed,
                pose_seed=self.pose_seed,
                noise_seed=self.pose_seed or 0,
                record=self.perception_log is not None,
            )
            camera = CameraProcess(spec)
        self._delivery = ResultDelivery(
            self._deliver, camera, rest_after_s=self.camera_idle_s, record=self.perception_log
        )
        ctx = multiprocessing.get_context("spawn")
        reader_end, writer_end = ctx.Pipe(duplex=False)
        self._bell = reader_end
        config = msgspec.msgpack.encode(cfg)
        proc = ctx.Process(target=loop_main, args=(config, writer_end), name=LOOP_PROCESS_NAME, daemon=True)
        proc.start()
        writer_end.close()
        self._proc = proc
        self._reader = threading.Thread(target=self._read, name="velma-loop-reader", daemon=True)
        self._reader.start()
        if not self._ready.wait(timeout):
            reason = self.exit_reason or f"no Ready within {timeout:.0f} s"
            self.stop()
            raise RuntimeError(f"executor loop process did not start: {reason}")
        if self.exit_reason is not None and self.setup is None:
            reason = self.exit_reason
            self.stop()
            raise RuntimeError(f"executor loop process did not start: {reason}")

    def stop(self, timeout: float = 5.0) -> None:
        """Ask the loop process to end, wait for it (then terminate it), answer open commands
        with ``stopped`` and free the shared memory."""
        proc = self._proc
        if proc is None:
            return
        self.unwatch()
        if self._commands is not None and proc.is_alive():
            self._commands.push(self._encode(Shutdown()))
        proc.join(timeout)
        if proc.is_alive():
            proc.terminate()  # the loop ends at its next cycle
            proc.join(timeout)
        if proc.is_alive():
            proc.kill()
            proc.join(timeout)
        if self._reader is not None:
            self._reader.join(timeout)
        if self._delivery is not None:  # the results the loop gave, in order, then the rest fail
            self._delivery.close()
            self._delivery = None
        self._fail_open(STOPPED)
        self._monitor = None
        self._state_reader = None
        states = (self._state, self._state_names)
        for block in (self._commands, self._results, *states, self._world):
            if block is not None:
                block.close()
                block.unlink()
        if self._mon_shm is not None:
            self._mon_shm.close()
            self._mon_shm.unlink()
        if self._world_counts is not None:
            self._world_counts.close()
            self._world_counts = None
        if self._bell is not None:
            self._bell.close()
        self._commands = self._results = self._state = self._state_names = None
        self._world = None
        self._mon_shm = None
        self._proc = None

    @property
    def pid(self) -> int | None:
        """Process id of the loop process (None before ``start``)."""
        return self._proc.pid if self._proc is not None else None

    @property
    def alive(self) -> bool:
        """True while the loop process runs."""
        return self._proc is not None and self._proc.is_alive()

    # ------------------------------------------------------------------ API
    def submit(self, command: ExecutorCommand, on_done: OnDone) -> int:
        """Queue ``command``; ``on_done(result)`` is called once when it ends. A full command
        ring or a dead loop answers at once with ``failure``. Returns the command's token (for
        ``cancel``)."""
        token = next(self._tokens)
        with self._lock:
            self._callbacks[token] = (on_done, command_name(command))
        reason: str | None = None
        if self._commands is None or not self.alive:
            reason = f"executor loop not running{': ' + self.exit_reason if self.exit_reason else ''}"
        elif not self._commands.push(
            self._encode(
                Submit(token=token, name=command_name(command), command=msgspec.Raw(self._encode(command)))
            )
        ):
            reason = "executor busy: command queue full"
        if reason is not None:
            self._answer(token, CommandResult(command=command_name(command), ok=False, reason=reason))
        return token

    def replay(self, name: str, result: CommandResult | Observation | WorldCapture, on_done: OnDone) -> int:
        """Answer ``on_done`` with ``result`` of command ``name`` that a loop ran before (ag_ex's
        ledger, velma/executor/ledger.py ``recall``) without running it: after every result
        put before it, a WorldCapture rendered and localised as the loop's own are. Returns
        its token (the loop does not know it: a ``cancel`` of it asks nothing)."""
        token = next(self._tokens)
        with self._lock:
            self._callbacks[token] = (on_done, name)
        if self._delivery is not None:
            self._delivery.put(token, result)
        elif not isinstance(result, WorldCapture):
            self._answer(token, result)
        else:
            self._answer(token, CommandResult(command=name, ok=False, reason=STOPPED, sim_time=result.stamp))
        return token

    def cancel(self, token: int) -> bool:
        """Ask the loop to halt the command ``token`` (``Cancel``): its ``on_done`` then gets
        a result that says ``halted`` (L_EX ``HALTED``) — or its own result, when it ended
        before the loop took the cancel. False when the loop could not be asked (not running,
        inbox full) or the command has been answered already."""
        with self._lock:
            open_ = token in self._callbacks
        return (
            open_
            and self._commands is not None
            and self.alive
            and self._commands.push(self._encode(Cancel(token=token)))
        )

    def hold(self, why: str) -> bool:
        """Ask the loop to hold position (velma.executor.loop); False if it could not be asked."""
        return self._commands is not None and self.alive and self._commands.push(self._encode(Hold(why=why)))

    def displace(self, body: str, delta: tuple[float, float, float], tilt: float = 0.0) -> bool:
        """Move free body ``body`` by ``delta`` (world, m) and tilt it by ``tilt`` (rad, about
        world x) in the simulated world; False when the loop is not running or its inbox is
        full."""
        msg = Displace(body=body, delta=delta, tilt=tilt)
        return self._commands is not None and self.alive and self._commands.push(self._encode(msg))

    def safe(self, why: str) -> bool:
        """Ask the loop to enter safe mode (velma.executor.loop); False if it could not be asked."""
        return self._commands is not None and self.alive and self._commands.push(self._encode(Safe(why=why)))

    def watch(self, objects: tuple[str, ...], period_s: float, on_frame: OnFrame) -> None:
        """See continuously (module docstring; velma/executor/watch.py): every ``period_s``
        (robot s) a watch frame of ``objects`` (empty: all the camera knows), observed in the
        camera's watch mode, is passed to ``on_frame`` (on the delivery thread, in order with
        the commands' results; at most one frame in flight, a due one skipped meanwhile); a
        loop that runs as fast as possible is paced to at most ``watch_pace`` × wall time. A
        watch replaces the one before. Raises ``RuntimeError`` before ``start``, without the
        camera (``perception="truth"``) or the world state (``world_state=False``);
        ``ValueError`` for a period out of velma/executor/watch.py ``PERIOD_RANGE_S``."""
        check_period(period_s)
        if self._delivery is None or self._commands is None:
            raise RuntimeError("executor loop not started")
        if self.perception != "camera":
            raise RuntimeError(f"a watch needs the head camera, not perception {self.perception!r}")
        if self._world is None:
            raise RuntimeError("a watch needs the world state (ExecutorProcess(world_state=True))")
        self.unwatch()
        delivery = self._delivery
        self._on_frame = on_frame
        self._watcher = Watcher(self.world, lambda frame: delivery.put(WATCH_TOKEN, frame), objects, period_s)
        if not self.realtime:
            self._commands.push(self._encode(Pace(factor=self.watch_pace)))
        log.info(
            "watch on: %s every %.2f s of robot time%s",
            ", ".join(objects) or "every object",
            period_s,
            "" if self.realtime else f", the loop paced to at most {self.watch_pace:g} × wall time",
        )

    def unwatch(self) -> None:
        """End the watch (nothing when none is on): no frame is made after it returns (one in
        flight is still delivered), and the loop's own pacing returns."""
        watcher, self._watcher = self._watcher, None
        if watcher is None:
            return
        watcher.stop()
        if not self.realtime and self._commands is not None and self.alive:
            self._commands.push(self._encode(Pace(factor=0.0)))
        log.info("watch off: %d frames made, %d skipped (one in flight)", watcher.frames, watcher.skipped)

    @property
    def watching(self) -> bool:
        """True while a watch is on."""
        return self._watcher is not None

    @property
    def watch_counts(self) -> tuple[int, int] | None:
        """The watch on: frames made so far and frames skipped (due while one was in flight);
        None when none is on."""
        w = self._watcher
        return (w.frames, w.skipped) if w is not None else None

    def _deliver(self, token: int, result: CommandResult | Observation) -> None:
        """The delivery thread's result for ``token``: a watch frame's to ``on_frame``, a
        command's to its ``on_done``."""
        if token != WATCH_TOKEN:
            self._answer(token, result)
            return
        watcher, on_frame = self._watcher, self._on_frame
        if watcher is not None:
            watcher.delivered()
        if watcher is None or on_frame is None:
            return  # the watch ended meanwhile
        if not isinstance(result, Observation):
            log.warning("a watch frame was not observed: %s", result.reason)
            return
        try:
            on_frame(result)
        except Exception:
            log.exception("on_frame callback raised")

    def snapshot(self) -> RobotSnapshot | None:
        """The latest robot state (≤ ``STATE_PERIOD`` ms old) with the loop's timing (at most
        ``TIMING_REFRESH`` s old), or None before the loop published one."""
        raw = self._state_reader.read() if self._state_reader is not None else None
        if raw is None:
            return None
        snap = snapshot_of(raw)
        now = time.monotonic()
        if self._timing_cache is None or now - self._timing_cache[0] >= TIMING_REFRESH:
            # percentiles over the window cost milliseconds: not at the state's 20–50 Hz
            self._timing_cache = (now, self.timing(snap.sim_time))
        return msgspec.structs.replace(snap, timing=self._timing_cache[1])

    def world(self) -> WorldState | None:
        """The latest whole simulation state (at most ``WORLD_PERIOD`` ms of simulation old),
        or None when it was not asked for (``world_state=False``), before ``start``, after
        ``stop``, or before the loop published one. Do not call it concurrently with ``stop``."""
        block = self._world
        raw = block.read() if block is not None else None
        if raw is None:
            return None
        values = np.frombuffer(raw, dtype=np.float64)
        return WorldState(sim_time=float(values[0]), qpos=values[1:])

    def timing(self, sim_time: float | None = None) -> TimingStats:
        """The loop's deadline statistics (computed here, from the shared monitor) at
        ``sim_time`` (default: that of the latest robot state), with the world process's
        timing (``TimingStats.world``) when the loop controls one. Raises ``RuntimeError``
        before ``start``."""
        if self._monitor is None or self._state_reader is None:
            raise RuntimeError("executor loop not started")
        if sim_time is None:
            sim_time = self._state_reader.sim_time() or 0.0
        self._monitor.setup = self.setup
        self._monitor.control_law = self.control_law
        self._monitor.plant = self.plant
        stats = self._monitor.stats(sim_time)
        world = self._world_timing()
        return stats if world is None else msgspec.structs.replace(stats, world=world)

    def _world_timing(self) -> WorldTiming | None:
        """The world process's timing counts (velma/world/timing.py), read from its link
        (attached on first use and kept: the counts stay readable after the world ended);
        None without a world process or when its link is not there."""
        if not self.world_link:
            return None
        if self._world_counts is None:
            try:
                self._world_counts = RobotLink.attach(self.world_link)
            except (FileNotFoundError, LinkError):
                return None
        return WorldTiming.read(self._world_counts.counters)

    # ------------------------------------------------------------------ reader thread
    def _read(self) -> None:
        assert self._bell is not None and self._results is not None
        fd = self._bell.fileno()
        while True:
            try:
                news = os.read(fd, 4096)
            except OSError:
                news = b""
            self._drain()
            if not news:
                break  # EOF: the loop process has exited
        proc = self._proc
        if proc is not None:
            proc.join(1.0)
            code = proc.exitcode
            if self.exit_reason is None:
                self.exit_reason = f"loop process exited with code {code}"
        self._fail_open(self.exit_reason or "loop process exited")
        self._ready.set()

    def _drain(self) -> None:
        results = self._results
        if results is None:
            return
        while (raw := results.pop()) is not None:
            msg = self._decode(raw)
            if isinstance(msg, Started):
                self._hook(self.on_start, msg.token, msg.command, msg.sim_time)
            elif isinstance(msg, Done):
                self._ended(msg)
                if self._delivery is not None:
                    self._delivery.put(msg.token, msg.result)
                elif not isinstance(msg.result, WorldCapture):
                    self._answer(msg.token, msg.result)
                else:  # no camera any more (stopping): the Observe is answered, not lost
                    stopped = CommandResult(
                        command="observe", ok=False, reason="stopped", sim_time=msg.result.stamp
                    )
                    self._answer(msg.token, stopped)
            elif isinstance(msg, Halting):
                self.halts.append(msg)
                log.info(
                    "halt: %s (token %d) halted by a cancel at wall time %.6f, sim time %.3f s",
                    msg.command,
                    msg.token,
                    msg.wall_time,
                    msg.sim_time,
                )
            elif isinstance(msg, Ready):
                self.setup = msg.setup
                self.control_law = msg.control_law
                self.plant = msg.plant
                self._ready.set()
            elif msg.command == START:
                self.exit_reason = msg.text
            else:
                log.error("executor command %s raised %s", msg.command, msg.text)

    def _ended(self, msg: Done) -> None:
        """Tell ``on_end`` that the loop ended the command of ``msg``."""
        if self.on_end is None:
            return
        with self._lock:
            entry = self._callbacks.get(msg.token)
        name = entry[1] if entry is not None else "?"
        result = msg.result
        at = result.sim_time if isinstance(result, CommandResult) else result.stamp
        self._hook(self.on_end, msg.token, name, at, outcome_of(result), result)

    @staticmethod
    def _hook(hook: Callable[..., None] | None, *args: object) -> None:
        if hook is None:
            return
        try:
            hook(*args)
        except Exception:
            log.exception("executor hook raised")

    def _answer(self, token: int, result: CommandResult | Observation) -> None:
        with self._lock:
            entry = self._callbacks.pop(token, None)
        if entry is None:
            return
        try:
            entry[0](result)
        except Exception:
            log.exception("on_done callback raised")

    def _fail_open(self, reason: str) -> None:
        with self._lock:
            open_ = list(self._callbacks.items())
            self._callbacks.clear()
        for _token, (on_done, name) in open_:
            try:
                on_done(CommandResult(command=name, ok=False, reason=reason))
            except Exception:
                log.exception("on_done callback raised")
