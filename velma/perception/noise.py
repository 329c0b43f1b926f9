"""Depth errors of a first-generation (structured-light) Kinect, applied to an ideal depth image.

Source: K. Khoshelham and S. O. Elberink, "Accuracy and Resolution of Kinect Depth Data for
Indoor Mapping Applications", Sensors 12(2):1437–1454, 2012. Depth comes from disparity, and
inverse depth is linear in the measured (normalised) disparity d' (their eq. 12), so

- the random error is ``σ_Z = (m / f b) · Z² · σ_d'`` (their eq. 16); with their calibrated
  ``m / (f b) = 2.85·10⁻⁵ cm⁻¹`` (absolute value) and ``σ_d' = ½`` disparity unit this is
  ``σ_Z = 1.425·10⁻³ · Z²`` m (Z in m): 1.4 mm at 1 m, 36 mm at 5 m;
- the depth resolution is one disparity unit: ``ΔZ = 2.85·10⁻³ · Z²`` m: 2.9 mm at 1 m, 71 mm
  at 5 m.

Verification: the coefficients are the ones recalled from the paper's error model; this
workplace could read only its abstract, whose figures they reproduce ("a few millimeters up
to about 4 cm at the maximum range" for the random error; ≈ 7 cm resolution at 5 m as its
resolution figure shows). Cross-check with C. V. Nguyen, S. Izadi and D. Lovell, "Modeling
Kinect Sensor Noise for Improved 3D Reconstruction and Tracking", 3DIMPVT 2012: their axial
σ_z = 0.0012 + 0.0019 (z − 0.4)² m gives 1.9 mm at 1 m (this model: 1.4 mm, or 1.6 mm with the
quantisation), and they report the error growing steeply towards grazing incidence, where
the sensor mostly returns nothing.

Both are applied in inverse depth, where they are uniform: a Gaussian of σ = ``SIGMA_INV``
(m⁻¹) is added to 1/Z, which is then rounded to steps of ``STEP_INV`` (m⁻¹). The quantised
output's σ is ≈ √(σ² + step²/12) ≈ 1.15 × the random error alone.

Missing depth (NaN): outside the range ``RANGE`` (0.5–4 m: velma/model/README.md "Head Kinect";
the Kinect's default mode is specified from 0.8 m, it returns depth from ≈ 0.5 m) and where
the surface is inclined to the ray by more than ``MAX_INCIDENCE`` (75°, assumed, after
Nguyen et al.'s observation above). Named simplifications: no projector shadow, no loss on
dark or shiny surfaces, no lateral (edge) noise, the colour and depth cameras share one pinhole.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

SIGMA_INV = 1.425e-3
"""σ of the inverse depth (m⁻¹): σ_Z = SIGMA_INV · Z² (Khoshelham & Elberink 2012)."""
STEP_INV = 2.85e-3
"""Quantisation step of the inverse depth (m⁻¹): one disparity unit, ΔZ = STEP_INV · Z²."""
RANGE = (0.5, 4.0)
"""Depth range (m); depth outside it is missing."""
MAX_INCIDENCE = math.radians(75.0)
"""Largest angle (rad) between a surface's normal and the ray for which depth is returned."""

FloatImage = npt.NDArray[np.float32]


def random_error(z: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """σ of the depth's random error (m) at depth ``z`` (m, any shape): SIGMA_INV · z²."""
    zz = np.asarray(z, dtype=np.float64)
    out: npt.NDArray[np.float64] = SIGMA_INV * zz * zz
    return out


def resolution(z: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """Depth step (m) between two successive disparity values at depth ``z`` (m): STEP_INV · z²."""
    zz = np.asarray(z, dtype=np.float64)
    out: npt.NDArray[np.float64] = STEP_INV * zz * zz
    return out


def apply_noise(
    depth: FloatImage,
    incidence: npt.NDArray[np.floating] | None,
    rng: np.random.Generator,
) -> FloatImage:
    """The ideal ``depth`` image (H × W, float32, m along the optical axis; NaN = nothing seen)
    as the Kinect returns it: random error and quantisation in inverse depth, NaN out of
    ``RANGE`` and where ``incidence`` (H × W, rad between normal and ray; None: not applied)
    exceeds ``MAX_INCIDENCE`` or is NaN. Draws from ``rng`` (seeded: reproducible). Raises
    ``ValueError`` when the shapes differ."""
    if incidence is not None and incidence.shape != depth.shape:
        raise ValueError(f"incidence {incidence.shape} and depth {depth.shape} differ")
    z = depth.astype(np.float64)
    valid = np.isfinite(z) & (z >= RANGE[0]) & (z <= RANGE[1])
    if incidence is not None:
        with np.errstate(invalid="ignore"):
            valid &= np.isfinite(incidence) & (incidence <= MAX_INCIDENCE)
    inv = np.full(z.shape, np.nan)
    inv[valid] = 1.0 / z[valid] + rng.normal(0.0, SIGMA_INV, size=int(np.count_nonzero(valid)))
    inv[valid] = np.round(inv[valid] / STEP_INV) * STEP_INV
    out = np.full(z.shape, np.nan, dtype=np.float32)
    out[valid] = (1.0 / inv[valid]).astype(np.float32)
    with np.errstate(invalid="ignore"):
        out[(out < RANGE[0]) | (out > RANGE[1])] = np.nan
    return out
