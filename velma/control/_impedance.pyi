"""Types of the compiled impedance law (velma/control/_impedance.cpp; used by
velma/control/compiled.py)."""

import numpy as np
import numpy.typing as npt

_F64 = npt.NDArray[np.float64]

class NotPositiveDefinite(ArithmeticError): ...

class Law:
    def __init__(self) -> None: ...
    def add_joint(
        self,
        parent: int,
        kind: int,
        axis: list[float],
        rot: list[float],
        pos: list[float],
        mass: float,
        com: list[float],
        inertia: list[float],
        armature: float,
        lower: float,
        upper: float,
        name: str,
    ) -> None: ...
    def add_grip(self, joint: int, rot: list[float], pos: list[float], name: str) -> None: ...
    def finish(self, arm_v0: list[int], torso: int, constants: list[float]) -> None: ...
    def dls_step(
        self,
        k: int,
        q: npt.NDArray[np.float64],
        target: npt.NDArray[np.float64],
        posture: npt.NDArray[np.float64],
        lo: npt.NDArray[np.float64],
        hi: npt.NDArray[np.float64],
        damping: float,
        pos_tol: float,
        rot_tol: float,
    ) -> tuple[float, float, bool]: ...
    def set_wrist(
        self,
        lower5: float,
        lower6: float,
        step: float,
        n5: int,
        n6: int,
        table: list[float],
        band: float,
        torque: float,
        damping: float,
    ) -> None: ...
    def update(
        self,
        q: _F64,
        v: _F64,
        cmd: _F64,
        torso: _F64,
        prev: _F64,
        limits: _F64,
        out: _F64,
        out_torso: _F64,
    ) -> None: ...

# Present only when the module was built with MuJoCo's headers (velma/control/_plant.hpp).
MUJOCO_HEADER_VERSION: int

class Plant:
    def __init__(
        self,
        model: object,
        data: object,
        step: int,
        qpos_adr: list[int],
        dof_adr: list[int],
        arm_act: list[int],
        torso_act: int,
        hand_side: list[int],
        part: list[int],
        robot_body: list[int],
    ) -> None: ...
    def bind(
        self,
        law: Law,
        cmd: _F64,
        torso: _F64,
        prev: _F64,
        limits: _F64,
        out: _F64,
        out_torso: _F64,
        q: _F64,
        v: _F64,
        parts: _F64,
    ) -> None: ...
    def bind_servos(
        self,
        hands: _F64,
        head: _F64,
        spread_act: list[int],
        prox_act: list[int],
        dist_act: list[int],
        prox_q: list[int],
        prox_kp: list[float],
        head_act: list[int],
        constants: list[float],
    ) -> None: ...
    def cycle(self) -> None: ...
    def bind_state_block(self, block: npt.NDArray[np.uint8], header: int) -> None: ...
    def release_state_block(self) -> None: ...
    def publish_state(self, names_version: float) -> None: ...
    def touching(self, side: int) -> dict[int, int]: ...
    def self_contacts(self) -> list[tuple[int, int]]: ...
    def set_state_layout(
        self, joint_qpos: list[int], sites: list[int], links: list[int], ft_adr: list[int], offsets: list[int]
    ) -> None: ...
    def gather(self, out: _F64) -> None: ...
