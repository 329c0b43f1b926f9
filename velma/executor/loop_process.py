"""ag_ex's loop process (started with spawn by velma/executor/process.py ``ExecutorProcess``):
the 1 kHz control loop (velma/executor/loop.py) with the commands, results, robot and world
state passed through shared memory (velma/executor/loop_wire.py); it imports neither Zenoh nor
the communication side."""

from __future__ import annotations

import collections
import contextlib
import gc
import multiprocessing.connection
import os
import signal
import time
from multiprocessing import shared_memory

import msgspec
import numpy as np

from shared.fipa_codec.languages.l_ex import CommandResult, command_decoder, command_name
from velma.executor.handoff import LatestValue, SpscRing, shared_view
from velma.executor.ledger import STOPPED
from velma.executor.loop_wire import (
    DT,
    INBOX_PER_CYCLE,
    LOOP_PROCESS_NAME,
    PARENT_CHECK,
    SLOT_SIZE,
    SLOTS,
    START,
    STATE_CAPACITY,
    STATE_PERIOD,
    STATE_PHASE,
    WORLD_CAPACITY,
    WORLD_PERIOD,
    WORLD_PHASE,
    Cancel,
    Displace,
    Done,
    Fault,
    Halting,
    Hold,
    LoopConfig,
    Pace,
    Ready,
    Safe,
    Started,
    Submit,
    ToLoop,
)
from velma.executor.timing import DeadlineMonitor, Pacer
from velma.realtime import RealtimeSetup


