"""Segmenting a coloured world point cloud into object candidates: horizontal support planes,
the points standing on them, Euclidean clusters, and a colour gate from an object's known
colour. Pure numpy; world z is up.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from velma.perception.cloud import Array

SUPPORT_BIN = 0.004  # m, height histogram bin for support planes
SUPPORT_MIN_SHARE = 0.03  # a support plane holds at least this share of the cloud's points
SUPPORT_PROMINENCE = 4.0  # ... and this many times the points of the height bands beside it
SUPPORT_SIDE = (0.02, 0.08)  # m, the bands beside: this far below and above the plane
SUPPORT_BAND = 0.008  # m, points this close to a support height belong to it
SUPPORT_CLEARANCE = 0.002  # m, an object's points start this high above its support
CLUSTER_VOXEL = 0.01  # m, voxels touching (26-neighbourhood) are one cluster
LIFT_GAP = 0.015
"""m: a cluster whose lowest point is more than this above its support plane does not stand
on it (an object held in the hand; ``lifted``)."""
MIN_BRIGHTNESS = 60  # sum of R, G, B (0..765) below which a colour's hue is not trusted
GREY = np.full(3, 1.0 / 3.0)


@dataclass(frozen=True)
class Cluster:
    """Points of one connected blob standing on a support plane: ``index`` (M,) into the cloud,
    ``support`` (m) the height of the plane below it, ``top`` (m) its highest point above
    that plane, ``extent`` (m) its largest horizontal size (bounding-box diagonal).
    ``lifted_from`` (m): None when the blob stands on its support; else it is held above it
    (``lifted``), ``support`` is then its own lowest point's height, ``top`` is measured from
    there and ``lifted_from`` is the plane's height below it."""

    index: npt.NDArray[np.int64]
    support: float
    top: float
    extent: float
    lifted_from: float | None = None

    @property
    def standing(self) -> bool:
        """Whether the blob stands on its support plane (``lifted``)."""
        return self.lifted_from is None


def support_heights(points: Array) -> list[float]:
    """Heights (m) of the horizontal planes in ``points`` (N × 3): peaks of the height
    histogram holding ≥ ``SUPPORT_MIN_SHARE`` of the points within ±``SUPPORT_BAND`` and
    ``SUPPORT_PROMINENCE`` times as many as an equal band beside them (on average over
    ``SUPPORT_SIDE`` below, and above: the larger), each the mean height of those points;
    ascending. A vertical wall spreads evenly over the heights and makes no peak; a shelf, a
    table top or the floor does."""
    if len(points) == 0:
        return []
    z = points[:, 2]
    lo = float(z.min())
    bins = np.floor((z - lo) / SUPPORT_BIN).astype(np.int64)
    counts = np.bincount(bins)
    w = round(SUPPORT_BAND / SUPPORT_BIN)
    window = np.convolve(counts, np.ones(2 * w + 1, dtype=np.int64), mode="same")
    need = SUPPORT_MIN_SHARE * len(points)
    near_bins, far_bins = (round(x / SUPPORT_BIN) for x in SUPPORT_SIDE)
    padded = np.concatenate([np.zeros(far_bins), window, np.zeros(far_bins)])
    heights: list[float] = []
    taken = np.zeros(len(counts), dtype=bool)
    for b in np.argsort(window)[::-1]:
        if window[b] < need:
            break
        if taken[max(0, b - 2 * w) : b + 2 * w + 1].any():
            continue
        i = b + far_bins
        below = padded[i - far_bins : i - near_bins + 1].mean()
        above = padded[i + near_bins : i + far_bins + 1].mean()
        if window[b] < SUPPORT_PROMINENCE * max(below, above):
            continue
        taken[b] = True
        centre = lo + (b + 0.5) * SUPPORT_BIN
        near = np.abs(z - centre) <= SUPPORT_BAND
        heights.append(float(np.mean(z[near])))
    return sorted(heights)


_HALF_NEIGHBOURHOOD = tuple(
    (dx, dy, dz) for dx in (-1, 0, 1) for dy in (-1, 0, 1) for dz in (-1, 0, 1) if (dx, dy, dz) > (0, 0, 0)
)
"""The offsets to half of a voxel's 26 neighbours (the other half: the same pairs reversed)."""


