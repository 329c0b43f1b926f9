"""L_WM: world-model queries, answers and updates over ontology O_RoCo (C4 and C6).

Queries travel in ``query-ref`` (a_pl → a_km, a_ta → a_km), answers in ``inform-ref``-style
``inform`` replies; updates travel in the ``fipa-subscribe`` conversation a_km opens with a_ta;
changes of the scene in a ``fipa-subscribe`` any agent may open with a_km (``SceneSubscription``,
``SceneChange``).
Lengths in metres, poses in the world frame, stamps in simulation seconds.
"""

from __future__ import annotations

from typing import Annotated

import msgspec

from shared.fipa_codec.languages.base import Language, register
from shared.fipa_codec.languages.common import CLOCK, Pose, Vec3


class SparqlQuery(msgspec.Struct, frozen=True, tag="sparql"):
    """A SPARQL 1.1 SELECT or ASK over the knowledge base (prefix ``roco:`` predefined)."""

    query: str


class ObjectQuery(msgspec.Struct, frozen=True, tag="object"):
    """Everything known about the individual ``name``."""

    name: str


class SceneQuery(msgspec.Struct, frozen=True, tag="scene"):
    """Everything known about every physical object (the largest answer)."""


class GraspQuery(msgspec.Struct, frozen=True, tag="grasps", kw_only=True):
    """The grasp affordances of ``object`` for the hand of ``arm``."""

    object: str
    arm: str


class PlacementQuery(msgspec.Struct, frozen=True, tag="placement", kw_only=True):
    """Where on ``surface`` the ``object`` can be put down."""

    object: str
    surface: str


class PourQuery(msgspec.Struct, frozen=True, tag="pour", kw_only=True):
    """How to pour from ``source`` into ``target`` (pivot offset and tilt)."""

    source: str
    target: str


class ObjectUpdate(msgspec.Struct, frozen=True, kw_only=True, omit_defaults=True):
    """A change to one individual: a new ``pose`` (with ``position_sigma``, its position's
    one-σ uncertainty in m, when the observation gave one); ``held_by`` ("" = released); a
    new ``location``/``relation``; ``particles`` inside. Unset fields stay as they were."""

    name: str
    pose: Pose | None = None
    position_sigma: float | None = None
    held_by: str | None = None
    location: str | None = None
    relation: str | None = None
    particles: int | None = None


AnyQuery = SparqlQuery | ObjectQuery | SceneQuery | GraspQuery | PlacementQuery | PourQuery


class GraspStep(msgspec.Struct, frozen=True, tag="grasp_step", kw_only=True):
    """A plan's step in which the hand of ``arm`` grasps ``object``; ``index`` is the step's
    number among the plan's leaves (1-based), ``changes`` its effects on the knowledge."""

    index: int
    object: str
    arm: str
    changes: tuple[ObjectUpdate, ...] = ()

    @property
    def operator(self) -> str:
        return f"grasp({self.object}, {self.arm})"

    def effects(self) -> tuple[ObjectUpdate, ...]:
        """What the grasp changes in the knowledge: ``object`` held by ``<arm>_gripper``."""
        return (ObjectUpdate(name=self.object, held_by=f"{self.arm}_gripper"),)


class PutStep(msgspec.Struct, frozen=True, tag="put_step", kw_only=True):
    """A plan's step in which the held ``object`` is put down ``relation`` (in/on)
    ``furniture`` with its frame (bottom centre) at ``position`` (world, m)."""

    index: int
    object: str
    furniture: str
    relation: str
    position: Vec3
    changes: tuple[ObjectUpdate, ...] = ()

    @property
    def operator(self) -> str:
        return f"put({self.object}, {self.furniture})"

    def effects(self) -> tuple[ObjectUpdate, ...]:
        """What the put changes in the knowledge: ``object`` out of the hand, standing
        ``relation`` ``furniture`` with its frame at ``position`` (world, m)."""
        put = ObjectUpdate(
            name=self.object,
            location=self.furniture,
            relation=self.relation,
            held_by="",
            pose=Pose(self.position),
        )
        return (put,)


class PourStep(msgspec.Struct, frozen=True, tag="pour_step", kw_only=True):
    """A plan's step in which the held ``source`` is poured out into ``target``."""

    index: int
    source: str
    target: str
    changes: tuple[ObjectUpdate, ...] = ()

    @property
    def operator(self) -> str:
        return f"pour({self.source}, {self.target})"


PlanStep = GraspStep | PutStep | PourStep
"""A plan step whose preconditions a_km checks in the hypothetical state (paper §5.7)."""


