"""Localising the known objects in the head camera's point cloud: segment, then fit the
object's model with ICP (small_gicp).

For each requested object (velma/perception/objects.py ``ObjectModel``):

1. the horizontal support planes of the cloud (shelf, table top, floor: peaks of the height
   histogram, velma/perception/segment.py ``support_heights``);
2. the points of the object's known colour (``colour_match``) standing on a support, in
   clusters of touching 1 cm voxels, pieces that fit together within the object's footprint
   merged (an open container's near rim and far inside wall are not connected in the image);
3. the cluster whose top is within the object's height (−40 %, +15 mm) and whose horizontal
   size fits its diameter, the one whose top is nearest the object's height first (each
   cluster goes to one object: this tells the bowl from the cup, both white);
4. point-to-plane ICP (``small_gicp.align``, ``PLANE_ICP``) of those points to the model's
   surface samples, started upright on the support at the centre of the least-squares circle
   through the points (and 8 mm beside it in ±x, ±y): a coarse pass (correspondences ≤ 20 mm)
   from each start, the one with the smallest truncated mean squared distance of all points to
   the model kept, then a fine pass (≤ 6 mm);
5. the estimate is accepted when the fit's inliers hold ≥ ``MIN_INLIER_SHARE`` of the points
   with an RMS residual ≤ ``MAX_RMSE`` and it tilts the object ≤ ``MAX_TILT``. Its x and y are
   ICP's; its z is the support plane's height (the object stands on it: thousands of plane
   points fix it better than the object's cut-off bottom does) — unless the cluster's lowest
   point lies more than ``LIFT_GAP`` above the plane (segment.py ``lifted``: held in a hand),
   when the cluster is gathered up from its own lowest point, ICP also starts from its top
   less the object's height, and z is ICP's unless the fit stands the object on the plane
   after all;
6. when no upright fit passes, the fit is tried again from the object tipped over
   (``TIPPED_STARTS``: upside down, on its rim) and accepted by stricter inlier and RMS tests
   and with the object lying on its support:
   the object is seen, with its tilt and ICP's z (a person knocked it over: a_ta reads its
   tilt and reports it not upright).

An object with fewer than ``MIN_POINTS`` matching points (out of view, hidden) or whose fit is
rejected is reported not seen, never guessed.

Yaw: when turning the model about its vertical axis changes its surface by less than
``YAW_OBSERVABLE_DEVIATION`` (the model's ``symmetry_deviation``; the jar, bowl and cup are
16- and 20-sided polygons whose facets depart < 1 mm from a circle, below the sensor's noise)
the yaw is not observable: the estimate's quaternion then carries the fitted tilt and yaw 0,
``yaw_observable`` is False and the yaw's σ is infinite.

Covariance: σ̂² H⁻¹ of the fine pass, H small_gicp's Gauss–Newton Hessian (rotation, then
translation, perturbing the observed points about the start) and σ̂² = 2·error / inliers its
mean squared residual; the position's 3 × 3 block is the translation's marginal (Schur
complement over the rotation, pseudo-inverse for the unobservable yaw); its z entry is ICP's
although z is taken from the support plane. It assumes independent residuals: correlated
errors (quantisation steps, a biased start) make the true error larger,
which the benchmark measures (docs/bench/perception.md).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
import numpy.typing as npt
import small_gicp

from velma.perception.cloud import Array
from velma.perception.objects import ObjectModel
from velma.perception.segment import (
    LIFT_GAP,
    Cluster,
    clusters,
    colour_match,
    lifted,
    merge_within,
    support_heights,
)
from velma.rotations import quat_wxyz

MIN_POINTS = 80
"""Colour-matched points below which an object is not seen."""
COLOUR_TOLERANCE = 0.008
"""Chromaticity distance accepted as an opaque object's colour (neutral grey is 0.015 from
the white ceramic's)."""
TRANSPARENT_TOLERANCE = 0.02
"""Chromaticity distance from a transparent object's grey-to-colour segment."""
MIN_INLIER_SHARE = 0.8
MAX_RMSE = 0.004  # m
COARSE_CORRESPONDENCE = 0.02  # m
FINE_CORRESPONDENCE = 0.006  # m
SOURCE_VOXEL = 0.002  # m, downsampling of the observed points for ICP
YAW_OBSERVABLE_DEVIATION = 0.002  # m
START_OFFSETS = ((0.0, 0.0), (0.008, 0.0), (-0.008, 0.0), (0.0, 0.008), (0.0, -0.008))
"""m: the ICP starts from the guess and from it shifted by these in x and y; the fit with the
smallest truncated mean squared distance of all points to the model wins."""
MAX_TILT = math.radians(10.0)
"""An upright fit tilting the object more than this is discarded (they stand on a support)."""
STANDING_TOLERANCE = 0.01
"""m: a tipped fit is accepted only when the fitted object's lowest point lies this close to
its cluster's support plane (it lies on it; a fit floating above it is some other thing)."""
TIPPED_MIN_INLIER_SHARE = 0.95
TIPPED_MAX_RMSE = 0.001  # m
"""A tipped fit must fit better than an upright one: an upside-down bowl seen from the head
fits with 100 % inliers at 0.4 mm RMS, while the cup standing upright fits an upside-down
bowl with 82 % at 1.9 mm (measured on the tidy-up scenario's final state, 640 × 480)."""
TIPPED_SUPPORT_RING = 0.03  # m
TIPPED_SUPPORT_POINTS = 50
"""A tipped fit needs this many points of its support plane in a ring ``TIPPED_SUPPORT_RING``
wide around it: the support planes are heights found over the whole cloud, so without this a
white part of the robot's own hand at a shelf's height fitted an upside-down bowl (measured
on the tidy-up scenario with the camera)."""
TIPPED_STARTS = (math.pi,)
"""rad about the horizontal x axis: the starts of the fit tried when no upright fit passes
(upside down, on its rim). Named simplification: an object lying on its side is not looked
for (its height no longer fits step 3's cluster test): it is reported not seen."""
REGISTRATION = "PLANE_ICP"


