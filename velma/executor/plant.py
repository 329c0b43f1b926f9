"""The compiled MuJoCo side of ag_ex's cycle: ``CompiledPlant`` wraps the C++
``Plant`` of velma/control/_plant.hpp for a ``Runtime``.

With it, ``Runtime.cycle`` (the hands' and the head's servo steps, the state gather, the
compiled law, the torques into ``data.ctrl``, ``mj_step``), the contact scans and the robot
state's numbers run in C++ on MuJoCo's own ``mjData``, with no Python object per value. The
Python path of ``Runtime.cycle`` stays the reference: tests/velma/test_plant.py runs both side
by side and compares the simulated robot's motion, the scans and the state bit for bit.

``plant_unavailable`` says why a runtime cannot have one: the Python law runs
(``ROCO_CONTROL_LAW=python``), the module was built without MuJoCo's headers, or the running
``mujoco`` is another version than the headers it was built with (the struct layout of
``mjData`` changes between versions; setup.py takes the headers from the ``mujoco`` wheel of
the build). Then ``Runtime`` runs the Python cycle.
"""

from __future__ import annotations

import mujoco
import numpy as np
import numpy.typing as npt

from velma.control.compiled import CompiledController
from velma.control.hand import ContactMonitor, Hands
from velma.control.joints import SIDES, Array, JointMap
from velma.control.mujoco_side import bind_servos, make_plant, mujoco_side_unavailable
from velma.executor.state import LINK_BODIES, raw_layout


def plant_unavailable(ctrl: object) -> str | None:
    """Why a runtime with controller ``ctrl`` cannot run the compiled plant, or None when it
    can (module docstring)."""
    if not isinstance(ctrl, CompiledController):
        return "the Python law runs"
    return mujoco_side_unavailable()


class CompiledPlant:
    """The C++ plant of one runtime (module docstring). ``arm_act`` the arm motors by side (7
    each), ``torso_act`` the torso motor; ``state_index`` the Pinocchio v indices of the
    snapshot's joints, ``grip_site`` the grip sites by side, ``link_ids`` the bodies of
    ``LINK_BODIES``, ``ft_adr`` per side the sensordata addresses of force and torque.
    Raises RuntimeError when ``plant_unavailable`` gives a reason, ValueError from the C++
    constructor on indices that do not fit the model."""

    def __init__(
        self,
        model: mujoco.MjModel,
        data: mujoco.MjData,
        ctrl: CompiledController,
        jmap: JointMap,
        contacts: ContactMonitor,
        *,
        arm_act: dict[str, npt.NDArray[np.int64]],
        torso_act: int,
        state_index: npt.NDArray[np.intp],
        grip_site: dict[str, int],
        link_ids: npt.NDArray[np.intp],
        ft_adr: dict[str, tuple[int, int]],
    ) -> None:
        why = plant_unavailable(ctrl)
        if why is not None:
            raise RuntimeError(f"no compiled plant: {why}")
        self.ctrl = ctrl
        self._plant = make_plant(
            model, data, jmap, contacts, [int(a) for s in SIDES for a in arm_act[s]], int(torso_act)
        )
        nv = len(jmap.qpos_adr)
        self.q = np.zeros(nv)
        """Pinocchio q (rad, (nv,)) that the last cycle's law used."""
        self.v = np.zeros(nv)
        """Pinocchio v (rad/s, (nv,)) that the last cycle's law used."""
        self.parts = np.zeros(2)
        """The last cycle's seconds: gather and law, mj_step."""
        ctrl.bind_plant(self._plant, self.q, self.v, self.parts)
        if len(link_ids) != len(LINK_BODIES):
            raise ValueError(f"{len(link_ids)} link bodies, the raw state has {len(LINK_BODIES)}")
        self._plant.set_state_layout(
            jmap.qpos_adr[state_index].tolist(),
            [grip_site[s] for s in SIDES],
            link_ids.tolist(),
            [a for s in SIDES for a in ft_adr[s]],
            list(raw_layout(len(state_index))),
        )

    def bind_servos(
        self, hands: Hands, head: Array, head_act: tuple[int, int], *, dt: float, head_step: float
    ) -> None:
        """Step the hands' and the head's servo setpoints in ``cycle`` too, in C++ (as
        velma/control/hand.py ``Hands.step`` with ``dt`` (s), and runtime.py
        ``Runtime._step_head``): on ``hands.state`` and ``head`` (4,) float64 (pan and tilt
        setpoints, then targets; rad), with ``head_act`` the pan and tilt servos and
        ``head_step`` (rad) the most a setpoint moves in one cycle. Both arrays are bound, not
        copied: assign into them, never rebind them. Raises ValueError on sizes or indices that do not fit."""
        bind_servos(self._plant, hands, head, head_act, dt=dt, head_step=head_step)

    def bind_state_block(self, block: npt.NDArray[np.uint8], header: int) -> None:
        """Publish the robot state into ``block`` (a ``LatestValue``'s buffer, its value at
        ``header``) with ``publish_state`` (velma/executor/state_block.py). Raises ValueError
        for a block too small."""
        self._plant.bind_state_block(block, header)

    def release_state_block(self) -> None:
        """Let go of the block of ``bind_state_block``."""
        self._plant.release_state_block()

    def publish_state(self, names_version: int) -> None:
        """Write the values of velma/executor/state_block.py ``state_values`` into the bound
        block under its sequence lock. Raises RuntimeError before ``bind_state_block``."""
        self._plant.publish_state(names_version)

    def cycle(self) -> None:
        """The law, the torques into ``data.ctrl`` and one ``mj_step`` (velma/control/compiled.py
        ``CompiledController.step_plant``); raises as the law."""
        self.ctrl.step_plant(self._plant, self.q)

    def touching(self, side: str) -> dict[int, int]:
        """As ``ContactMonitor.touching``: {body id: distinct geoms of hand ``side`` touching it}."""
        return self._plant.touching(SIDES.index(side))

    def self_contacts(self) -> list[tuple[int, int]]:
        """As ``ContactMonitor.self_contacts``: (geom, geom) of the robot touching itself."""
        return self._plant.self_contacts()

    def gather(self, out: Array) -> None:
        """The numbers of velma/executor/gather.py ``raw_state`` that MuJoCo's data holds into
        ``out`` (its layout); the setpoint block is left as it is."""
        self._plant.gather(out)
