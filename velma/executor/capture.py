"""What an Observe hands off from the 1 kHz loop: the world state to perceive, not the
perception (the loop never renders or fits).

In camera mode (velma/executor/observer.py) ``ObservePrimitive`` ends at once with a
``WorldCapture``: the requested object names, the simulation time and a copy of MuJoCo's whole
``qpos`` (180 float64 in the kitchen: ≈ 1.4 kB, a copy of a few µs). The host (``Executor``'s
or ``ExecutorProcess``'s ``ResultDelivery``, velma/executor/delivery.py) renders and localises
it outside the loop and delivers the L_SD ``Observation`` in the command's place. Pure
msgspec and numpy: no MuJoCo, so it crosses the loop process's result ring as it is.
"""

from __future__ import annotations

from collections.abc import Mapping

import msgspec
import numpy as np
import numpy.typing as npt

from shared.settings import Settings
from velma.gl import HOW as GL_HOW
from velma.gl import renders

PERCEPTION_LOG = "ag_ex_perception.jsonl"
"""The file in the run folder where ag_ex logs each camera Observation beside the truth
(velma/executor/perception_log.py; read by the run report, services/report)."""
DEFAULT_PERCEPTION = "camera"
"""``ROCO_PERCEPTION`` when unset: the head camera (velma/executor/observer.py). The pour's
fleet with it: 20 of 20 pose seeds succeed, the content check passing on the camera's count;
that count sees content spilled in view, not a sphere gone out of view from behind the bowl's
wall (docs/bench/observe.md). ``ROCO_PERCEPTION=truth`` answers from the physics (tests, and to
compare). On a machine without an off-screen GL library (velma/gl.py) the default is
``truth``: see :func:`perception_mode`."""


def perception_mode(environ: Mapping[str, str] | None = None) -> str:
    """``ROCO_PERCEPTION`` of ``environ`` (default ``os.environ``, read now). Unset or empty:
    ``DEFAULT_PERCEPTION`` where MuJoCo can render off-screen, else ``truth`` (a machine
    without libEGL or libOSMesa still runs the robot; :func:`camera_unavailable` says why).
    Raises ``ValueError`` for a value other than ``camera`` and ``truth``."""
    value = Settings.from_env(environ, only=("perception",)).perception
    if value is None:
        return DEFAULT_PERCEPTION if camera_unavailable() is None else "truth"
    return value


def camera_unavailable() -> str | None:
    """Why the head camera cannot render on this machine (no off-screen GL library for MuJoCo,
    velma/gl.py, with the packages to install), or None."""
    if renders():
        return None
    return f"no off-screen GL library (libEGL or libOSMesa) for the head camera: {GL_HOW}"


class WorldCapture(msgspec.Struct, frozen=True, tag="world_capture", kw_only=True, omit_defaults=True):
    """The world when an Observe ran: ``objects`` asked for (empty: all known), ``stamp``
    (simulation time, s) and ``qpos`` (MuJoCo's ``qpos`` as raw little-endian float64 bytes,
    ``model.nq`` values). ``watch``: a watch frame (velma/executor/watch.py), observed in the
    observer's cheaper watch mode (velma/executor/observer.py ``CameraObserver.observe``), not
    an Observe."""

    objects: tuple[str, ...]
    stamp: float
    qpos: bytes
    watch: bool = False

    @classmethod
    def of(
        cls, objects: tuple[str, ...], stamp: float, qpos: npt.NDArray[np.float64], *, watch: bool = False
    ) -> WorldCapture:
        """A capture of ``qpos`` (copied) at ``stamp`` (``watch``: a watch frame)."""
        return cls(objects=objects, stamp=stamp, qpos=np.asarray(qpos, dtype="<f8").tobytes(), watch=watch)

    def positions(self) -> npt.NDArray[np.float64]:
        """``qpos`` as an array (shape ``(nq,)``, a read-only view)."""
        return np.frombuffer(self.qpos, dtype="<f8")