@dataclass(frozen=True)
class ObjectEstimate:
    """What was seen of object ``name``.

    ``seen`` False: ``position``/``quaternion``/``covariance`` are None and ``reason`` says why.
    Else ``position`` (3,) m of the object frame's origin (bottom centre) in the world,
    ``quaternion`` (w, x, y, z) its orientation (yaw 0 when ``yaw_observable`` is False),
    ``covariance`` (3 × 3, m²) of the position, ``yaw_sigma`` (rad, inf when not observable),
    ``rmse`` (m) the fit's RMS residual, ``points`` the observed points fitted, ``inliers``
    how many of those (after downsampling) the fit used."""

    name: str
    seen: bool
    reason: str = ""
    position: Array | None = None
    quaternion: Array | None = None
    covariance: Array | None = None
    yaw_observable: bool = False
    yaw_sigma: float = math.inf
    rmse: float = math.nan
    points: int = 0
    inliers: int = 0
    cluster: npt.NDArray[np.int64] | None = field(default=None, repr=False)
    """Indices into the cloud of the cluster the object was found in (for content estimates)."""

    @property
    def sigma_position(self) -> float:
        """√trace of the position covariance (m); inf when not seen."""
        return math.inf if self.covariance is None else float(math.sqrt(np.trace(self.covariance)))


def _circle_centre(xy: Array) -> Array | None:
    """Centre (2,) of the least-squares circle through ``xy`` (M × 2, algebraic fit: the
    walls of an upright round object seen from any side), None when degenerate."""
    a = np.column_stack([xy, np.ones(len(xy))])
    b = np.sum(xy * xy, axis=1)
    sol, _, rank, _ = np.linalg.lstsq(a, b, rcond=None)
    if rank < 3:
        return None
    out: Array = sol[:2] / 2
    return out


def _tilt_only(r: Array) -> Array:
    """The smallest rotation taking world z to ``r``'s z axis (``r`` with its yaw removed)."""
    z = r[:, 2]
    axis = np.cross([0.0, 0.0, 1.0], z)
    s, c = float(np.linalg.norm(axis)), float(z[2])
    if s < 1e-12:
        return np.eye(3)
    k = axis / s
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    out: Array = np.eye(3) + s * kx + (1 - c) * kx @ kx
    return out


def _start_centre(observed: Array, camera: Array, radius: float) -> Array:
    """The object's axis (x, y) to start the fit from: the centre of the circle through the
    observed points, or (when there is none within ``radius`` of their mean) their mean moved
    a third of ``radius`` away from the camera."""
    centre = _circle_centre(observed[:, :2])
    if centre is None or np.linalg.norm(centre - observed[:, :2].mean(axis=0)) > radius:
        mean = observed[:, :2].mean(axis=0)
        away = mean - np.asarray(camera, dtype=np.float64)[:2]
        centre = mean + away / max(float(np.linalg.norm(away)), 1e-9) * radius / 3
    return centre


class _Fit(NamedTuple):
    """One ICP fit: its result, transform (4 × 4, model from source), inliers, their share of
    the source points and the RMS error (m)."""

    result: small_gicp.RegistrationResult
    t: Array
    inliers: int
    share: float
    rmse: float


