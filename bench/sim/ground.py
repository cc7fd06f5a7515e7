"""Uneven ground: an ISO 8608 road-profile heightfield for the pybullet testbed.

ISO 8608:2016 (Mechanical vibration, road surface profiles) classifies a road by its one-sided
vertical displacement PSD in spatial frequency n [cycles/m],

    G_d(n) = G_d(n0) (n / n0)^-w,   n0 = 0.1 cycles/m,  w = 2,                          (ISO 8608 eq. (1))

with class geometric means G_d(n0) = 16, 64, 256, 1024, 4096 ... x 1e-6 m^3 for classes A, B, C, D, E ...
(:data:`ISO8608_CLASS_GD0`).  The standard defines the profile along the track; the ground here is a 2-D
surface whose every profile along x (the driving direction of the scenarios) has exactly that PSD in
expectation: the 2-D spectrum is the isotropic shape |k|^-3 (whose line integral over n_y is the
1-D n_x^-2 law) normalised at each n_x so that its sum over the grid's n_y equals the 1-D spectrum.
The field is drawn with numpy's FFT from ``Terrain.roughness_seed`` (a terrain field, so part of the
scenario hash and the same for every sensor seed: the physics stays seed-independent, bench/sim/__init__.py).

The ground is one GEOM_HEIGHTFIELD body spanning ``roughness_length_x`` x ``roughness_length_y`` (the
scenario must keep the robot on it: copies of a periodic tile cost ~0.1 s each to build and slowed the
step 2.3x at 144 tiles, so the field is sized to the path instead).  With ``roughness_gd0 = 0`` nothing here
is called and the ground is the GEOM_PLANE of bench/sim/testbed.py, bit for bit.

    ISO 8608 eq. (1)           -> :func:`iso8608_psd`
    field of that PSD          -> :func:`road_heights`
    periodogram of the profiles -> :func:`profile_psd` (validate-testbed's check, bench/sim/validate.py)
    closed-form variance       -> :func:`grid_variance`
"""
from __future__ import annotations

import math

import numpy as np

N0 = 0.1  # ISO 8608 reference spatial frequency [cycles/m]
ISO8608_CLASS_GD0 = {c: 16e-6 * 4.0**i for i, c in enumerate("ABCDEFGH")}  # geometric class means [m^3]


def iso8608_psd(n: np.ndarray, gd0: float) -> np.ndarray:
    """One-sided displacement PSD G_d(n) [m^3] of ISO 8608 eq. (1) (waviness w = 2)."""
    n = np.asarray(n, dtype=float)
    return gd0 * (n / N0) ** -2.0


