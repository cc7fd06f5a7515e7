"""Mandow 2007 Sec. III: calibration segments and the odometric cost J(K) of eq. (13).

Training paths are cut into N short segments at the external sensor's rate; each segment's model pose
increment integrates eq. (6) with (7) (exact SE(2) integration, batched over a population of K for the
optimisers of :mod:`methods.mandow2007.ga`) and is compared with the reference increment.

Implementation choice the paper leaves open (documented, configurable): segments of eq. (13) are cut at
every reference sample (the paper: "according to the external sensor rate"); ``segment_period`` merges
reference samples into longer segments.  Increments are compared in the frame of the reference pose at the
segment start (the squared position error of eq. (13) does not depend on that rotation); the heading
residual is wrapped.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Sequence

import numpy as np
from numpy.typing import ArrayLike

from bench import registry
from bench.run import Run, wrap_angle
from methods.baselines import encoder_speeds, has_reference, platform_geometry, reference_poses
from methods.mandow2007.kinematics import PARAM_NAMES, IcrParams

try:  # eq. (13) in C (built by pip install); segment_cost_numpy is its reference and the fallback
    from methods.mandow2007 import _cost as _COST
except ImportError:  # pragma: no cover - a source tree without the built extension
    _COST = None


class CalibrationDataError(registry.CalibrationDataError):
    """The calibration runs do not contain the experiment an identification needs."""


@dataclass(frozen=True, eq=False)
class Segments:
    """Calibration data of eq. (13), all runs concatenated.

    Sub-interval arrays (length M): ``dt`` and the nominal tread speeds ``v_l``, ``v_r`` held on it
    (zero-order hold of the encoder samples; sub-intervals are cut at encoder and reference
    instants), ``index`` = its segment.  Segment arrays (length N): ``first`` = index of its first
    sub-interval, reference increments ``ref_dx``, ``ref_dy`` in the frame of the reference pose at
    the segment start, ``ref_dphi``, that start yaw ``ref_yaw0`` and ``duration``."""

    dt: np.ndarray
    v_l: np.ndarray
    v_r: np.ndarray
    index: np.ndarray
    first: np.ndarray
    ref_dx: np.ndarray
    ref_dy: np.ndarray
    ref_dphi: np.ndarray
    ref_yaw0: np.ndarray
    duration: np.ndarray
    run_ids: tuple[str, ...] = ()
    track: float = float("nan")

    @property
    def dl(self) -> np.ndarray:
        """Nominal left tread travel ``V_l dt`` of each interval [m]."""
        return self.v_l * self.dt

    @property
    def dr(self) -> np.ndarray:
        return self.v_r * self.dt

    @property
    def n_segments(self) -> int:
        return int(self.first.size)

    @property
    def n_intervals(self) -> int:
        return int(self.dt.size)


def _run_segments(run: Run, segment_period: float | None) -> dict[str, np.ndarray] | None:
    _, radius = platform_geometry(run)
    te, wl, wr = encoder_speeds(run)
    tr, x, y, yaw = reference_poses(run)
    m = (tr >= te[0]) & (tr <= te[-1])
    tr, x, y, yaw = tr[m], x[m], y[m], yaw[m]
    if segment_period is not None and tr.size:
        bins = np.floor((tr - tr[0]) / segment_period + 1e-9)
        _, keep = np.unique(bins, return_index=True)
        tr, x, y, yaw = tr[keep], x[keep], y[keep], yaw[keep]
    if tr.size < 2:
        return None
    inner = te[(te > tr[0]) & (te < tr[-1])]
    tau = np.union1d(tr, inner)
    start = tau[:-1]
    k = np.searchsorted(te, start, side="right") - 1
    c0, s0 = np.cos(yaw[:-1]), np.sin(yaw[:-1])
    dxw, dyw = np.diff(x), np.diff(y)
    return {
        "dt": np.diff(tau), "v_l": radius * wl[k], "v_r": radius * wr[k],
        "index": np.searchsorted(tr, start, side="right") - 1,
        "first": np.searchsorted(start, tr[:-1]),
        "ref_dx": c0 * dxw + s0 * dyw, "ref_dy": -s0 * dxw + c0 * dyw, "ref_dphi": np.diff(yaw),
        "ref_yaw0": yaw[:-1], "duration": np.diff(tr),
    }


def build_segments(runs: Sequence[Run], segment_period: float | None = None) -> Segments:
    """Cut every run with reference poses into segments between consecutive reference samples
    (Sec. III: "training paths can be broken into a number N of short segments according to the
    external sensor rate"); ``segment_period`` [s] merges samples into segments of about that length."""
    parts, ids, tracks = [], [], []
    for r in runs:
        if not has_reference(r):
            continue
        part = _run_segments(r, segment_period)
        if part is not None:
            parts.append(part)
            ids.append(r.id)
            tracks.append(platform_geometry(r)[0])
    if not parts:
        raise CalibrationDataError("eq. (13) needs runs with encoders and at least two reference poses "
                                   f"(ref_x, ref_y, ref_yaw); got runs {[r.id for r in runs]}")
    if len(set(tracks)) > 1:
        raise CalibrationDataError(f"calibration runs mix platforms with tracks {sorted(set(tracks))}")
    off_m = np.cumsum([0] + [p["dt"].size for p in parts[:-1]])
    off_n = np.cumsum([0] + [p["first"].size for p in parts[:-1]])
    cat = {k: np.concatenate([p[k] for p in parts]) for k in parts[0] if k not in ("index", "first")}
    index = np.concatenate([p["index"] + o for p, o in zip(parts, off_n, strict=True)])
    first = np.concatenate([p["first"] + o for p, o in zip(parts, off_m, strict=True)])
    return Segments(index=index, first=first, run_ids=tuple(ids), track=tracks[0], **cat)


_SMALL_ANGLE = 0.05  # |d| below which sin(d)/d and (1-cos d)/d use their series (truncation < 1e-16)


def _increments_chunk(seg: Segments, k: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Segment increments (dx, dy in the segment-start frame, dphi) for parameter rows ``k`` (P, 5):
    eqs. (6)-(7) integrated exactly (SE(2) exponential, zero-order hold) over each segment.

    Same integration as :func:`bench.kinematics.integrate_se2`, batched over a population and
    restarted at every segment (this is the GA's inner loop).  Eq. (7) is linear in the tread
    travels ``V dt``; the heading factor ``exp(i yaw)`` is the running product of the per-interval
    rotations ``exp(i d) = 1 - d c + i d s`` with ``s = sin(d)/d``, ``c = (1 - cos d)/d`` from their
    series (trigonometric calls only for the rare ``|d| > 0.05``)."""
    xl, xr, yv, al, ar = (k[:, i:i + 1] for i in range(5))
    inv = 1.0 / (xr - xl)
    # eq. (7) rows on the travels (suite axes: forward row, yaw row; lateral = -y_ICRv * yaw)
    dth = (-al * inv) * seg.dl + (ar * inv) * seg.dr
    fwd = (xr * al * inv) * seg.dl + (-xl * ar * inv) * seg.dr
    lat = -yv * dth
    d2 = dth * dth
    s = 1.0 + d2 * (-1 / 6 + d2 * (1 / 120 - d2 / 5040))
    c = dth * (0.5 + d2 * (-1 / 24 + d2 * (1 / 720 - d2 / 40320)))
    big = np.abs(dth) > _SMALL_ANGLE
    if big.any():
        db = dth[big]
        s[big], c[big] = np.sin(db) / db, (1.0 - np.cos(db)) / db
    n, m = k.shape[0], seg.n_intervals
    rot = np.empty((n, m), complex)
    rot.real = 1.0 - dth * c
    rot.imag = dth * s
    heading = np.empty((n, m + 1), complex)
    heading[:, 0] = 1.0
    np.cumprod(rot, axis=1, out=heading[:, 1:])
    z = np.empty((n, m), complex)  # body increment of each interval, (s + i c)(fwd + i lat)
    z.real = s * fwd - c * lat
    z.imag = c * fwd + s * lat
    z *= heading[:, :-1]  # ... in the run-start frame
    h0 = heading[:, seg.first]
    dz = np.add.reduceat(z, seg.first, axis=1) * (np.conj(h0) / (h0.real**2 + h0.imag**2))
    return dz.real, dz.imag, np.add.reduceat(dth, seg.first, axis=1)


def segment_increments(seg: Segments, params: ArrayLike, max_elements: int = 16384
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Model increments for a population ``params`` (P, 5) or one set (5,): arrays (P, N).
    Evaluated in chunks of about ``max_elements`` (candidates x intervals) to stay in cache."""
    k = np.atleast_2d(np.asarray(params, float))
    if k.shape[1] != 5:
        raise ValueError(f"parameter rows must have 5 values {PARAM_NAMES}, got shape {k.shape}")
    rows = max(1, max_elements // max(1, seg.n_intervals))
    parts = [_increments_chunk(seg, k[i:i + rows]) for i in range(0, k.shape[0], rows)]
    return tuple(np.concatenate([p[j] for p in parts]) for j in range(3))  # type: ignore[return-value]


def segment_cost(seg: Segments, params: ArrayLike) -> np.ndarray:
    """Eq. (13): J(K) = sum_i (dx_i - dx^_i)^2 + (dy_i - dy^_i)^2 + (dphi_i - dphi^_i)^2 for each
    parameter row (P,), or a scalar array for one set.  Degenerate rows (x_ICRr <= x_ICRl) cost inf.

    Computed by the C implementation (``methods/mandow2007/_cost.c``, ~20x faster: the GA's whole cost) when
    it is built and ``SKIDBENCH_KERNEL`` is not ``python``; otherwise by :func:`segment_cost_numpy`, its
    reference (the two agree to ~1e-15 relative: tests/methods/mandow2007/test_cost_c.py)."""
    if _COST is None or os.environ.get("SKIDBENCH_KERNEL", "c") == "python":
        return segment_cost_numpy(seg, params)
    k = np.asarray(params, float)
    k2 = np.ascontiguousarray(np.atleast_2d(k), dtype=np.float64)
    if k2.shape[1] != 5:
        raise ValueError(f"parameter rows must have 5 values {PARAM_NAMES}, got shape {k2.shape}")
    c = _c_arrays(seg)
    out = np.empty(k2.shape[0])
    _COST.segment_cost(k2, *c, out)
    return out if k.ndim > 1 else out[0]


def _c_arrays(seg: Segments) -> tuple[np.ndarray, ...]:
    """The contiguous arrays the C cost reads (made once per Segments object)."""
    got = seg.__dict__.get("_c_arrays")
    if got is None:
        got = tuple(np.ascontiguousarray(a, dtype=dt) for a, dt in (
            (seg.dl, np.float64), (seg.dr, np.float64), (seg.first, np.int64), (seg.ref_dx, np.float64),
            (seg.ref_dy, np.float64), (seg.ref_dphi, np.float64)))
        object.__setattr__(seg, "_c_arrays", got)
    return got


def segment_cost_numpy(seg: Segments, params: ArrayLike) -> np.ndarray:
    """Eq. (13) in numpy (the reference of the C cost; see :func:`segment_cost`)."""
    k = np.asarray(params, float)
    k2 = np.atleast_2d(k)
    ok = k2[:, 1] > k2[:, 0]
    out = np.full(k2.shape[0], np.inf)
    if ok.any():
        dx, dy, dphi = segment_increments(seg, k2[ok])
        out[ok] = np.sum((seg.ref_dx - dx) ** 2 + (seg.ref_dy - dy) ** 2 + wrap_angle(seg.ref_dphi - dphi) ** 2,
                         axis=1)
    return out if k.ndim > 1 else out[0]


def segment_errors(seg: Segments, p: IcrParams) -> dict[str, np.ndarray]:
    """Per-segment errors (reference - model) in the WORLD frame: ``ex``, ``ey`` [m], ``ephi`` [rad]
    (Table III reports their mean squares)."""
    dx, dy, dphi = (a[0] for a in segment_increments(seg, p.as_array()))
    bx, by = seg.ref_dx - dx, seg.ref_dy - dy
    c, s = np.cos(seg.ref_yaw0), np.sin(seg.ref_yaw0)
    return {"ex": c * bx - s * by, "ey": s * bx + c * by, "ephi": wrap_angle(seg.ref_dphi - dphi)}
