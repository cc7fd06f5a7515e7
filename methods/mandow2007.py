"""Mandow et al. 2007: experimental ICR kinematics of a wheeled skid-steer robot.

Citation
    A. Mandow, J. L. Martinez, J. Morales, J. L. Blanco, A. Garcia-Cerezo and J. Gonzalez,
    "Experimental kinematics for wheeled skid-steer mobile robots", in Proc. IEEE/RSJ Int. Conf. on
    Intelligent Robots and Systems (IROS), San Diego, CA, USA, 2007, pp. 1222-1227.

Paper equation -> code
    (2)-(5)   tread ICRs from velocities          ``IcrParams`` (fields), ``IcrParams.body_icr``
    (6)-(7)   kinematic matrix A(K)               :func:`kinematic_matrix`, :func:`body_velocities`
    (8)       symmetric model                     :meth:`IcrParams.symmetric`
    (9)       steering efficiency chi             :func:`steering_efficiency`
    (10)      eccentricity e                      :func:`eccentricity`
    (11)      x_ICR from a pure rotation          :func:`identify_symmetric`
    (12)      alpha from a straight line          :func:`identify_symmetric`
    (13)      segment cost J(K)                   :func:`build_segments`, :func:`segment_cost`,
                                                  :func:`segment_errors`
    Sec. III  GA, 8-bit genes, 40-bit chromosome  :func:`identify_ga` (pygad)
              (second optimiser, not in paper)    :func:`identify_de` (scipy differential_evolution)
    (14)-(15) P3-AT server Ticksmm / Revcount      :func:`p3at_server_parameters`, :func:`p3at_symmetric_model`
    Sec. IV-B default P3-AT model (alpha = 1, x_ICR = 0.3 m)   :data:`P3AT_DEFAULT`
    Tables I, II (published parameters)           :data:`TABLE_I`, :data:`TABLE_II`

Plugins: ``mandow2007.default_p3at`` (:class:`DefaultP3at`), ``mandow2007.symmetric``
(:class:`Symmetric`), ``mandow2007.asymmetric_ga`` (:class:`AsymmetricGa`),
``mandow2007.asymmetric_de`` (:class:`AsymmetricDe`).

Axes (converted here, at the boundary)
    Mandow's local frame has Y forward and X lateral pointing to the RIGHT (eq. (7): a positive
    yaw rate needs V_r > V_l when x_ICRr > x_ICRl).  The suite's body frame has x forward, y left.
    Hence, for the ICR coordinates::

        y_l   = -x_ICRl        y_r = -x_ICRr        x_icr = y_ICRv
        vx    = Mandow v_y     vy  = -Mandow v_x    wz    = omega_z

    :class:`IcrParams` keeps Mandow's names and signs (so Table I can be typed in as printed);
    :meth:`IcrParams.body_icr` gives the suite's ``(y_l, y_r, x_icr)``.  Mandow's tread speeds
    ``V_l, V_r`` are the nominal ones, ``r * w`` with the platform's nominal wheel radius; the
    correction factors ``alpha_l, alpha_r`` turn them into the speeds that move the ICRs (eqs. (3)-(4)).

Implementation choices the paper leaves open (documented, configurable)
    * Eq. (11) is written without alpha.  With eq. (3) (the tread ICR is defined on the corrected
      speed alpha*V), a pure rotation gives ``x_ICR = alpha (S_r - S_l) / (2 phi)``; this consistent
      form is the default (alpha from eq. (12) first), ``alpha_in_eq11=False`` gives the literal one.
    * Segments of eq. (13) are cut at every reference sample (the paper: "according to the external
      sensor rate"); ``segment_period`` merges reference samples into longer segments.  Increments
      are compared in the frame of the reference pose at the segment start (the squared position
      error of eq. (13) does not depend on that rotation); the heading residual is wrapped.
    * Gene ranges are not published: :meth:`GeneRanges.for_track` (x_ICR in [0.4 B, 1.2 B] per
      side, y_ICRv in [-B/4, B/4], alpha in [0.75, 1.15]); 8 bits each, decoded linearly; Gray
      coding is on by default (the paper does not state the bit code; plain binary via
      ``GaSettings(gray_code=False)``).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike

from bench.kinematics import icr_forward
from bench.registry import Estimate, make_estimate
from bench.run import Run, RunError, wrap_angle
from methods.baselines import (
    dead_reckon,
    encoder_speeds,
    has_reference,
    held_integral,
    initial_pose,
    platform_geometry,
    reference_poses,
)

PAPER = "Mandow et al. 2007"
PARAM_NAMES = ("x_icr_l", "x_icr_r", "y_icr_v", "alpha_l", "alpha_r")
GENE_BITS = 8  # Sec. IV-C: "each parameter has been coded as an 8 bit string"


class NotCalibratedError(RuntimeError):
    """A plugin that needs identified parameters was asked to estimate before calibration."""


class CalibrationDataError(ValueError):
    """The calibration runs do not contain the experiment an identification needs."""


# ------------------------------------------------------------------------------------------------
# Parameters, kinematic matrix, indexes
# ------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class IcrParams:
    """Kinematic parameters K = {x_ICRl, x_ICRr, y_ICRv, alpha_l, alpha_r} in Mandow's axes
    (X lateral to the right, Y forward) [m, m, m, -, -]."""

    x_icr_l: float
    x_icr_r: float
    y_icr_v: float
    alpha_l: float = 1.0
    alpha_r: float = 1.0

    def __post_init__(self) -> None:
        vals = self.as_array()
        if not np.all(np.isfinite(vals)):
            raise ValueError(f"IcrParams must be finite, got {dict(zip(PARAM_NAMES, vals, strict=True))}")
        if not self.x_icr_r > self.x_icr_l:
            raise ValueError(f"IcrParams needs x_icr_r > x_icr_l (right tread ICR right of the left one), "
                             f"got x_icr_l={self.x_icr_l}, x_icr_r={self.x_icr_r}")

    @classmethod
    def symmetric(cls, alpha: float, x_icr: float) -> "IcrParams":
        """Eq. (8): alpha_l = alpha_r = alpha, x_ICR = -x_ICRl = x_ICRr, y_ICRv = 0."""
        return cls(-x_icr, x_icr, 0.0, alpha, alpha)

    @classmethod
    def ideal(cls, track: float) -> "IcrParams":
        """No-slip differential drive: tread ICRs on the tread centre lines, alpha = 1."""
        return cls.symmetric(1.0, track / 2.0)

    @classmethod
    def from_array(cls, k: ArrayLike) -> "IcrParams":
        k = np.asarray(k, float).ravel()
        return cls(*(float(v) for v in k))

    def as_array(self) -> np.ndarray:
        return np.array([self.x_icr_l, self.x_icr_r, self.y_icr_v, self.alpha_l, self.alpha_r], float)

    def as_dict(self) -> dict[str, float]:
        return dict(zip(PARAM_NAMES, (float(v) for v in self.as_array()), strict=True))

    def body_icr(self) -> tuple[float, float, float]:
        """The suite's ``(y_l, y_r, x_icr)`` = ``(-x_ICRl, -x_ICRr, y_ICRv)`` (axes conversion)."""
        return -self.x_icr_l, -self.x_icr_r, self.y_icr_v

    def steering_efficiency(self, track: float) -> float:
        return float(steering_efficiency(self.x_icr_l, self.x_icr_r, track))

    def eccentricity(self) -> float:
        return float(eccentricity(self.x_icr_l, self.x_icr_r))