def _is_upright(fit: _Fit) -> bool:
    """Whether a fine fit passes as upright: enough inliers, a small error, little tilt."""
    return fit.share >= MIN_INLIER_SHARE and fit.rmse <= MAX_RMSE and fit.t[2, 2] >= math.cos(MAX_TILT)


def _rejection(fine: _Fit | None) -> str:
    """Why an object is not seen when neither an upright nor a tipped fit passes."""
    if fine is None:
        return "no upright fit"
    return f"fit rejected: {fine.share:.0%} inliers, rms {fine.rmse * 1e3:.1f} mm"


def _stand(position: Array, c: Cluster) -> None:
    """An upright fit's height: on its support plane when it stands (module docstring), on the
    plane it was lifted from when the fit is within :data:`LIFT_GAP` of it."""
    if c.standing:
        position[2] = c.support
    elif c.lifted_from is not None and position[2] - c.lifted_from <= LIFT_GAP:
        position[2] = c.lifted_from  # the fit stands it on the plane after all


class _Target:
    """An object model prepared for small_gicp: point cloud with normals and its KdTree."""

    def __init__(self, model: ObjectModel) -> None:
        self.model = model
        self.cloud = small_gicp.PointCloud(model.points)
        self.tree = small_gicp.KdTree(self.cloud)
        small_gicp.estimate_normals(self.cloud, self.tree, num_neighbors=10)


