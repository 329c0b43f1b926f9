"""What a_pl knows while it plans: the answers a_km gave during the initialize behaviour."""

from __future__ import annotations

from dataclasses import dataclass, field

from shared.fipa_codec.languages.l_wm import GraspAffordance, ObjectInfo, PlacementInfo, PourAffordance

ARMS = ("left", "right")


@dataclass
class Knowledge:
    """Answers of a_km, by query: objects by name; grasps by (object, arm); placements by
    (object, surface); pouring by (source, target)."""

    objects: dict[str, ObjectInfo] = field(default_factory=dict)
    grasps: dict[tuple[str, str], tuple[GraspAffordance, ...]] = field(default_factory=dict)
    placements: dict[tuple[str, str], PlacementInfo] = field(default_factory=dict)
    pours: dict[tuple[str, str], PourAffordance | None] = field(default_factory=dict)
    queries: int = 0
