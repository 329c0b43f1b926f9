"""What ag_ex's two processes share: the loop process's name and timing constants, the blocks
of shared memory and their sizes, the messages of the hand-offs between the communication side
(velma/executor/process.py) and the loop process (velma/executor/loop_process.py), and the
world state read from them (velma/executor/process.py's module docstring says how they are
used)."""

from __future__ import annotations

from typing import NamedTuple

import msgspec
import numpy as np
import numpy.typing as npt

from shared.fipa_codec.languages.l_ex import CommandResult
from shared.fipa_codec.languages.l_sd import Observation
from velma.executor.capture import WorldCapture
from velma.realtime import RealtimeSetup

LOOP_PROCESS_NAME = "velma-loop"
"""The loop process's name in ``ps``, ``top`` and ``/proc/<pid>/comm`` (``name_process``)."""

DT = 0.001  # s (velma.executor.runtime.DT; repeated so that this module imports no MuJoCo)
SLOTS = 64  # messages per ring
SLOT_SIZE = 65536  # B per message (an L_SD Observation of the kitchen is ≈ 3 KiB)
STATE_CAPACITY = 65536  # B
STATE_PERIOD = 20  # cycles between robot-state publications (50 Hz)
STATE_PHASE = 3  # … in cycles 3, 23, 43…: not in those of the hands' contact scans (0, 5 mod 10)
INBOX_PER_CYCLE = 4  # messages taken from the command ring per cycle
PARENT_CHECK = 1000  # cycles between checks that the parent process still exists
DEFAULT_SPIN = 0.0003  # s before each release time that the real-time loop busy-waits instead of sleeping
TIMING_REFRESH = 1.0  # s between recomputations of the timing attached to snapshots
WORLD_PERIOD = 20  # cycles between world-state writes (50 Hz), when asked for (a watch frame's age)
WORLD_PHASE = 13  # … in cycles 13, 33…: neither a state publication nor a contact scan
WORLD_CAPACITY = 65536  # B: sim time + qpos of up to 8 190 coordinates (the kitchen has 180)
START_TIMEOUT = 120.0  # s for the loop process to build the scene and report Ready


class WorldState(NamedTuple):
    """The whole simulation state needed to draw the scene: ``sim_time`` (s) and MuJoCo's
    ``qpos`` (shape ``(model.nq,)``, float64: the robot's joints, the free objects' and
    particles' positions and unit quaternions)."""

    sim_time: float
    qpos: npt.NDArray[np.float64]


# ---------------------------------------------------------------------- wire messages
class Submit(msgspec.Struct, frozen=True, tag="submit"):
    """Run the L_EX command ``name`` whose msgpack bytes are ``command``; its result comes back
    as ``Done`` with the same ``token``. The loop decodes the command with the commands its own
    process knows (L_EX ``COMMANDS``, ``command_decoder``), not a fixed union: a command added
    with ``add_command`` reaches it as the built-in ones do (docs/executor.md, "Adding a robot
    primitive")."""

    token: int
    name: str
    command: msgspec.Raw


class Cancel(msgspec.Struct, frozen=True, tag="cancel"):
    """Halt the command submitted with ``token`` (velma.executor.loop ``ControlLoop.cancel``):
    queued, it ends at once; running, it is brought to rest and ends; either way its ``Done``
    says ``halted``. Nothing when it has ended already."""

    token: int


class Hold(msgspec.Struct, frozen=True, tag="hold"):
    """Hold position in joint impedance (velma.executor.loop), because ``why``."""

    why: str


class Safe(msgspec.Struct, frozen=True, tag="safe"):
    """Enter safe mode (velma.executor.loop), because ``why``."""

    why: str


class Displace(msgspec.Struct, frozen=True, tag="displace"):
    """Move free body ``body`` by ``delta`` (world, m) and tilt it by ``tilt`` (rad, about
    world x): a disturbance of the simulated world (velma.executor.runtime.Runtime.displace)."""

    body: str
    delta: tuple[float, float, float]
    tilt: float = 0.0


class Pace(msgspec.Struct, frozen=True, tag="pace"):
    """Pace the loop to at most ``factor`` × wall time (``Pacer.pace``, velma/executor/timing.py;
    the watch's pace); 0: the pacing it started with."""

    factor: float = 0.0


class Shutdown(msgspec.Struct, frozen=True, tag="shutdown"):
    """End the loop process (open commands end with ``stopped``)."""


class Ready(msgspec.Struct, frozen=True, tag="ready"):
    """The loop runs in process ``pid`` with ``setup`` (SCHED_FIFO? pinned?)."""

    pid: int
    setup: RealtimeSetup
    control_law: str = ""
    plant: str = ""


class Done(msgspec.Struct, frozen=True, tag="done"):
    """The result of the command submitted with ``token``."""

    token: int
    result: CommandResult | Observation | WorldCapture


class Started(msgspec.Struct, frozen=True, tag="started"):
    """The loop started the command submitted with ``token`` (L_EX name ``command``) in the
    cycle at ``sim_time`` (s): its motion primitive began (velma/executor/loop.py
    ``ControlLoop.started``)."""

    token: int
    command: str
    sim_time: float


class Halting(msgspec.Struct, frozen=True, tag="halting"):
    """The loop began to halt the running command ``command`` submitted with ``token`` in the
    cycle at ``wall_time`` (POSIX s, the loop's clock) and ``sim_time`` (s): from that cycle on
    its setpoints brake to rest (the halt event; its ``Done`` follows once at rest)."""

    token: int
    command: str
    wall_time: float
    sim_time: float


class Fault(msgspec.Struct, frozen=True, tag="fault"):
    """A motion primitive raised (``text``) while running ``command``; it was answered with a
    failure and the loop went on. Logged by the communication side. With ``command`` ``START``
    the loop could not start (``text`` says why) and its process exits."""

    command: str
    text: str


START = "start"
"""``Fault.command`` of a loop that could not start."""

ToLoop = Submit | Cancel | Hold | Safe | Displace | Pace | Shutdown
FromLoop = Ready | Started | Done | Halting | Fault


class LoopConfig(msgspec.Struct, frozen=True, kw_only=True):
    """What the loop process needs: pacing, scene seed, and the names of the shared blocks."""

    realtime: bool
    seed: int
    pose_seed: int | None
    realtime_priority: bool
    spin: float
    cpu: int | None
    pin: bool
    commands: str
    results: str
    state: str
    state_names: str
    monitor: str
    window: int
    parent_pid: int
    world: str = ""  # the world-state block ("": not published)
    camera: bool = True  # Observe ends with a WorldCapture (False: ground truth, ROCO_PERCEPTION=truth)
    world_link: str = ""  # the robot link of a world process to control ("": the physics runs here)