class Localiser:
    """Finds ``models`` (velma/perception/objects.py) in coloured world point clouds; the
    models' ICP targets are prepared once here (≈ 0.1 s)."""

    def __init__(self, models: Iterable[ObjectModel]) -> None:
        self.targets = {m.name: _Target(m) for m in models}

    def localise(
        self,
        points: Array,
        colours: npt.NDArray[np.uint8],
        camera_position: Array,
        names: Iterable[str] | None = None,
        supports: list[float] | None = None,
    ) -> dict[str, ObjectEstimate]:
        """Estimates of ``names`` (all known objects when None) from ``points`` (N × 3, m,
        world, z up), their ``colours`` (N × 3, uint8) and the camera's world position (3,) m;
        ``supports`` the cloud's support planes (m, segment.py ``support_heights``; found here
        when None). Each cluster goes to at most one object. Raises ``KeyError`` for an
        unknown name."""
        wanted = list(self.targets) if names is None else list(names)
        for n in wanted:
            if n not in self.targets:
                raise KeyError(n)
        if supports is None:
            supports = support_heights(points)
        scored: list[tuple[float, str, Cluster]] = []
        for n in wanted:
            scored += self._candidates(n, points, colours, supports)
        out = self._assign(scored, points, camera_position)
        for n in wanted:
            if n not in out:
                out[n] = ObjectEstimate(name=n, seen=False, reason="no cluster of its size and colour fits")
        return out

    def _assign(
        self, scored: list[tuple[float, str, Cluster]], points: Array, camera_position: Array
    ) -> dict[str, ObjectEstimate]:
        """The objects fitted to their clusters, best score first: each object and each
        cluster at most once."""
        out: dict[str, ObjectEstimate] = {}
        used: set[int] = set()
        for _, n, c in sorted(scored, key=lambda s: -s[0]):
            if n in out or used.intersection(c.index[:20].tolist()):
                continue
            estimate = self._fit(n, points[c.index], c, camera_position, points)
            if estimate.seen:
                used.update(c.index.tolist())
                out[n] = ObjectEstimate(**{**estimate.__dict__, "cluster": c.index})
        return out

    def _candidates(
        self, n: str, points: Array, colours: npt.NDArray[np.uint8], supports: list[float]
    ) -> list[tuple[float, str, Cluster]]:
        """The clusters of object ``n``'s colour that may be it, each with its score (steps
        2 and 3 of the module docstring)."""
        model = self.targets[n].model
        tolerance = TRANSPARENT_TOLERANCE if model.transparent else COLOUR_TOLERANCE
        match = np.flatnonzero(colour_match(colours, model.rgba, tolerance))
        parts = clusters(points, match, supports, model.height + 0.015, MIN_POINTS // 4)
        scored: list[tuple[float, str, Cluster]] = []
        for c in merge_within(parts, points, self._max_extent(model)):
            if len(c.index) < MIN_POINTS:
                continue
            c = lifted(points, match, c, self._max_extent(model) / 2, model.height + 0.015)
            score = self._score(model, c)
            if score is not None:
                scored.append((score, n, c))
        return scored

    @staticmethod
    def _max_extent(model: ObjectModel) -> float:
        """Largest horizontal bounding-box diagonal (m) of the object's points, with margin."""
        return 2 * model.radius * math.sqrt(2) + 0.01

    @staticmethod
    def _score(model: ObjectModel, c: Cluster) -> float | None:
        """How well cluster ``c`` (of the object's colour) fits ``model``'s size (higher is
        better), or None when it cannot be the object."""
        if not (0.6 * model.height <= c.top <= model.height + 0.015):
            return None
        if c.extent > Localiser._max_extent(model):
            return None
        return -abs(c.top - model.height) / model.height

    def _fit(
        self, name: str, observed: Array, c: Cluster, camera: Array, cloud: Array | None = None
    ) -> ObjectEstimate:
        """ICP of ``observed`` (M × 3, world) to the model of ``name`` (module docstring);
        ``cloud`` (N × 3, world) the whole cloud, for the tipped fit's support test (without
        it no tipped fit is tried)."""
        target = self.targets[name]
        model = target.model
        start = np.array([*_start_centre(observed, camera, model.radius), c.support])
        source, _ = small_gicp.preprocess_points(observed - start, downsampling_resolution=SOURCE_VOXEL)
        if source.size() < MIN_POINTS // 2:
            return ObjectEstimate(name=name, seen=False, reason=f"{source.size()} points after downsampling")
        # a lifted object's bottom: its lowest point seen (the start), or its top seen less its height
        lifts = (0.0,) if c.standing else (0.0, c.top - model.height)
        best = self._coarse(target, source, lifts)
        fine = self._fine(target, source, best) if best is not None else None
        upright = fine is not None and _is_upright(fine)
        if fine is not None and upright:
            fit = fine
        else:
            tipped = (
                self._fit_tipped(target, source, cloud - start) if cloud is not None and c.standing else None
            )
            if tipped is None:
                return ObjectEstimate(name=name, seen=False, reason=_rejection(fine))
            result, share, rmse = tipped
            fit = _Fit(result, result.T_target_source, int(result.num_inliers), share, rmse)
        return self._estimate(name, c, start, fit, upright, len(observed))

    def _coarse(
        self, target: _Target, source: small_gicp.PointCloud, lifts: tuple[float, ...]
    ) -> Array | None:
        """The start of the fine fit: of the coarse fits from each of :data:`START_OFFSETS`
        and ``lifts`` that keep the object upright, the one with the smallest truncated mean
        squared distance of all points to the model (None: none keeps it upright)."""
        source_points = np.asarray(source.points())[:, :3]
        best: tuple[float, Array] | None = None
        for (dx, dy), dz in itertools.product(START_OFFSETS, lifts):
            t = np.eye(4)
            t[:3, 3] = (-dx, -dy, -dz)
            t = self._align(target, source, t, COARSE_CORRESPONDENCE).T_target_source
            if t[2, 2] < math.cos(MAX_TILT):
                continue
            moved = source_points @ t[:3, :3].T + t[:3, 3]
            _, sq = target.tree.batch_nearest_neighbor_search(moved)
            key = float(np.mean(np.minimum(np.asarray(sq), FINE_CORRESPONDENCE**2)))
            if best is None or key < best[0]:
                best = (key, t)
        return best[1] if best is not None else None

    def _fine(self, target: _Target, source: small_gicp.PointCloud, t: Array) -> _Fit:
        """The fine fit from ``t``, with its inliers' share and RMS error."""
        result = self._align(target, source, t, FINE_CORRESPONDENCE)
        inliers = int(result.num_inliers)
        share = inliers / source.size()
        rmse = math.sqrt(2 * result.error / max(inliers, 1))
        return _Fit(result, result.T_target_source, inliers, share, rmse)

    def _estimate(
        self, name: str, c: Cluster, start: Array, fit: _Fit, upright: bool, points: int
    ) -> ObjectEstimate:
        """The estimate of ``name`` from ``fit`` (in the frame of ``start``): an upright fit
        stands on its support plane, the yaw of a symmetric object is not observed."""
        model = self.targets[name].model
        inv: Array = np.asarray(np.linalg.inv(fit.t), dtype=np.float64)  # object frame in the start frame
        rotation = inv[:3, :3]
        position = start + inv[:3, 3]
        if upright:
            _stand(position, c)
        rmse = fit.rmse
        result = fit.result
        yaw_observable = model.symmetry_deviation > YAW_OBSERVABLE_DEVIATION
        cov6 = rmse**2 * np.linalg.pinv(np.asarray(result.H))
        covariance = self._position_covariance(np.asarray(result.H), rmse)
        yaw_sigma = math.sqrt(max(cov6[2, 2], 0.0)) if yaw_observable else math.inf
        if not yaw_observable:
            rotation = _tilt_only(rotation)
        return ObjectEstimate(
            name=name,
            seen=True,
            position=position,
            quaternion=np.array(quat_wxyz(rotation)),
            covariance=covariance,
            yaw_observable=yaw_observable,
            yaw_sigma=yaw_sigma,
            rmse=rmse,
            points=points,
            inliers=fit.inliers,
        )

    def _fit_tipped(
        self, target: _Target, source: small_gicp.PointCloud, cloud: Array
    ) -> tuple[small_gicp.RegistrationResult, float, float] | None:
        """The fit of ``source`` (points less the start, module docstring) to ``target`` with
        the object started at each of ``TIPPED_STARTS`` (a rotation about the horizontal x
        axis, its lowest point on the support) and ``START_OFFSETS``, the best by the coarse
        pass's truncated mean squared distance, then refined: (result, inlier share, RMS m)
        when it passes ``TIPPED_MIN_INLIER_SHARE`` and ``TIPPED_MAX_RMSE`` and the fitted object's lowest
        point is within ``STANDING_TOLERANCE`` of the cluster's support plane (z 0 of the start
        frame) and ``cloud`` (N × 3, the whole cloud in the start frame) holds at least
        ``TIPPED_SUPPORT_POINTS`` points of that plane around it, else None."""
        source_points = np.asarray(source.points())[:, :3]
        best: tuple[float, Array] | None = None
        for angle in TIPPED_STARTS:
            c, s = math.cos(angle), math.sin(angle)
            turn = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])  # object in the start frame
            lift = -float(np.min((target.model.points @ turn.T)[:, 2]))
            for dx, dy in START_OFFSETS:
                pose = np.eye(4)
                pose[:3, :3], pose[:3, 3] = turn, (dx, dy, lift)
                start_t: Array = np.asarray(np.linalg.inv(pose), dtype=np.float64)
                t = self._align(target, source, start_t, COARSE_CORRESPONDENCE).T_target_source
                moved = source_points @ t[:3, :3].T + t[:3, 3]
                _, sq = target.tree.batch_nearest_neighbor_search(moved)
                key = float(np.mean(np.minimum(np.asarray(sq), FINE_CORRESPONDENCE**2)))
                if best is None or key < best[0]:
                    best = (key, t)
        if best is None:
            return None
        result = self._align(target, source, best[1], FINE_CORRESPONDENCE)
        inliers = int(result.num_inliers)
        share = inliers / source.size()
        rmse = math.sqrt(2 * result.error / max(inliers, 1))
        if share < TIPPED_MIN_INLIER_SHARE or rmse > TIPPED_MAX_RMSE:
            return None
        pose = np.linalg.inv(result.T_target_source)  # the object in the start frame
        lowest = float(np.min(target.model.points @ pose[2, :3] + pose[2, 3]))
        if abs(lowest) > STANDING_TOLERANCE:  # a knocked-over object lies on its support (z 0 here)
            return None
        # … and the support is there around it: points of the plane in a ring about its place
        ring = np.hypot(cloud[:, 0] - pose[0, 3], cloud[:, 1] - pose[1, 3])
        around = (ring > target.model.radius + 0.005) & (ring < target.model.radius + TIPPED_SUPPORT_RING)
        if np.count_nonzero(around & (np.abs(cloud[:, 2]) <= STANDING_TOLERANCE)) < TIPPED_SUPPORT_POINTS:
            return None
        return result, share, rmse

    @staticmethod
    def _align(
        target: _Target, source: small_gicp.PointCloud, t: Array, distance: float
    ) -> small_gicp.RegistrationResult:
        """One ``small_gicp.align`` of ``source`` to ``target`` from ``t`` (4 × 4)."""
        return small_gicp.align(
            target.cloud,
            source,
            target.tree,
            init_T_target_source=t,
            registration_type=REGISTRATION,
            max_correspondence_distance=distance,
            max_iterations=30,
        )

    @staticmethod
    def _position_covariance(h: Array, rmse: float) -> Array:
        """σ̂² times the inverse of the translation block's Schur complement (m²)."""
        hrr, hrt, htt = h[:3, :3], h[:3, 3:], h[3:, 3:]
        schur = htt - hrt.T @ np.linalg.pinv(hrr, rcond=1e-6) @ hrt
        out: Array = np.asarray(rmse**2 * np.linalg.pinv(schur), dtype=np.float64)
        return out
