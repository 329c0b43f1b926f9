"""What the operator puts on a running fleet's Zenoh: a person's command to the agent that plays
the person's role (``roco send``), and a disturbance of the simulated kitchen (``roco disturb``)."""

from __future__ import annotations

import json
import uuid
from typing import TYPE_CHECKING

import msgspec

from services.runtime import keys
from services.runtime.human import HumanInput

if TYPE_CHECKING:
    import zenoh


def say(session: zenoh.Session, command: str, priority: int, person: str) -> str:
    """Put ``command``, said by ``person`` (a_hi keeps a conversation per person) with
    ``priority``, on the person's input; the request id its reports answer."""
    request_id = uuid.uuid4().hex[:8]
    said = HumanInput(text=command, request_id=request_id, priority=priority, person=person)
    session.put(keys.HUMAN_IN, msgspec.json.encode(said))
    return request_id


def disturb(session: zenoh.Session, obj: str, delta: tuple[float, float, float], tilt: float) -> None:
    """Ask ag_ex to move the kitchen's free body ``obj`` by ``delta`` metres (world x, y, z)
    and tip it by ``tilt`` radians about world x, as a person would."""
    session.put(keys.SIM_DISTURB, json.dumps({"object": obj, "delta": list(delta), "tilt": tilt}))
