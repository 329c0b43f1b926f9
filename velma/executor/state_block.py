"""The robot state's hand-off from the loop process to ag_ex's communication side:
the publication every ``STATE_PERIOD`` cycles costs the loop a few microseconds, not the
≈ 70 µs of building, encoding and copying a message in Python in a cycle that sleeps.

Two ``LatestValue`` blocks (velma/executor/handoff.py):

- **values**, rewritten at every publication: float64, native byte order, ``[sim time (s),
  names version, raw_state's numbers…]`` (``state_values``; the numbers in
  velma/executor/state.py ``raw_layout``). With the compiled plant the loop writes it from C++
  (velma/control/_plant.hpp ``Plant.publish_state``), under the block's sequence lock as
  ``LatestValue.write`` does; without it, from Python (``state_values``), the same bytes.
- **names**, rewritten only when they change (a grasp, a release, a hold): the msgpack
  ``StateNames`` — the joints' names, what each hand holds, why the loop holds, and the
  ``version`` that the values written after it carry.

``StateReader`` pairs a value with the names of its version, re-reading the names when the
version moved, so a snapshot never joins the numbers of one moment with the words of another.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import msgspec
import numpy as np
import numpy.typing as npt

from velma.control.joints import SIDES
from velma.executor.gather import python_gather
from velma.executor.handoff import LatestValue
from velma.executor.state import RawState, raw_layout

if TYPE_CHECKING:
    from velma.executor.runtime import Runtime

HEAD = 2
"""The values before raw_state's numbers: sim time, names version."""
READ_RETRIES = 1000
"""Reads of a value and its names before ``StateReader.read`` gives up (the writer writes the
names, then the value, microseconds apart)."""


class StateNames(msgspec.Struct, frozen=True, array_like=True):
    """The words of the robot state (module docstring): ``version`` (≥ 1), ``joints`` (the
    values' joint order), ``held_object`` (body name held by the right and the left hand, or
    None), ``holding`` (why the loop holds position, or None)."""

    version: int
    joints: tuple[str, ...]
    held_object: tuple[str | None, str | None]
    holding: str | None = None


def state_values(rt: Runtime, names_version: int) -> npt.NDArray[np.float64]:
    """The values block's content now ((HEAD + raw_layout size,) float64; module docstring), in
    Python: the reference of ``Plant.publish_state``. Call from the loop's thread."""
    out = np.empty(HEAD + raw_layout(len(rt.joint_v_index))[-1])
    out[0] = rt.time
    out[1] = names_version
    python_gather(rt, out[HEAD:])
    return out


class StateWriter:
    """The loop side: ``publish`` writes the names (when changed) and the values of ``rt``'s
    state; with ``rt.plant`` the values come from C++ (``compiled=False``: from Python).
    Raises ValueError (at construction) when the values block is too small."""

    def __init__(
        self, rt: Runtime, values: LatestValue, names: LatestValue, *, compiled: bool = True
    ) -> None:
        self.rt = rt
        self.values = values
        self.names = names
        self.version = 0
        """The names' version (0 before the first ``publish``)."""
        self._said: tuple[int | None, int | None, str | None] | None = None
        self._encode = msgspec.msgpack.Encoder().encode
        self.compiled = compiled and rt.plant is not None
        if self.compiled:
            assert rt.plant is not None
            block, header = values.block()
            rt.plant.bind_state_block(block, header)

    def close(self) -> None:
        """Stop publishing: the compiled plant lets go of the values block (which can then be
        closed). Idempotent."""
        if self.compiled:
            assert self.rt.plant is not None
            self.rt.plant.release_state_block()
            self.compiled = False

    def publish(self, holding: str | None) -> None:
        """Publish the state now, ``holding`` being why the loop holds position (or None)."""
        rt = self.rt
        said = (rt.held[SIDES[0]], rt.held[SIDES[1]], holding)
        if said != self._said:
            self.version += 1
            names = tuple(None if b is None else rt.model.body(b).name for b in said[:2])
            self.names.write(
                self._encode(
                    StateNames(
                        version=self.version,
                        joints=rt.robot.joint_names,
                        held_object=(names[0], names[1]),
                        holding=holding,
                    )
                )
            )
            self._said = said
        if self.compiled:
            assert rt.plant is not None
            rt.plant.publish_state(self.version)
        else:
            self.values.write(state_values(rt, self.version).tobytes())


class StateReader:
    """The communication side: ``read`` gives the latest ``RawState``, or None before the loop
    published one (or if the writer kept changing it for ``READ_RETRIES`` reads)."""

    def __init__(self, values: LatestValue, names: LatestValue) -> None:
        self.values = values
        self.names = names
        self._names: StateNames | None = None
        self._decode = msgspec.msgpack.Decoder(StateNames).decode

    def read(self) -> RawState | None:
        for _ in range(READ_RETRIES):
            raw = self.values.read()
            if raw is None:
                return None
            head = np.frombuffer(raw, dtype=np.float64, count=HEAD)
            version = int(head[1])
            if self._names is None or self._names.version != version:
                said = self.names.read()
                if said is None:
                    continue
                self._names = self._decode(said)
                if self._names.version != version:
                    continue
            names = self._names
            return RawState(
                sim_time=float(head[0]),
                joints=names.joints,
                values=raw[8 * HEAD :],
                held_object=names.held_object,
                holding=names.holding,
            )
        return None

    def sim_time(self) -> float | None:
        """The sim time (s) of the latest value, or None before the first."""
        raw = self.values.read()
        return None if raw is None else float(np.frombuffer(raw, dtype=np.float64, count=1)[0])