def grid_variance(gd0: float, spacing: float, n_x: int) -> float:
    """Closed-form expected height variance [m^2] of a profile of ``n_x`` points at ``spacing`` drawn by
    :func:`road_heights`: the sum of G_d(n) dn over its grid frequencies n = k / (n_x spacing), 0 < n < Nyquist,
    plus half the Nyquist bin's two-sided share (G_d(n0) n0^2 / dn * sum 1/k^2; -> the integral from dn as the
    bins get finer, times pi^2/6 for the lowest bins)."""
    dn = 1.0 / (n_x * spacing)
    k = np.arange(1, (n_x + 1) // 2)
    var = float(np.sum(iso8608_psd(k * dn, gd0)) * dn)
    if n_x % 2 == 0:
        var += 0.5 * float(iso8608_psd(n_x // 2 * dn, gd0)) * dn
    return var


def road_heights(gd0: float, spacing: float, n_x: int, n_y: int, seed: int) -> np.ndarray:
    """Heights [m], shape (n_x, n_y), on a periodic grid of ``spacing``: every row profile along x has
    the expected one-sided periodogram G_d(n_x) at each grid frequency n_x != 0 (zero mean per row)."""
    rng = np.random.default_rng(seed)
    nx = np.fft.fftfreq(n_x, spacing)[:, None]  # cycles/m
    ny = np.fft.fftfreq(n_y, spacing)[None, :]
    with np.errstate(divide="ignore"):
        shape = (nx * nx + ny * ny) ** -1.5  # isotropic 2-D shape whose n_y integral is ~ n_x^-2
        shape = np.where(nx == 0.0, 0.0, shape)
        p1 = np.where(nx == 0.0, 0.0, 0.5 * gd0 * (N0 / np.where(nx == 0.0, 1.0, nx)) ** 2)  # two-sided 1-D
    weight = shape / shape.sum(axis=1, keepdims=True).clip(min=1e-300)
    dn_x = 1.0 / (n_x * spacing)
    amp = np.sqrt(p1 * dn_x * weight)  # variance of each Fourier coefficient
    white = np.fft.fft2(rng.standard_normal((n_x, n_y))) / math.sqrt(n_x * n_y)
    return np.real(np.fft.ifft2(white * amp)) * (n_x * n_y)


def profile_psd(heights: np.ndarray, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """(n, one-sided periodogram [m^3]) of the row profiles along x, averaged over the rows (the whole
    periodic profile, no window: the field is periodic)."""
    n_x = heights.shape[0]
    spec = np.abs(np.fft.rfft(heights, axis=0)) ** 2
    psd = 2.0 * spacing / n_x * spec.mean(axis=1)
    n = np.fft.rfftfreq(n_x, spacing)
    return n[1:-1], psd[1:-1]  # DC and Nyquist bins are not one-sided doubled bins


def field_heights(gd0: float, spacing: float, length_x: float, length_y: float, seed: int) -> np.ndarray:
    """The ground's heights [m] on its grid, x along axis 0: the periodic field of
    :func:`road_heights` with its wrap-around row and column appended (shape (N_x + 1, N_y + 1))."""
    n_x, n_y = (max(8, int(round(length / spacing))) for length in (length_x, length_y))
    h = road_heights(gd0, spacing, n_x, n_y, seed)
    return np.pad(h, ((0, 1), (0, 1)), mode="wrap")


def build_heightfield(p, cid: int, h: np.ndarray, spacing: float, corner: tuple[float, float]) -> int:
    """One GEOM_HEIGHTFIELD body of the heights ``h`` (x along axis 0) in client ``cid``, its node (0, 0)
    at world (x, y) = ``corner``; returns the body id."""
    rows, cols = h.shape
    # pybullet indexes heightfieldData[i + j * rows] with i along x (checked by ray casts in
    # tests/test_ground.py); the shape is centred at its mid-height (min + max) / 2 and mid-extent
    shape = p.createCollisionShape(
        p.GEOM_HEIGHTFIELD, meshScale=(spacing, spacing, 1.0), heightfieldData=h.ravel(order="F").tolist(),
        numHeightfieldRows=rows, numHeightfieldColumns=cols, physicsClientId=cid,
    )
    centre = (corner[0] + 0.5 * (rows - 1) * spacing, corner[1] + 0.5 * (cols - 1) * spacing,
              0.5 * (float(h.max()) + float(h.min())))
    # a visual shape of its own: with -1 pybullet turns the heightfield into a render mesh for its DIRECT-mode
    # renderer (1.4 s of the 3 s a 1025 x 1025 field takes to build), which no run reads; collision is unchanged
    unseen = p.createVisualShape(p.GEOM_SPHERE, radius=1e-3, physicsClientId=cid)
    body = p.createMultiBody(0, shape, unseen, centre, (0, 0, 0, 1), physicsClientId=cid)
    p.changeDynamics(body, -1, lateralFriction=1.0, physicsClientId=cid)
    return body


def height_at(h: np.ndarray, spacing: float, corner: tuple[float, float], x: float, y: float) -> float:
    """Bilinear height of the grid ``h`` (node (0, 0) at ``corner``) at world (x, y), periodic beyond its
    edges (an estimate of the triangulated surface: exact at the grid nodes)."""
    n_x, n_y = h.shape[0] - 1, h.shape[1] - 1
    u, v = ((x - corner[0]) / spacing) % n_x, ((y - corner[1]) / spacing) % n_y
    i, j = int(u), int(v)
    fu, fv = u - i, v - j
    return float((1 - fu) * (1 - fv) * h[i, j] + fu * (1 - fv) * h[i + 1, j]
                 + (1 - fu) * fv * h[i, j + 1] + fu * fv * h[i + 1, j + 1])


def ground_corner(terr) -> tuple[float, float]:
    """World (x, y) of the heightfield's node (0, 0): the field spans ``roughness_length_x`` centred at
    ``roughness_centre_x`` and ``roughness_length_y`` centred at ``roughness_centre_y``."""
    return (terr.roughness_centre_x - 0.5 * terr.roughness_length_x,
            terr.roughness_centre_y - 0.5 * terr.roughness_length_y)


def rough_ground(p, cid: int, terr, plat, yaw: float) -> tuple[int, float]:
    """The rough ground of terrain ``terr`` in client ``cid``; returns (first body id, the highest ground
    height under the four wheels of ``plat`` placed at the origin with heading ``yaw``: the start height)."""
    if terr.slope != 0.0:
        raise ValueError(f"terrain {terr.name}: roughness_gd0 {terr.roughness_gd0} with slope {terr.slope}: "
                         "a rough ramp is not modelled (set one of them to 0)")
    sp, corner = terr.roughness_spacing, ground_corner(terr)
    h = field_heights(terr.roughness_gd0, sp, terr.roughness_length_x, terr.roughness_length_y, terr.roughness_seed)
    body = build_heightfield(p, cid, h, sp, corner)
    c, s = math.cos(yaw), math.sin(yaw)
    a, b = plat.wheelbase / 2, plat.track / 2
    z = max(height_at(h, sp, corner, c * x - s * y, s * x + c * y)
            for x in (-a, a) for y in (-b, b))
    return body, z + 0.01 * plat.wheel_radius  # clears the triangles between the grid nodes