def loop_main(config: bytes, doorbell: multiprocessing.connection.Connection) -> None:
    """Entry point of the loop process (started with spawn by ``ExecutorProcess``)."""
    from velma.gl import never_renders

    never_renders()  # the loop renders nothing (the head camera's process does): no GL platform
    from velma.executor.loop import ControlLoop
    from velma.executor.runtime import Runtime
    from velma.executor.state_block import StateWriter
    from velma.realtime import enter_realtime, name_process
    from velma.world.link import RobotLink

    name_process(LOOP_PROCESS_NAME)
    cfg = msgspec.msgpack.decode(config, type=LoopConfig)
    inbox = SpscRing.attach(cfg.commands, SLOTS, SLOT_SIZE)
    outbox_ring = SpscRing.attach(cfg.results, SLOTS, SLOT_SIZE)
    state = LatestValue.attach(cfg.state, STATE_CAPACITY)
    state_names = LatestValue.attach(cfg.state_names, STATE_CAPACITY)
    world = LatestValue.attach(cfg.world, WORLD_CAPACITY) if cfg.world else None
    mon_shm = shared_memory.SharedMemory(name=cfg.monitor)
    monitor = DeadlineMonitor(DT, realtime=cfg.realtime, window=cfg.window, buffer=shared_view(mon_shm))
    bell = doorbell.fileno()
    os.set_blocking(bell, False)
    encode = msgspec.msgpack.Encoder().encode
    decode = msgspec.msgpack.Decoder(ToLoop).decode
    read_command = command_decoder()

    try:
        link = RobotLink.attach(cfg.world_link) if cfg.world_link else None
        rt = Runtime(seed=cfg.seed, pose_seed=cfg.pose_seed, link=link)
    except Exception as exc:  # say why before the process exits: ExecutorProcess.start raises it
        outbox_ring.push(encode(Fault(command=START, text=f"{type(exc).__name__}: {exc}")))
        with contextlib.suppress(BlockingIOError, BrokenPipeError):
            os.write(bell, b"\x01")
        raise
    rt.observe_by_camera = cfg.camera
    loop: ControlLoop[int] = ControlLoop(rt)
    running = True

    def on_signal(_signum: int, _frame: object) -> None:
        nonlocal running
        running = False  # end after this cycle

    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)
    if cfg.realtime and cfg.realtime_priority:
        setup = enter_realtime(cpu=cfg.cpu, pin=cfg.pin)
    else:
        setup = RealtimeSetup(
            policy="SCHED_OTHER",
            priority=0,
            cpus=tuple(sorted(os.sched_getaffinity(0))) if hasattr(os, "sched_getaffinity") else (),
            pinned=False,
            notes=("not requested",),
        )
    pending: collections.deque[bytes] = collections.deque()

    def ring() -> None:
        while pending and outbox_ring.push(pending[0]):
            pending.popleft()
        # a full pipe means the reader has a wake-up pending anyway; broken: the parent is gone
        with contextlib.suppress(BlockingIOError, BrokenPipeError):
            os.write(bell, b"\x01")

    world_buf = np.zeros(1 + rt.model.nq)  # [sim_time, qpos…], reused
    if world is not None and world_buf.nbytes > WORLD_CAPACITY - 4:
        pending.append(encode(Fault(command="world state", text=f"nq={rt.model.nq} does not fit")))
        world = None
    from velma.control.compiled import law_name  # the loop's side only: it loads Pinocchio

    pending.append(
        encode(
            Ready(
                pid=os.getpid(),
                setup=setup,
                control_law=law_name(rt.ctrl),
                plant=rt.plant_name,
            )
        )
    )
    publisher = StateWriter(rt, state, state_names)
    publisher.publish(loop.holding)
    ring()
    # the scene and the controller are built: everything allocated so far lives for the whole
    # run; freezing it keeps the collector's passes short (gc.freeze, Python ≥ 3.7)
    gc.collect()
    gc.freeze()

    cycle = rt.cycles  # > 0 attached to a running world: the phases stay those of its contact scans
    pacer = Pacer(DT, realtime=cfg.realtime and link is None, spin=cfg.spin)  # a world paces itself
    while running:
        start = pacer.begin()
        cpu = time.thread_time()
        for _ in range(INBOX_PER_CYCLE):
            raw = inbox.pop()
            if raw is None:
                break
            msg = decode(raw)
            if isinstance(msg, Submit):
                try:
                    loop.submit(msg.token, read_command(msg.command))
                except msgspec.ValidationError:  # no row of COMMANDS in this process
                    unknown = f"not an executor command in the loop's process: {msg.name}"
                    failed = CommandResult(command=msg.name, ok=False, reason=unknown, sim_time=rt.time)
                    pending.append(encode(Done(token=msg.token, result=failed)))
            elif isinstance(msg, Cancel):
                ended = loop.cancel(msg.token)
                if ended == [] and loop.current is not None:  # it runs: the halt begins now
                    name = command_name(loop.current[1])
                    halt = Halting(token=msg.token, command=name, wall_time=time.time(), sim_time=rt.time)
                    pending.append(encode(halt))
                pending.extend(encode(Done(token=t, result=r)) for t, r in ended or ())
            elif isinstance(msg, Hold):
                pending.extend(encode(Done(token=t, result=r)) for t, r in loop.hold(msg.why))
            elif isinstance(msg, Safe):
                pending.extend(encode(Done(token=t, result=r)) for t, r in loop.safe(msg.why))
            elif isinstance(msg, Displace):
                try:
                    loop.rt.displace(msg.body, msg.delta, msg.tilt)
                except (KeyError, ValueError) as exc:
                    pending.append(encode(Fault(command="displace", text=str(exc))))
            elif isinstance(msg, Pace):
                try:
                    pacer.pace(msg.factor or None)
                except ValueError as exc:
                    pending.append(encode(Fault(command="pace", text=str(exc))))
            else:
                running = False
        done = loop.cycle()
        while loop.started:  # after the control step, like the results
            token, name, at = loop.started.popleft()
            pending.append(encode(Started(token=token, command=name, sim_time=at)))
        if done is not None:
            pending.append(encode(Done(token=done[0], result=done[1])))
        while loop.errors:
            name, text = loop.errors.popleft()
            pending.append(encode(Fault(command=name, text=text)))
        if pending:
            ring()
        if cycle % STATE_PERIOD == STATE_PHASE:
            publisher.publish(loop.holding)
        if world is not None and cycle % WORLD_PERIOD == WORLD_PHASE:
            world_buf[0] = rt.data.time
            world_buf[1:] = rt.data.qpos
            world.write(world_buf.tobytes())
        if cycle % PARENT_CHECK == 0 and os.getppid() != cfg.parent_pid:
            running = False  # orphaned: the communication side is gone
        cycle += 1
        cpu = time.thread_time() - cpu
        end = time.perf_counter()
        if link is not None:  # the world paces: the cycle's work is all but the wait for its state
            start += rt.waited_s
            monitor.record(start, start, end, rt.part_s, cpu)
        else:
            monitor.record(pacer.release, start, end, rt.part_s, cpu)
        pacer.wait(rt.time)  # the simulation's time: paced while watched (Pacer.pace)
    pending.extend(encode(Done(token=t, result=r)) for t, r in loop.abort(STOPPED))
    ring()
    del monitor
    publisher.close()  # its plant holds a view of the state block
    for block in (inbox, outbox_ring, state, state_names, world):
        if block is not None:
            block.close()
    mon_shm.close()
    if link is not None:
        link.close()
