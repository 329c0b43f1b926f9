"""ag_ex's camera in a process of its own (lean processes).

The head Kinect renders with MuJoCo's off-screen renderer on Mesa's software rasteriser
(llvmpipe): the first frame maps LLVM and Mesa and allocates the renderer's buffers, and a
process keeps much of that memory (≈ 80 MiB, docs/benchmarks.md) after the renderer is
closed. ``CameraProcess`` therefore runs ``CameraWork`` (velma/executor/camera.py)
in a child process, started with spawn (zenoh and GL must not be inherited across fork) and
ended when the camera has been idle for ``idle_s`` (``ResultDelivery.rest``): while the robot
observes, the fleet holds the renderer; at rest it does not. A fault in the renderer ends the
child, not ag_ex: that Observe is answered ``perception error: the camera process ended …``
and the next one starts a new child.

- ``warm()`` starts the child without waiting (≈ 0.7 s to import, build the kitchen and the
  object models; the first frame then ≈ 0.5 s more): ``ResultDelivery`` warms it at its start
  and whenever a command's result passes while it is not running, so the first Observe of a
  task seldom waits for the start.
- The child builds the kitchen from ``CameraSpec`` (the loop's seeds, velma/model/scene.py
  ``load_kitchen``) and answers one ``WorldCapture`` at a time over a pipe (msgpack), in order;
  it ends when the pipe closes (ag_ex ended or ``rest``/``close``).
- The Kinect's noise comes from a generator the child seeds when it starts
  (velma/executor/camera.py): a new child starts the noise sequence again.

``ROCO_CAMERA_IDLE_S`` (``camera_idle_s``) sets ``idle_s``: seconds (default
``DEFAULT_IDLE_S``), or ``never`` to keep the child for the whole run.
"""

from __future__ import annotations

import logging
import multiprocessing
import multiprocessing.connection
from collections.abc import Mapping
from typing import Any

import msgspec

from shared.settings import Settings
from velma.executor.camera import CameraWork, Perceived
from velma.executor.capture import WorldCapture
from velma.gl import choose as choose_gl

log = logging.getLogger(__name__)

DEFAULT_IDLE_S = Settings().camera_idle_s
"""Seconds without an Observe after which the camera process ends (module docstring): longer
than the gaps between a task's Observes (a pour observes at its start, after grasping and after
pouring, tens of seconds apart in real time), short enough that a fleet at rest holds no
renderer."""
ANSWER_TIMEOUT_S = 120.0
"""The longest an Observe may take in the child (start included) before it is answered with a
perception error and the child is ended (an Observe takes 0.2–1 s: docs/bench/observe.md)."""

PROCESS_NAME = "velma-camera"
"""The child's name in ``ps``, ``top`` and ``/proc/<pid>/comm``."""


class CameraSpec(msgspec.Struct, frozen=True, kw_only=True):
    """What the child needs to build the loop's kitchen and its camera: the content's
    ``seed`` and the objects' ``pose_seed`` (velma/model/scene.py ``load_kitchen``), the noise's
    ``noise_seed``, the frame ``size`` (w, h px; None: velma/executor/observer.py
    ``CAMERA_SIZE``) and whether to ``record`` the perception log."""

    seed: int
    pose_seed: int | None
    noise_seed: int
    size: tuple[int, int] | None = None
    record: bool = False


def camera_idle_s(environ: Mapping[str, str] | None = None) -> float:
    """``ROCO_CAMERA_IDLE_S`` of ``environ`` (default ``os.environ``, read now): s, > 0, or
    ``never`` → infinity; unset or empty → ``DEFAULT_IDLE_S``. Raises ``ValueError`` for
    anything else."""
    return Settings.from_env(environ, only=("camera_idle_s",)).camera_idle_s


