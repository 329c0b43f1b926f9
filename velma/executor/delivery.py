"""Results from the loop to the caller, in the loop's order, with an Observe's world capture
turned into the camera's Observation on the way (issue 19: outside the 1 kHz loop).

``ResultDelivery`` is one worker thread with a FIFO: ``put(token, result)`` from the host
(loop thread or reader thread; never blocks); the thread hands each result to ``deliver`` in
the order they were put, and a ``WorldCapture`` (velma/executor/capture.py) first becomes an
L_SD ``Observation`` by ``CameraObserver`` (velma/executor/observer.py, made in this thread: its
GL context is the thread's). Ordering (chosen): a result never overtakes one put before it, so
a command that ends while an Observe's image is being processed (≈ 0.2 s) is answered after
that Observation — a caller sees results in the order the commands ended in the loop. The
loop itself does not wait: it runs the next command meanwhile.

A perception that raises answers the Observe with ``CommandResult(ok=False, reason="perception
error: …")``. With ``record`` each camera Observation is compared with the ground truth of the
same captured state (velma/executor/perception_log.py) and the records passed to ``record``.
"""

from __future__ import annotations

import logging
import queue
import threading
import time
from collections.abc import Callable
from typing import Any, Generic, TypeVar

from shared.fipa_codec.languages.l_ex import CommandResult
from shared.fipa_codec.languages.l_sd import Observation
from velma.executor.capture import WorldCapture

log = logging.getLogger(__name__)

T = TypeVar("T")
Item = CommandResult | Observation | WorldCapture
RecordSink = Callable[[list[dict[str, Any]]], None]
Deliver = Callable[[Any, CommandResult | Observation], None]
MakeModel = Callable[[], Any]
"""Builds the kitchen's ``mujoco.MjModel`` the loop runs (same seeds)."""


class ResultDelivery(Generic[T]):
    """The delivery thread (module docstring). ``make_model`` builds the MjModel for the
    camera (called in the thread, at its start, so that the first Observe does not wait for
    it); ``size`` the frame (px); ``seed`` the Kinect noise's seed."""

    def __init__(
        self,
        deliver: Callable[[T, CommandResult | Observation], None],
        make_model: MakeModel | None,
        *,
        size: tuple[int, int] | None = None,
        seed: int = 0,
        record: RecordSink | None = None,
        name: str = "velma-observe",
    ) -> None:
        self._deliver = deliver
        self._make_model = make_model
        self._size = size
        self._seed = seed
        self._record = record
        self._queue: queue.SimpleQueue[tuple[T, Item] | None] = queue.SimpleQueue()
        self._observer: Any = None
        self._truth: Any = None
        self.observe_ms: list[float] = []
        """Wall time (ms) of each camera Observation made (render + localisation)."""
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
        if self._make_model is not None:
            try:
                self._start_observer()
            except Exception:
                log.exception("the camera perception could not be built")
        while (item := self._queue.get()) is not None:
            token, result = item
            out = self._observe(result) if isinstance(result, WorldCapture) else result
            try:
                self._deliver(token, out)
            except Exception:
                log.exception("delivering a result raised")
        if self._observer is not None:
            self._observer.close()

    def _start_observer(self) -> None:
        from velma.executor.observer import CAMERA_SIZE, CameraObserver

        assert self._make_model is not None
        model = self._make_model()
        self._observer = CameraObserver(model, self._size or CAMERA_SIZE, self._seed)
        if self._record is not None:
            from velma.executor.ground_truth import GroundTruth

            self._truth = GroundTruth(model)

    def _observe(self, capture: WorldCapture) -> CommandResult | Observation:
        if self._observer is None:
            return CommandResult(
                command="observe", ok=False, reason="perception error: no camera", sim_time=capture.stamp
            )
        try:
            t0 = time.perf_counter()
            obs, seen = self._observer.observe(capture)
            ms = 1e3 * (time.perf_counter() - t0)
            self.observe_ms.append(ms)
        except Exception as exc:
            log.exception("the camera perception raised")
            return CommandResult(
                command="observe", ok=False, reason=f"perception error: {exc}", sim_time=capture.stamp
            )
        if self._record is not None and self._truth is not None:
            try:
                from velma.executor.perception_log import records

                self._record(records(obs, seen, self._truth, self._observer.data, ms))
            except Exception:
                log.exception("the perception log raised")
        return obs
