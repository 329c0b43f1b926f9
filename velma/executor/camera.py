"""The camera's work for ``ResultDelivery`` (velma/executor/delivery.py): a world capture in,
an Observation (and the perception log's records) out, and where that work runs.

- ``CameraWork`` builds ``CameraObserver`` (velma/executor/observer.py) for a kitchen model
  and, with a log, ``GroundTruth`` of the same model; ``perceive(capture)`` observes. The
  Kinect's noise comes from one generator seeded when the work is built (the observer's), so
  a camera host that is built again (a restarted ag_ex, or ``CameraProcess`` after a rest)
  starts the noise sequence again, as a restarted ag_ex always did.
- ``InThreadCamera`` runs it in the delivery thread (``velma.executor.core.Executor``: tests and
  tools with the loop in-process).
- ``CameraProcess`` (velma/executor/camera_process.py) runs it in a process of its own
  (ag_ex: ``ExecutorProcess``).

A host's ``warm()`` prepares it without waiting, ``perceive`` waits for the answer, ``rest()``
frees what an idle host holds, ``close()`` ends it. Every method is called from the delivery
thread only (the renderer's GL context belongs to the thread that made it).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from typing import Any, Protocol

import msgspec

from shared.fipa_codec.languages.l_sd import Observation
from velma.executor.capture import WorldCapture

log = logging.getLogger(__name__)

Record = dict[str, Any]
"""One perception-log record (velma/executor/perception_log.py)."""


class Perceived(msgspec.Struct, frozen=True, kw_only=True):
    """What one Observe gave: the ``observation``, or ``reason`` (one line) why there is none;
    ``records`` for the perception log (None without a log); ``ms`` the render and
    localisation's wall time (ms)."""

    observation: Observation | None = None
    reason: str | None = None
    records: list[Record] | None = None
    ms: float = 0.0


class CameraHost(Protocol):
    """Where the camera's work runs (module docstring)."""

    def warm(self) -> None: ...

    def perceive(self, capture: WorldCapture) -> Perceived: ...

    def rest(self) -> None: ...

    def close(self) -> None: ...


class CameraWork:
    """The observer (and, with ``record``, the ground truth) of ``model`` (an
    ``mujoco.MjModel``): frames of ``size`` px (w, h; None: velma/executor/observer.py
    ``CAMERA_SIZE``), the Kinect's noise from a generator seeded with ``seed`` (module
    docstring). Building takes ≈ 0.3 s (the object models and ICP targets)."""

    def __init__(self, model: Any, size: tuple[int, int] | None, seed: int, record: bool) -> None:
        from velma.executor.observer import CAMERA_SIZE, CameraObserver

        self.observer = CameraObserver(model, size or CAMERA_SIZE, seed)
        self.truth: Any = None
        if record:
            from velma.executor.ground_truth import GroundTruth

            self.truth = GroundTruth(model)

    def perceive(self, capture: WorldCapture) -> Perceived:
        """Observe ``capture``; an exception of the perception becomes ``reason``
        ("perception error: …"), one of the log a missing ``records``. A watch frame
        (``capture.watch``) has no records: the perception log holds the Observes."""
        try:
            t0 = time.perf_counter()
            obs, seen = self.observer.observe(capture)
            ms = 1e3 * (time.perf_counter() - t0)
        except Exception as exc:
            return Perceived(reason=f"perception error: {exc}")
        records: list[Record] | None = None
        if self.truth is not None and not capture.watch:
            try:
                from velma.executor.perception_log import records as log_records

                records = log_records(obs, seen, self.truth, self.observer.data, ms)
            except Exception:
                log.exception("the perception log raised")
        return Perceived(observation=obs, records=records, ms=ms)

    def close(self) -> None:
        """Free the renderer (from the thread that observed)."""
        self.observer.close()


class InThreadCamera:
    """``CameraWork`` in the calling (delivery) thread, built by ``warm`` from ``make_model()``
    (a ``mujoco.MjModel``). A build that raises leaves no camera: each Observe is answered
    "perception error: no camera" and the build is not retried."""

    def __init__(
        self, make_model: Callable[[], Any], size: tuple[int, int] | None, seed: int, record: bool
    ) -> None:
        self._make_model: Callable[[], Any] | None = make_model
        self._args = (size, seed, record)
        self._work: CameraWork | None = None

    def warm(self) -> None:
        """Build the camera work once (≈ 0.3 s plus ``make_model``); later calls do nothing."""
        if self._make_model is None:
            return
        make, self._make_model = self._make_model, None
        try:
            self._work = CameraWork(make(), *self._args)
        except Exception:
            log.exception("the camera perception could not be built")

    def perceive(self, capture: WorldCapture) -> Perceived:
        """``CameraWork.perceive`` of ``capture``; without a camera, ``reason`` says so."""
        self.warm()
        if self._work is None:
            return Perceived(reason="perception error: no camera")
        return self._work.perceive(capture)

    def rest(self) -> None:
        """Nothing: the in-thread camera keeps its renderer."""

    def close(self) -> None:
        """Free the renderer (from the delivery thread)."""
        if self._work is not None:
            self._work.close()
            self._work = None