class HypotheticalQuery(msgspec.Struct, frozen=True, tag="hypothetical", kw_only=True):
    """Answer ``query`` in the hypothetical state of the knowledge base after ``steps``, then
    ``changes`` (paper §5.7: "creation of the hypothetical state of the knowledge base"). The
    real state is not touched. Each step's preconditions are checked in the state the steps
    before it left, then its ``changes`` applied; ``changes`` are applied in order, as
    :class:`WorldUpdate` objects are."""

    changes: tuple[ObjectUpdate, ...] = ()
    query: AnyQuery
    steps: tuple[PlanStep, ...] = ()


class Subscription(msgspec.Struct, frozen=True, tag="subscription"):
    """a_km's fipa-subscribe to a_ta: send every observation of ``topic`` (``environment``);
    ``watch``: have the robot watch the scene, a camera frame every ``period_s`` s of robot time
    (a_ta sends what it sees as observations of ``environment``), as long as the subscription
    lasts."""

    topic: str = "environment"
    period_s: float | None = None


class ObjectInfo(msgspec.Struct, frozen=True, kw_only=True, omit_defaults=True):
    """An individual: ``name``, its ``type`` (an O_RoCo class), ``pose`` with ``pose_stamp``
    and ``position_sigma`` (m, one σ of the observed position; None: not given),
    bounding ``size`` (x, y, z extents), ``mass`` (kg, with its content as the scene began),
    where it is (``location`` with ``relation`` in/on),
    who holds it (``held_by``), whether its pose was ``localised`` since it last moved, and
    for containers the count of ``particles`` inside. For furniture: ``facing``, the torso
    angle (rad) at which Velma works at it, and ``view_point``, where the head looks (world).
    A held object names the furniture it was ``picked_from``."""

    name: str
    type: str
    pose: Pose | None = None
    pose_stamp: float | None = None
    position_sigma: float | None = None
    size: Vec3 | None = None
    mass: float | None = None
    location: str | None = None
    relation: str | None = None
    held_by: str | None = None
    localised: bool = False
    particles: int | None = None
    facing: float | None = None
    view_point: Vec3 | None = None
    picked_from: str | None = None


class GraspAffordance(msgspec.Struct, frozen=True, kw_only=True):
    """One way to grasp an object (object frame = bottom centre, world axes; m, rad).

    ``grip_in_object``: the grip frame's pose in the object frame. The hand opens to
    ``preshape`` (proximal angle), reaches a pre-grasp ``distance`` back along ``approach``
    (the unit direction it then moves in to the grasp), optionally first an entry point
    ``entry_distance`` back along ``entry`` from there; closes with finger ``spread``; lifts
    by ``lift``; and withdraws ``retreat_distance`` along ``retreat``. A non-empty
    ``posture`` (the arm's seven joint angles, rad) is taken first, by a joint move. ``on``
    names the furniture the object must stand on or in for this grasp (empty: anywhere)."""

    name: str
    grip_in_object: Pose
    approach: Vec3
    distance: float
    spread: float = 0.0
    preshape: float = 0.5
    entry: Vec3 | None = None
    entry_distance: float = 0.0
    lift: float = 0.04
    retreat: Vec3 = (-1.0, 0.0, 0.0)
    retreat_distance: float = 0.25
    posture: tuple[float, ...] = ()
    on: tuple[str, ...] = ()


class PourAffordance(msgspec.Struct, frozen=True, kw_only=True):
    """Pouring ``source`` into ``target``: the torso turns to ``facing`` (rad); in the target
    frame turned with the torso, the upright source's frame goes to ``source_in_target``
    (coming down from ``approach_height`` above), then the source tilts by ``angle`` rad about
    ``axis`` (torso frame) through ``pivot_in_target`` in ``duration`` s, waits ``wait`` s,
    and tilts back in ``untilt_duration`` s; then it moves by ``clear_view`` (same turned
    frame) out of the head's view of the target, for the content check. Metres, radians,
    seconds."""

    facing: float
    source_in_target: Vec3
    approach_height: float
    pivot_in_target: Vec3
    axis: Vec3
    angle: float
    duration: float
    wait: float = 2.0
    untilt_duration: float = 3.0
    clear_view: Vec3 = (0.0, 0.0, 0.0)


class PlacementInfo(msgspec.Struct, frozen=True, kw_only=True):
    """Places for an object on a surface, in order of preference: world ``positions`` of the
    object's frame and, for each, the torso angle Velma works there at (``facings``, rad;
    None or missing: the surface's own facing); the object is released ``clearance`` m above
    and comes down from ``approach`` m above; the hand then parks at ``park`` from the
    release pose (frame turned with the torso). ``approaches`` and ``parks`` override
    ``approach`` and ``park`` for single places (None or missing: no override)."""

    surface: str
    positions: tuple[Vec3, ...]
    clearance: float = 0.005
    approach: float = 0.08
    park: Vec3 = (0.0, 0.0, 0.1)
    facings: tuple[float | None, ...] = ()
    approaches: tuple[float | None, ...] = ()
    parks: tuple[Vec3 | None, ...] = ()

    def facing(self, i: int) -> float | None:
        """The torso angle for place ``i`` (None: the surface's facing)."""
        return self.facings[i] if i < len(self.facings) else None

    def approach_at(self, i: int) -> float:
        """The height (m) the object comes down from at place ``i``."""
        value = self.approaches[i] if i < len(self.approaches) else None
        return self.approach if value is None else value

    def park_at(self, i: int) -> Vec3:
        """Where the hand parks after releasing at place ``i`` (m, turned frame)."""
        value = self.parks[i] if i < len(self.parks) else None
        return self.park if value is None else value