def _neighbours(keys: npt.NDArray[np.int64]) -> tuple[npt.NDArray[np.int64], npt.NDArray[np.int64]]:
    """The pairs of neighbouring voxels of ``keys`` (V × 3 integer coordinates, unique), as
    two index arrays: each pair once."""
    v = len(keys)
    span = keys.max(axis=0) - keys.min(axis=0) + 3
    k = keys - keys.min(axis=0) + 1
    flat = (k[:, 0] * span[1] + k[:, 1]) * span[2] + k[:, 2]
    order = np.argsort(flat)
    sorted_flat = flat[order]
    pairs = []
    for dx, dy, dz in _HALF_NEIGHBOURHOOD:
        target = flat + (dx * span[1] + dy) * span[2] + dz
        pos = np.clip(np.searchsorted(sorted_flat, target), 0, v - 1)
        hit = sorted_flat[pos] == target
        pairs.append((np.flatnonzero(hit), order[pos[hit]]))
    a = np.concatenate([p[0] for p in pairs]) if pairs else np.zeros(0, dtype=np.int64)
    b = np.concatenate([p[1] for p in pairs]) if pairs else np.zeros(0, dtype=np.int64)
    return a, b


def _components(keys: npt.NDArray[np.int64]) -> npt.NDArray[np.int64]:
    """Labels of the 26-connected components of voxels ``keys`` (V × 3 integer coordinates,
    unique): the smallest voxel index of its component, for each voxel."""
    v = len(keys)
    a, b = _neighbours(keys)
    labels = np.arange(v)
    while True:
        m = np.minimum(labels[a], labels[b])
        new = labels.copy()
        np.minimum.at(new, a, m)
        np.minimum.at(new, b, m)
        new = new[new]  # pointer jumping
        if np.array_equal(new, labels):
            return labels
        labels = new


def clusters(
    points: Array,
    candidates: npt.NDArray[np.int64],
    supports: list[float],
    max_height: float,
    min_points: int,
) -> list[Cluster]:
    """Clusters of the ``candidates`` (indices into ``points``, N × 3) standing on the
    ``supports`` (heights, m): candidates more than ``SUPPORT_CLEARANCE`` and at most
    ``max_height`` (m) above the nearest support below them, grouped by touching
    ``CLUSTER_VOXEL`` voxels; clusters of fewer than ``min_points`` points are dropped. A
    cluster's support is the highest plane below its lowest point. The candidates are meant to
    be of one colour (``colour_match``), which keeps the support itself out when its colour
    differs; one of the same colour joins its points within its noise to the objects on it."""
    if len(candidates) == 0 or not supports:
        return []
    z = points[candidates, 2]
    s = np.asarray(supports)
    below = np.where(z[:, None] > s[None, :] + SUPPORT_CLEARANCE, s[None, :], -np.inf).max(axis=1)
    keep = np.isfinite(below) & (z - below <= max_height)
    idx = candidates[keep]
    below = below[keep]
    if len(idx) == 0:
        return []
    vox = np.floor(points[idx] / CLUSTER_VOXEL).astype(np.int64)
    keys, inverse = np.unique(vox, axis=0, return_inverse=True)
    labels = _components(keys)[inverse.ravel()]
    out = []
    for lab in np.unique(labels):
        member = labels == lab
        if np.count_nonzero(member) < min_points:
            continue
        p = points[idx[member]]
        support = float(below[member].min())
        lo, hi = p[:, :2].min(axis=0), p[:, :2].max(axis=0)
        out.append(
            Cluster(
                index=idx[member],
                support=support,
                top=float(p[:, 2].max() - support),
                extent=float(np.hypot(*(hi - lo))),
            )
        )
    return out