P3AT_DEFAULT = IcrParams.symmetric(1.0, 0.3)
"""Sec. IV-B: the manufacturer's implicit symmetric model of the P3-AT, alpha = 1, x_ICR = 0.3 m."""

TABLE_I = {  # asphalt (Mandow Table I), Mandow's axes
    "pneumatic_50psi": IcrParams(-0.2758, 0.2998, -0.0080, 0.9464, 0.9253),
    "pneumatic_20psi": IcrParams(-0.2553, 0.3071, -0.0120, 0.9271, 0.9049),
    "solid_rubber": IcrParams(-0.2667, 0.2588, -0.0120, 0.9047, 0.9128),
}
TABLE_II = {  # smooth concrete (Mandow Table II)
    "pneumatic_50psi": IcrParams(-0.2878, 0.2758, -0.0159, 0.9457, 0.9418),
    "pneumatic_20psi": IcrParams(-0.2772, 0.2899, -0.0128, 0.9222, 0.9183),
    "solid_rubber": IcrParams(-0.2659, 0.2703, -0.0139, 0.9047, 0.9139),
}


P3AT_ENCODER_GEAR = 138 / 110  # eq. (14): encoder and transmission constant of the P3-AT


def p3at_server_parameters(alpha: float, x_icr: float, wheel_radius: float) -> tuple[int, int]:
    """Eqs. (14)-(15): the P3-AT server's integer ``(Ticksmm, Revcount)`` for a symmetric model
    (alpha, x_ICR [m]) and the wheel radius [m] (the equations take millimetres: converted here)."""
    r_mm, x_icr_mm = 1000.0 * wheel_radius, 1000.0 * x_icr
    ticksmm = round(alpha * r_mm * P3AT_ENCODER_GEAR)
    return ticksmm, round(2 * np.pi * x_icr_mm * ticksmm / 8)