class Answer(msgspec.Struct, frozen=True, tag="answer", kw_only=True):
    """The answer to an L_WM query; exactly one field is set, matching the query."""

    objects: tuple[ObjectInfo, ...] = ()
    grasps: tuple[GraspAffordance, ...] = ()
    placement: PlacementInfo | None = None
    pour: PourAffordance | None = None
    variables: tuple[str, ...] = ()
    rows: tuple[tuple[str | None, ...], ...] = ()
    boolean: bool | None = None


class WorldUpdate(msgspec.Struct, frozen=True, tag="update", kw_only=True):
    """Observations and changes a_ta sends a_km (C6) at simulation time ``stamp``.
    ``renews``: the observation is of a robot that was power-cycled (its kitchen started anew,
    its time from 0): a_km drops what it believed of the world and takes the kitchen's initial
    knowledge with this observation instead. ``seen_at``: for an observation, when a_ta received
    it on its wall clock (POSIX s), which a_km keeps as each seen object's ``roco:seenAt`` (what
    a person is told the knowledge's age by); None for asserted changes."""

    stamp: float
    objects: tuple[ObjectUpdate, ...]
    total_particles: int | None = None
    renews: bool = False
    seen_at: Annotated[float, CLOCK] | None = None


class SceneSubscription(msgspec.Struct, frozen=True, tag="scene_subscription", kw_only=True):
    """A fipa-subscribe (FIPA SC00035) to a_km for changes of the scene, on any channel where
    the specification makes a_km its participant. ``objects``: the individuals of interest
    (empty: every physical object). What counts as a change, each measured from what the
    subscriber was last told of that object (at first: what a_km knew when it agreed):
    ``moved`` (m), the object's position moved farther than this (None: not of interest);
    ``tilted`` (rad), the object's up axis crossed this angle from upright, either way (an
    object knocked over, or stood up again; None: not of interest); ``content``, its count of
    particles changed; ``relation``, who holds it or where it stands (in/on) changed.
    ``queue``: the changes a_km keeps for this subscriber before it drops the oldest (the
    bounds a_km accepts: services/agents/knowledge/scene_watch.py). ``within_s`` (robot s;
    None: whenever the robot next looks): tell a change within this long of its happening — a_km
    then has the robot watch the scene while the subscription lasts (a camera frame every
    ``within_s / 2``), which in simulation paces the robot to the camera (docs/agents.md)."""

    objects: tuple[str, ...] = ()
    moved: float | None = 0.05
    tilted: float | None = 0.5
    content: bool = True
    relation: bool = True
    queue: int = 64
    within_s: float | None = None


class SceneChange(msgspec.Struct, frozen=True, tag="scene_change", kw_only=True, omit_defaults=True):
    """A change of one object that matches a :class:`SceneSubscription`, in an ``inform`` of
    that subscription. ``changed``: what changed, each of ``moved``, ``tilted`` (its up axis
    now farther than the subscription's angle from upright), ``upright`` (back within it),
    ``content``, ``held`` (a hand took it), ``released``, ``placed`` (it now stands in/on
    ``location``). ``stamp``: the robot's time (simulation s) of the update a_km learnt it
    from (a_ta's C6 inform; < 0: an asserted change, not an observation); ``seen_at``: when a_ta
    received that observation (its wall clock, POSIX s; None for asserted changes). The
    object as it is now: ``pose`` (world, m), its ``tilt`` (rad from upright), ``particles``,
    ``held_by`` ("" when no hand holds it), ``location`` with ``relation``; ``distance`` (m):
    how far it moved from the position last told. ``dropped``: changes for this subscriber
    a_km dropped (its queue was full) just before this one."""

    object: str
    changed: tuple[str, ...]
    stamp: float
    seen_at: Annotated[float, CLOCK] | None = None
    pose: Pose | None = None
    distance: float | None = None
    tilt: float | None = None
    particles: int | None = None
    held_by: str | None = None
    location: str | None = None
    relation: str | None = None
    dropped: int = 0


L_WM = register(
    Language(
        "L_WM",
        "O_RoCo",
        (
            SparqlQuery,
            ObjectQuery,
            SceneQuery,
            GraspQuery,
            PlacementQuery,
            PourQuery,
            HypotheticalQuery,
            Subscription,
            Answer,
            WorldUpdate,
            SceneSubscription,
            SceneChange,
        ),
    )
)