def lifted(
    points: Array, candidates: npt.NDArray[np.int64], c: Cluster, reach: float, max_height: float
) -> Cluster:
    """``c`` again as a blob that does not stand on its support (its lowest point more than
    ``LIFT_GAP`` above it: an object held in the hand), or ``c`` unchanged when it stands.

    ``clusters`` cut the blob at ``max_height`` above the plane below it, which for a lifted
    object is not its bottom; here the ``candidates`` (indices into ``points``, N × 3) within
    ``reach`` (m, horizontally) of ``c``'s bounding-box centre and at most ``max_height`` (m)
    above ``c``'s lowest point are gathered: ``support`` that lowest point's height (m),
    ``top`` measured from it, ``lifted_from`` the plane's height."""
    p = points[c.index]
    low = float(p[:, 2].min())
    if low - c.support <= LIFT_GAP:
        return c
    centre = (p[:, :2].min(axis=0) + p[:, :2].max(axis=0)) / 2
    q = points[candidates]
    keep = (np.hypot(q[:, 0] - centre[0], q[:, 1] - centre[1]) <= reach) & (q[:, 2] >= low)
    keep &= q[:, 2] <= low + max_height
    index = candidates[keep]
    r = points[index]
    lo, hi = r[:, :2].min(axis=0), r[:, :2].max(axis=0)
    return Cluster(
        index=index,
        support=low,
        top=float(r[:, 2].max() - low),
        extent=float(np.hypot(*(hi - lo))),
        lifted_from=c.support,
    )


def chromaticity(colours: npt.NDArray[np.uint8]) -> tuple[Array, npt.NDArray[np.bool_]]:
    """Chromaticity (N × 3, r + g + b = 1) of ``colours`` (N × 3, uint8) and whether each is
    bright enough (sum ≥ ``MIN_BRIGHTNESS``) for its hue to be trusted. Under white light it
    does not change with shading."""
    c = colours.astype(np.float64)
    s = c.sum(axis=1)
    bright = s >= MIN_BRIGHTNESS
    out: Array = c / np.maximum(s, 1.0)[:, None]
    return out, bright


def colour_match(colours: npt.NDArray[np.uint8], rgba: Array, tolerance: float) -> npt.NDArray[np.bool_]:
    """Which ``colours`` (N × 3, uint8) look like a surface of colour ``rgba`` (4,) under white
    light: an opaque one (alpha 1) within ``tolerance`` of its chromaticity; a transparent one
    on the segment from neutral grey to its chromaticity (the glass over an unknown background),
    at least a fifth of the way towards it, and within ``tolerance`` of that segment."""
    chroma, bright = chromaticity(colours)
    own = np.asarray(rgba[:3], dtype=np.float64)
    own = own / own.sum()
    if rgba[3] >= 1.0:
        return bright & (np.linalg.norm(chroma - own, axis=1) <= tolerance)
    d = own - GREY
    t = (chroma - GREY) @ d / float(d @ d)
    off = np.linalg.norm(chroma - GREY - t[:, None] * d[None, :], axis=1)
    return bright & (t >= 0.2) & (t <= 1.2) & (off <= tolerance)


def merge_within(parts: list[Cluster], points: Array, max_extent: float) -> list[Cluster]:
    """Groups of ``parts`` on the same support (within ``SUPPORT_BAND``) whose points together
    span at most ``max_extent`` (m, horizontal bounding-box diagonal): one object seen in
    pieces (an open container's near rim and its inside far wall are not connected in the
    image) becomes one cluster again. Greedy, largest part first."""
    groups: list[tuple[float, list[npt.NDArray[np.int64]], Array, Array]] = []
    for c in sorted(parts, key=lambda c: -len(c.index)):
        p = points[c.index, :2]
        lo, hi = p.min(axis=0), p.max(axis=0)
        for k, (support, members, glo, ghi) in enumerate(groups):
            nlo, nhi = np.minimum(lo, glo), np.maximum(hi, ghi)
            if abs(support - c.support) <= SUPPORT_BAND and float(np.hypot(*(nhi - nlo))) <= max_extent:
                groups[k] = (support, [*members, c.index], nlo, nhi)
                break
        else:
            groups.append((c.support, [c.index], lo, hi))
    out = []
    for support, members, lo, hi in groups:
        index = np.concatenate(members)
        out.append(
            Cluster(
                index=index,
                support=support,
                top=float(points[index, 2].max() - support),
                extent=float(np.hypot(*(hi - lo))),
            )
        )
    return out
