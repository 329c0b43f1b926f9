"""Results from the loop to the caller, in the loop's order, with an Observe's world capture
turned into the camera's Observation on the way (outside the 1 kHz loop).

``ResultDelivery`` is one worker thread with a FIFO: ``put(token, result)`` from the host
(loop thread or reader thread; never blocks); the thread hands each result to ``deliver`` in
the order they were put, and a ``WorldCapture`` (velma/executor/capture.py) first becomes an
L_SD ``Observation`` by the camera host (velma/executor/camera.py: in this thread, or in a
process of its own, velma/executor/camera_process.py). Ordering (chosen): a result never
overtakes one put before it, so a command that ends while an Observe's image is being processed
(≈ 0.2 s) is answered after that Observation — a caller sees results in the order the commands
ended in the loop. The loop itself does not wait: it runs the next command meanwhile.

The camera host is warmed at the thread's start and whenever another result passes (a task is
running: its Observe should not wait for the camera to start), and rested after
``rest_after_s`` without any result.

A perception that raises answers the Observe with ``CommandResult(ok=False, reason="perception
error: …")``. With ``record`` each camera Observation is compared with the ground truth of the
same captured state (velma/executor/perception_log.py) and the records passed to ``record``.
A watch frame (``WorldCapture.watch``, velma/executor/watch.py) goes through the same FIFO and
camera host, so it is never delivered out of order with the results; it has no records.
"""

from __future__ import annotations

import logging
import math
import queue
import threading
from collections.abc import Callable
from typing import Any, Generic, TypeVar

from shared.fipa_codec.languages.l_ex import CommandResult
from shared.fipa_codec.languages.l_sd import Observation
from velma.executor.camera import CameraHost, Perceived
from velma.executor.capture import WorldCapture

log = logging.getLogger(__name__)

T = TypeVar("T")
Item = CommandResult | Observation | WorldCapture
RecordSink = Callable[[list[dict[str, Any]]], None]
Deliver = Callable[[Any, CommandResult | Observation], None]


class ResultDelivery(Generic[T]):
    """The delivery thread (module docstring). ``camera``: where captures are observed (None:
    each Observe is answered "perception error: no camera"); ``rest_after_s`` seconds without a
    result before the camera host rests (``math.inf``: never); ``record`` receives the
    perception log's records."""

    def __init__(
        self,
        deliver: Callable[[T, CommandResult | Observation], None],
        camera: CameraHost | None,
        *,
        rest_after_s: float = math.inf,
        record: RecordSink | None = None,
        name: str = "velma-observe",
    ) -> None:
        self._deliver = deliver
        self._camera = camera
        self._rest_after_s = None if math.isinf(rest_after_s) else rest_after_s
        self._record = record
        self._queue: queue.SimpleQueue[tuple[T, Item] | None] = queue.SimpleQueue()
        self.observe_ms: list[float] = []
        """Wall time (ms) of each camera Observation made (render + localisation)."""
        self.watch_ms: list[float] = []
        """Wall time (ms) of each watch frame observed (``WorldCapture.watch``)."""
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    def put(self, token: T, result: Item) -> None:
        """Deliver ``result`` for ``token`` after everything put before it."""
        self._queue.put((token, result))

    def close(self, timeout: float = 30.0) -> None:
        """Deliver what was put, then end the thread (waits up to ``timeout`` s)."""
        self._queue.put(None)
        self._thread.join(timeout)

    def _run(self) -> None:
        camera = self._camera
        if camera is not None:
            self._safely(camera.warm)
        resting = False
        while True:
            try:
                item = self._queue.get(timeout=self._rest_after_s)
            except queue.Empty:
                if camera is not None and not resting:
                    self._safely(camera.rest)
                resting = True
                continue
            if item is None:
                break
            token, result = item
            if isinstance(result, WorldCapture):
                out: CommandResult | Observation = self._observe(result)
            else:
                out = result
                if resting and camera is not None:
                    self._safely(camera.warm)
            resting = False
            try:
                self._deliver(token, out)
            except Exception:
                log.exception("delivering a result raised")
        if camera is not None:
            self._safely(camera.close)

    @staticmethod
    def _safely(action: Callable[[], None]) -> None:
        """Run a camera host's ``warm``/``rest``/``close``: what it raises is logged, and the
        delivery of results goes on (an Observe then says why it has no camera)."""
        try:
            action()
        except Exception:
            log.exception("the camera host raised")

    def _observe(self, capture: WorldCapture) -> CommandResult | Observation:
        failed = "perception error: no camera"
        if self._camera is not None:
            try:
                got = self._camera.perceive(capture)
            except Exception as exc:
                log.exception("the camera host raised")
                got = Perceived(reason=f"perception error: {exc}")
            if got.observation is not None:
                (self.watch_ms if capture.watch else self.observe_ms).append(got.ms)
                if self._record is not None and got.records is not None:
                    try:
                        self._record(got.records)
                    except Exception:
                        log.exception("the perception log raised")
                return got.observation
            failed = got.reason or failed
            log.error("the camera perception failed: %s", failed)
        return CommandResult(command="observe", ok=False, reason=failed, sim_time=capture.stamp)