def p3at_symmetric_model(ticksmm: int, revcount: int, wheel_radius: float) -> IcrParams:
    """Inverse of eqs. (14)-(15): the symmetric model (eq. (8)) implied by the server parameters."""
    alpha = ticksmm / (1000.0 * wheel_radius * P3AT_ENCODER_GEAR)
    return IcrParams.symmetric(alpha, 8 * revcount / (2 * np.pi * ticksmm) / 1000.0)


def kinematic_matrix(p: IcrParams) -> np.ndarray:
    """Eq. (7): the 3x2 matrix A with (v_x, v_y, omega_z)^T = A (V_l, V_r)^T in Mandow's axes."""
    d = p.x_icr_r - p.x_icr_l
    return np.array([
        [-p.y_icr_v * p.alpha_l, p.y_icr_v * p.alpha_r],
        [p.x_icr_r * p.alpha_l, -p.x_icr_l * p.alpha_r],
        [-p.alpha_l, p.alpha_r],
    ]) / d


def body_velocities(p: IcrParams, v_l: ArrayLike, v_r: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Eqs. (6)-(7) in the suite's body frame: ``(vx, vy, wz)`` from nominal tread speeds
    ``V = r w`` [m/s].  Uses :func:`bench.kinematics.icr_forward` on the corrected speeds
    ``alpha V`` with ``(y_l, y_r, x_icr) = (-x_ICRl, -x_ICRr, y_ICRv)``."""
    y_l, y_r, x_icr = p.body_icr()
    return icr_forward(p.alpha_l * np.asarray(v_l, float), p.alpha_r * np.asarray(v_r, float), y_l, y_r, x_icr)


def steering_efficiency(x_icr_l: ArrayLike, x_icr_r: ArrayLike, track: float) -> np.ndarray:
    """Eq. (9): chi = L / (x_ICRr - x_ICRl), 0 < chi <= 1 (the inverse of Wang's chi)."""
    return track / (np.asarray(x_icr_r, float) - np.asarray(x_icr_l, float))


def eccentricity(x_icr_l: ArrayLike, x_icr_r: ArrayLike) -> np.ndarray:
    """Eq. (10): e = (x_ICRr + x_ICRl) / (x_ICRr - x_ICRl)."""
    x_icr_l, x_icr_r = np.asarray(x_icr_l, float), np.asarray(x_icr_r, float)
    return (x_icr_r + x_icr_l) / (x_icr_r - x_icr_l)


def dead_reckoning(p: IcrParams, run: Run, name: str = "mandow2007", info: Mapping[str, Any] | None = None
                   ) -> Estimate:
    """Dead reckoning of eq. (6) with (7) from the encoders, from :func:`methods.baselines.initial_pose`."""
    track, radius = platform_geometry(run)
    t, wl, wr = encoder_speeds(run)
    vx, vy, wz = body_velocities(p, radius * wl, radius * wr)
    pose0 = initial_pose(run)
    x, y, yaw = dead_reckon(t, vx, vy, wz, pose0)
    y_l, y_r, x_icr = p.body_icr()
    n = t.size
    out = {"params": p.as_dict(), "body_icr": {"y_l": y_l, "y_r": y_r, "x_icr": x_icr},
           "steering_efficiency": p.steering_efficiency(track), "eccentricity": p.eccentricity(),
           "initial_pose": pose0}
    out.update(info or {})
    return make_estimate(
        name, out, t=t, x=x, y=y, yaw=yaw, vx=vx, vy=vy, wz=wz,
        y_l=np.full(n, y_l), y_r=np.full(n, y_r), x_icr=np.full(n, x_icr),
        chi=np.full(n, (y_l - y_r) / track),
    )


# ------------------------------------------------------------------------------------------------
# Symmetric model from pure-rotation and straight-line experiments: eqs. (11)-(12)
# ------------------------------------------------------------------------------------------------
_ROTATION_KINDS = {"rotation", "pure_rotation", "spin", "turn_in_place"}
_STRAIGHT_KINDS = {"straight", "straight_line", "line"}


def run_kind(run: Run, tol: float = 0.05) -> str:
    """``"rotation"``, ``"straight"`` or ``"other"``: from ``run.meta["scenario_kind"]`` when it names
    one of them, else from the wheel commands (encoders if there are no commands).  A run is a pure rotation when
    ``|w_l + w_r| <= tol (|w_l| + |w_r|)`` and straight when ``|w_l - w_r| <= tol (|w_l| + |w_r|)``
    on 95 % of the samples where the robot is commanded to move."""
    kind = run.meta.get("scenario_kind")
    if kind is None and isinstance(run.meta.get("command"), Mapping):
        kind = run.meta["command"].get("kind")
    if isinstance(kind, str):
        k = kind.lower()
        if k in _ROTATION_KINDS:
            return "rotation"
        if k in _STRAIGHT_KINDS:
            return "straight"
        # other kinds (v_radius, wheel_speeds, ...) may still be a straight line: look at the commands
    chans = ("cmd_wl", "cmd_wr") if run.has("cmd_wl") and run.has("cmd_wr") else ("enc_wl", "enc_wr")
    if not (run.has(chans[0]) and run.has(chans[1])):
        return "other"
    wl, wr = run[chans[0]], run[chans[1]]
    ok = np.isfinite(wl) & np.isfinite(wr)
    mag = np.abs(wl[ok]) + np.abs(wr[ok])
    if mag.size == 0 or mag.max() <= 0:
        return "other"
    moving = mag > 0.2 * mag.max()
    sum_ratio = np.abs(wl[ok] + wr[ok])[moving] / mag[moving]
    diff_ratio = np.abs(wl[ok] - wr[ok])[moving] / mag[moving]
    if np.mean(sum_ratio <= tol) >= 0.95:
        return "rotation"
    if np.mean(diff_ratio <= tol) >= 0.95:
        return "straight"
    return "other"


@dataclass(frozen=True)
class RunTravel:
    """Wheel travel and reference motion of one run between its first and last reference sample."""

    run_id: str
    s_l: float  # integral V_l dt [m] (nominal tread speed)
    s_r: float
    distance: float  # reference displacement |p_end - p_start| [m]
    phi: float  # reference rotation angle (unwrapped) [rad]
    duration: float


def run_travel(run: Run) -> RunTravel:
    """Integrals of eqs. (11)-(12) for one run over the span of its reference samples."""
    _, radius = platform_geometry(run)
    t, wl, wr = encoder_speeds(run)
    tr, x, y, yaw = reference_poses(run)
    m = (tr >= t[0]) & (tr <= t[-1])
    if m.sum() < 2:
        raise RunError(run.where, "ref_yaw", f"{int(m.sum())} samples within the encoder span",
                       "identification needs two reference samples while the encoders run")
    tr, x, y, yaw = tr[m], x[m], y[m], yaw[m]
    s_l = float(radius * held_integral(t, wl, tr[0], tr[-1]))
    s_r = float(radius * held_integral(t, wr, tr[0], tr[-1]))
    return RunTravel(run.id, s_l, s_r, float(np.hypot(x[-1] - x[0], y[-1] - y[0])), float(yaw[-1] - yaw[0]),
                     float(tr[-1] - tr[0]))


@dataclass(frozen=True)
class SymmetricIdentification:
    """Result of eqs. (11)-(12): alpha from straight runs, x_ICR from pure rotations (pooled)."""

    alpha: float
    x_icr: float
    alpha_in_eq11: bool
    straight: tuple[RunTravel, ...]
    rotation: tuple[RunTravel, ...]

    @property
    def params(self) -> IcrParams:
        return IcrParams.symmetric(self.alpha, self.x_icr)

    def as_dict(self) -> dict[str, Any]:
        return {"alpha": self.alpha, "x_icr": self.x_icr, "alpha_in_eq11": self.alpha_in_eq11,
                "straight_runs": [r.run_id for r in self.straight],
                "rotation_runs": [r.run_id for r in self.rotation],
                "straight": [dataclasses.asdict(r) for r in self.straight],
                "rotation": [dataclasses.asdict(r) for r in self.rotation]}


def identify_symmetric(runs: Sequence[Run], alpha_in_eq11: bool = True) -> SymmetricIdentification:
    """Symmetric model of eq. (8) from the runs' pure rotations (eq. (11)) and straight lines
    (eq. (12)); runs are sorted by :func:`run_kind`, others ignored.  Pooled over runs:

        alpha = 2 sum d / sum |S_r + S_l|                                (eq. (12))
        x_ICR = alpha sum |S_r - S_l| / (2 sum |phi|)                    (eq. (11) with eq. (3))

    ``alpha_in_eq11=False`` drops the factor alpha (eq. (11) as printed)."""
    kinds = [(r, run_kind(r)) for r in runs]
    straight = [run_travel(r) for r, k in kinds if k == "straight" and has_reference(r)]
    rotation = [run_travel(r) for r, k in kinds if k == "rotation" and has_reference(r)]
    listing = ", ".join(f"{r.id}={k}" for r, k in kinds) or "(no runs)"
    if not rotation:
        raise CalibrationDataError(f"mandow2007.symmetric: eq. (11) needs a pure-rotation run with reference "
                                   f"poses; calibration runs: {listing}")
    if not straight:
        raise CalibrationDataError(f"mandow2007.symmetric: eq. (12) needs a straight-line run with reference "
                                   f"poses; calibration runs: {listing}")
    wheel = sum(abs(s.s_r + s.s_l) for s in straight)
    turn = sum(abs(s.phi) for s in rotation)
    if wheel <= 0 or turn <= 0:
        raise CalibrationDataError(f"mandow2007.symmetric: degenerate experiments (wheel travel {wheel} m, "
                                   f"rotation {turn} rad); calibration runs: {listing}")
    alpha = 2.0 * sum(s.distance for s in straight) / wheel
    x_icr = sum(abs(s.s_r - s.s_l) for s in rotation) / (2.0 * turn)
    if alpha_in_eq11:
        x_icr *= alpha
    return SymmetricIdentification(alpha, x_icr, alpha_in_eq11, tuple(straight), tuple(rotation))


# ------------------------------------------------------------------------------------------------
# Segments and the cost of eq. (13)
# ------------------------------------------------------------------------------------------------
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
    parameter row (P,), or a scalar array for one set.  Degenerate rows (x_ICRr <= x_ICRl) cost inf."""
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


# ------------------------------------------------------------------------------------------------
# Optimisers: GA (as published) and differential evolution (second optimiser)
# ------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class GeneRanges:
    """Search ranges per parameter (lo, hi) in Mandow's axes; not given in the paper."""

    x_icr_l: tuple[float, float]
    x_icr_r: tuple[float, float]
    y_icr_v: tuple[float, float]
    alpha_l: tuple[float, float] = (0.75, 1.15)
    alpha_r: tuple[float, float] = (0.75, 1.15)

    @classmethod
    def for_track(cls, track: float) -> "GeneRanges":
        """x_ICR within [0.4 B, 1.2 B] per side, y_ICRv within +-B/4, alpha within [0.75, 1.15]."""
        return cls((-1.2 * track, -0.4 * track), (0.4 * track, 1.2 * track), (-0.25 * track, 0.25 * track))

    def bounds(self) -> np.ndarray:
        b = np.array([getattr(self, n) for n in PARAM_NAMES], float)
        if np.any(b[:, 1] <= b[:, 0]):
            raise ValueError(f"gene ranges need lo < hi: {self}")
        return b

    def quantum(self, bits: int = GENE_BITS) -> np.ndarray:
        b = self.bounds()
        return (b[:, 1] - b[:, 0]) / (2**bits - 1)


@dataclass(frozen=True)
class GaSettings:
    """pygad settings for the 40-bit GA (the paper gives only the chromosome)."""

    population: int = 100
    generations: int = 300
    parents_mating: int = 50
    parent_selection: str = "tournament"
    tournament_size: int = 3
    crossover: str = "uniform"
    mutation_probability: float = 0.025  # per-bit flip probability (1/40: one bit per chromosome)
    gray_code: bool = True
    elitism: int = 2
    stop_saturate: int | None = 60  # stop after this many generations without improvement
    seed: int = 2007


@dataclass(frozen=True)
class DeSettings:
    """scipy.optimize.differential_evolution settings (vectorised objective)."""

    popsize: int = 10  # x 5 parameters = 50 members
    maxiter: int = 300
    tol: float = 1e-8
    atol: float = 0.0
    strategy: str = "best1bin"
    polish: bool = True
    seed: int = 2007


@dataclass(frozen=True)
class Identification:
    """Result of an asymmetric identification (eq. (13) minimised over K)."""

    optimiser: str
    params: IcrParams
    cost: float
    n_segments: int
    n_evaluations: int
    iterations: int
    seed: int
    runs: tuple[str, ...]
    bounds: tuple[tuple[float, float], ...]
    quantum: tuple[float, ...] | None = None
    cost_history: tuple[float, ...] = field(default=(), repr=False)

    def as_dict(self) -> dict[str, Any]:
        d = dataclasses.asdict(self)
        d["params"] = self.params.as_dict()
        return d


def decode_chromosomes(bits: ArrayLike, ranges: GeneRanges, gray_code: bool = True) -> np.ndarray:
    """40-bit chromosomes (P, 40) -> parameters (P, 5): 8 bits per parameter (MSB first), optionally
    Gray-coded, mapped linearly onto ``ranges`` (code 0 -> lo, 255 -> hi)."""
    b = np.atleast_2d(np.asarray(bits)).astype(np.int64)
    if b.shape[1] != 5 * GENE_BITS:
        raise ValueError(f"chromosomes must have {5 * GENE_BITS} bits, got shape {b.shape}")
    code = b.reshape(b.shape[0], 5, GENE_BITS) @ (1 << np.arange(GENE_BITS - 1, -1, -1))
    if gray_code:
        shift = 1
        while shift < GENE_BITS:
            code = code ^ (code >> shift)
            shift *= 2
    lo_hi = ranges.bounds()
    return lo_hi[:, 0] + code * (lo_hi[:, 1] - lo_hi[:, 0]) / (2**GENE_BITS - 1)


def identify_ga(seg: Segments, ranges: GeneRanges | None = None, settings: GaSettings = GaSettings()
                ) -> Identification:
    """Sec. III: GA over 40-bit chromosomes (8 bits per parameter) maximising -J(K) of eq. (13).
    pygad with a fixed ``random_seed`` (its own generators: no global random state); the fitness of
    a whole population is one vectorised call (``fitness_batch_size`` = population)."""
    import pygad  # local import: only identification needs it

    ranges = ranges or GeneRanges.for_track(seg.track)
    evals = [0]
    history: list[float] = []

    def fitness(_ga: Any, sols: np.ndarray, _idx: Any) -> np.ndarray:
        sols = np.atleast_2d(sols)
        evals[0] += sols.shape[0]
        return -segment_cost(seg, decode_chromosomes(sols, ranges, settings.gray_code))

    def bit_flip(offspring: np.ndarray, ga: Any) -> np.ndarray:
        # classical binary-GA mutation, vectorised, drawn from the GA's own seeded generator
        flip = ga.numpy_random_generator.random_sample(offspring.shape) < settings.mutation_probability
        return np.where(flip, 1 - offspring, offspring)

    def on_generation(ga: Any) -> None:
        history.append(float(-np.max(ga.last_generation_fitness)))

    ga = pygad.GA(
        num_generations=settings.generations,
        num_parents_mating=settings.parents_mating,
        fitness_func=fitness,
        fitness_batch_size=settings.population,
        sol_per_pop=settings.population,
        num_genes=5 * GENE_BITS,
        gene_space=[0, 1],
        gene_type=int,
        parent_selection_type=settings.parent_selection,
        K_tournament=settings.tournament_size,
        crossover_type=settings.crossover,
        mutation_type=bit_flip,
        keep_elitism=settings.elitism,
        stop_criteria=None if settings.stop_saturate is None else f"saturate_{settings.stop_saturate}",
        on_generation=on_generation,
        random_seed=settings.seed,
        suppress_warnings=True,
    )
    ga.run()
    best, fit, _ = ga.best_solution(pop_fitness=ga.last_generation_fitness)
    k = decode_chromosomes(best, ranges, settings.gray_code)[0]
    return Identification(
        optimiser="pygad.GA", params=IcrParams.from_array(k), cost=float(-fit), n_segments=seg.n_segments,
        n_evaluations=evals[0], iterations=int(ga.generations_completed), seed=settings.seed,
        runs=seg.run_ids,
        bounds=tuple(map(tuple, ranges.bounds().tolist())), quantum=tuple(ranges.quantum().tolist()),
        cost_history=tuple(history),
    )


def identify_de(seg: Segments, ranges: GeneRanges | None = None, settings: DeSettings = DeSettings()
                ) -> Identification:
    """Second optimiser (not in the paper): scipy differential evolution on continuous K within the
    same ranges, seeded, vectorised objective, L-BFGS-B polish."""
    from scipy.optimize import differential_evolution

    ranges = ranges or GeneRanges.for_track(seg.track)
    evals = [0]
    history: list[float] = []

    def objective(x: np.ndarray) -> np.ndarray | float:
        x = np.asarray(x, float)
        if x.ndim == 1:
            evals[0] += 1
            return float(segment_cost(seg, x))
        evals[0] += x.shape[1]
        return segment_cost(seg, x.T)

    def callback(intermediate_result: Any) -> None:
        history.append(float(intermediate_result.fun))

    res = differential_evolution(
        objective, ranges.bounds(), strategy=settings.strategy, maxiter=settings.maxiter,
        popsize=settings.popsize, tol=settings.tol, atol=settings.atol, rng=np.random.default_rng(settings.seed),
        polish=settings.polish, updating="deferred", vectorized=True, callback=callback,
    )
    return Identification(
        optimiser="scipy.optimize.differential_evolution", params=IcrParams.from_array(res.x), cost=float(res.fun),
        n_segments=seg.n_segments, n_evaluations=evals[0], iterations=int(res.nit), seed=settings.seed,
        runs=seg.run_ids, bounds=tuple(map(tuple, ranges.bounds().tolist())),
        cost_history=tuple(history),
    )


def compare_optimisers(runs: Sequence[Run], ranges: GeneRanges | None = None, ga: GaSettings = GaSettings(),
                       de: DeSettings = DeSettings(), segment_period: float | None = None
                       ) -> dict[str, Identification]:
    """GA (published) and DE (second optimiser) on the same segments: ``{"ga": ..., "de": ...}``."""
    seg = build_segments(runs, segment_period)
    return {"ga": identify_ga(seg, ranges, ga), "de": identify_de(seg, ranges, de)}


# ------------------------------------------------------------------------------------------------
# Plugins
# ------------------------------------------------------------------------------------------------
def _require_params(method: Any) -> IcrParams:
    if method.params is None:
        raise NotCalibratedError(f"{method.name}: no kinematic parameters; call calibrate(runs) first "
                                 "or construct it with params=IcrParams(...)")
    return method.params


def _ident_info(method: Any) -> dict[str, Any]:
    info: dict[str, Any] = {}
    if method.identification is not None:
        info["identification"] = method.identification.as_dict()
    if method.cross_identification is not None:
        info["cross_check"] = method.cross_identification.as_dict()
    return info


@dataclass(frozen=True)
class DefaultP3at:
    """``mandow2007.default_p3at``: the P3-AT server's symmetric model, alpha = 1, x_ICR = 0.3 m
    (Sec. IV-B).  Nothing to calibrate."""

    name: str = "mandow2007.default_p3at"
    paper: str = PAPER
    requires: frozenset[str] = frozenset({"enc_wl", "enc_wr"})
    params: IcrParams = P3AT_DEFAULT

    def calibrate(self, runs: Sequence[Run]) -> "DefaultP3at":
        return dataclasses.replace(self)

    def estimate(self, run: Run) -> Estimate:
        return dead_reckoning(self.params, run, self.name, {"model": "P3-AT default (alpha=1, x_ICR=0.3 m)"})


@dataclass(frozen=True)
class Symmetric:
    """``mandow2007.symmetric``: eq. (8) with alpha from straight runs (eq. (12)) and x_ICR from
    pure rotations (eq. (11)); calibration picks those runs by :func:`run_kind`."""

    name: str = "mandow2007.symmetric"
    paper: str = PAPER
    requires: frozenset[str] = frozenset({"enc_wl", "enc_wr"})
    params: IcrParams | None = None
    alpha_in_eq11: bool = True
    identification: SymmetricIdentification | None = field(default=None, compare=False, repr=False)

    def calibrate(self, runs: Sequence[Run]) -> "Symmetric":
        ident = identify_symmetric(runs, self.alpha_in_eq11)
        return dataclasses.replace(self, params=ident.params, identification=ident)

    def estimate(self, run: Run) -> Estimate:
        info = {"identification": self.identification.as_dict()} if self.identification else {}
        return dead_reckoning(_require_params(self), run, self.name, info)


@dataclass(frozen=True)
class AsymmetricGa:
    """``mandow2007.asymmetric_ga``: eq. (7) with K identified by the GA of Sec. III on every
    calibration run that has reference poses (segments at the reference rate, eq. (13))."""

    name: str = "mandow2007.asymmetric_ga"
    paper: str = PAPER
    requires: frozenset[str] = frozenset({"enc_wl", "enc_wr"})
    params: IcrParams | None = None
    ranges: GeneRanges | None = None
    settings: GaSettings = GaSettings()
    segment_period: float | None = None
    cross_check: bool = False  # also run differential evolution on the same segments (reported only)
    identification: Identification | None = field(default=None, compare=False, repr=False)
    cross_identification: Identification | None = field(default=None, compare=False, repr=False)

    def calibrate(self, runs: Sequence[Run]) -> "AsymmetricGa":
        seg = build_segments(runs, self.segment_period)
        ident = identify_ga(seg, self.ranges, self.settings)
        other = identify_de(seg, self.ranges) if self.cross_check else None
        return dataclasses.replace(self, params=ident.params, identification=ident, cross_identification=other)

    def estimate(self, run: Run) -> Estimate:
        return dead_reckoning(_require_params(self), run, self.name, _ident_info(self))


@dataclass(frozen=True)
class AsymmetricDe:
    """``mandow2007.asymmetric_de``: as :class:`AsymmetricGa`, K identified by scipy's differential
    evolution (second optimiser beside the published GA)."""

    name: str = "mandow2007.asymmetric_de"
    paper: str = PAPER
    requires: frozenset[str] = frozenset({"enc_wl", "enc_wr"})
    params: IcrParams | None = None
    ranges: GeneRanges | None = None
    settings: DeSettings = DeSettings()
    segment_period: float | None = None
    cross_check: bool = False  # also run the published GA on the same segments (reported only)
    identification: Identification | None = field(default=None, compare=False, repr=False)
    cross_identification: Identification | None = field(default=None, compare=False, repr=False)

    def calibrate(self, runs: Sequence[Run]) -> "AsymmetricDe":
        seg = build_segments(runs, self.segment_period)
        ident = identify_de(seg, self.ranges, self.settings)
        other = identify_ga(seg, self.ranges) if self.cross_check else None
        return dataclasses.replace(self, params=ident.params, identification=ident, cross_identification=other)

    def estimate(self, run: Run) -> Estimate:
        return dead_reckoning(_require_params(self), run, self.name, _ident_info(self))
