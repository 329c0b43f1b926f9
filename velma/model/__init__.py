"""MJCF models: ``velma.xml`` (the robot: ``robot_mjcf.py``) and ``kitchen.xml``
(the scene of the pouring experiment, which includes velma.xml)."""

from __future__ import annotations

from pathlib import Path

MODEL_DIR = Path(__file__).resolve().parent
VELMA_XML = MODEL_DIR / "velma.xml"
KITCHEN_XML = MODEL_DIR / "kitchen.xml"


def grip_frame(side: str) -> str:
    """Name of ``side``'s ("left" or "right") grip frame: a site in MuJoCo, a frame in
    Pinocchio, 0.12 m out of the palm (velma/model/robot_mjcf.py); the pose MoveTool targets."""
    return f"{side}_HandGripLink"


__all__ = ["KITCHEN_XML", "MODEL_DIR", "VELMA_XML", "grip_frame"]