def camera_main(spec: bytes, conn: multiprocessing.connection.Connection) -> None:
    """The child: build ``CameraWork`` from ``spec`` (msgpack ``CameraSpec``), then answer each
    request until the pipe closes. A build that fails answers every request with its reason."""
    from velma.model.scene import N_PARTICLES, load_kitchen
    from velma.realtime import name_process

    name_process(PROCESS_NAME)
    s = msgspec.msgpack.decode(spec, type=CameraSpec)
    work: CameraWork | None = None
    failed = ""
    try:
        work = CameraWork(load_kitchen(N_PARTICLES, s.seed, s.pose_seed), s.size, s.noise_seed, s.record)
    except Exception as exc:
        failed = f"perception error: the camera could not be built: {exc}"
    encode = msgspec.msgpack.Encoder().encode
    decode = msgspec.msgpack.Decoder(WorldCapture).decode
    try:
        while True:
            try:
                raw = conn.recv_bytes()
            except (EOFError, OSError):
                break
            capture = decode(raw)
            answer = work.perceive(capture) if work is not None else Perceived(reason=failed)
            conn.send_bytes(encode(answer))
    finally:
        if work is not None:
            work.close()


class CameraProcess:
    """The camera host in a child process (module docstring). Not thread-safe: the delivery
    thread calls it."""

    def __init__(self, spec: CameraSpec, answer_timeout_s: float = ANSWER_TIMEOUT_S) -> None:
        self.spec = spec
        self.answer_timeout_s = answer_timeout_s
        self.starts = 0
        """Children started so far (the first at ``warm``, then one after each rest or fault)."""
        self._proc: Any = None
        self._conn: multiprocessing.connection.Connection | None = None
        self._decode = msgspec.msgpack.Decoder(Perceived).decode
        self._encode = msgspec.msgpack.Encoder().encode

    @property
    def pid(self) -> int | None:
        """The running child's process id, or None."""
        return None if self._proc is None else int(self._proc.pid)

    def warm(self) -> None:
        """Start a child unless one runs (not waited for). Raises ``OSError`` if the process
        cannot be started (``ResultDelivery`` logs it; the Observe then fails with it)."""
        if self._proc is not None and self._proc.is_alive():
            return
        self._end()
        # MuJoCo reads MUJOCO_GL when it is first imported, and a spawned child imports this
        # process's __main__ module before camera_main runs: the environment it inherits must
        # hold the choice, or a main module that imports MuJoCo leaves it without a GL platform
        choose_gl()
        ctx = multiprocessing.get_context("spawn")
        mine, theirs = ctx.Pipe(duplex=True)
        spec = msgspec.msgpack.encode(self.spec)
        proc = ctx.Process(target=camera_main, args=(spec, theirs), name=PROCESS_NAME, daemon=True)
        proc.start()
        theirs.close()
        self._proc, self._conn = proc, mine
        self.starts += 1

    def perceive(self, capture: WorldCapture) -> Perceived:
        """The child's answer for ``capture`` (a child is started first if none runs). A child
        that ends or stays silent for ``answer_timeout_s`` s gives ``reason`` ("perception error:
        …") and is ended; the next call starts a new one."""
        self.warm()
        conn = self._conn
        assert conn is not None
        try:
            conn.send_bytes(self._encode(capture))
            if not conn.poll(self.answer_timeout_s):
                self._end()
                waited = f"{self.answer_timeout_s:.0f} s"
                return Perceived(reason=f"perception error: no answer from the camera process in {waited}")
            return self._decode(conn.recv_bytes())
        except (EOFError, OSError):
            code = self._end()
            return Perceived(reason=f"perception error: the camera process ended (exit code {code})")

    def rest(self) -> None:
        """End the child (it is started again by the next ``warm`` or Observe)."""
        if self._proc is not None:
            log.info("camera idle: its process %s ends", self._proc.pid)
        self._end()

    def close(self) -> None:
        """End the child, if any (waits up to 10 s, then kills it)."""
        self._end()

    def _end(self, timeout: float = 10.0) -> int | None:
        """Close the pipe (the child ends), join it (killed after ``timeout`` s); its exit
        code."""
        proc, conn = self._proc, self._conn
        self._proc = self._conn = None
        if conn is not None:
            conn.close()
        if proc is None:
            return None
        proc.join(timeout)
        if proc.is_alive():
            proc.kill()
            proc.join()
        code = proc.exitcode
        proc.close()
        return None if code is None else int(code)
