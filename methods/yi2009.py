"""Yi et al. 2009: IMU + encoder EKF with skid-steer velocity constraints and slip estimation.

Citation
    J. Yi, H. Wang, J. Zhang, D. Song, S. Jayasuriya, J. Liu, "Kinematic Modeling and Analysis of
    Skid-Steered Mobile Robots With Applications to Low-Cost Inertial-Measurement-Unit-Based Motion
    Estimation", IEEE Transactions on Robotics, vol. 25, no. 5, pp. 1087-1097, Oct. 2009,
    doi:10.1109/TRO.2009.2026506.

Frames and units
    The paper's body frame B is x forward, y left, z up, yaw counter-clockwise (its eqs. (3)-(4)
    put the left wheels at y = +W/2): the same as skidbench, so no axis conversion is needed.
    Euler angles Theta = (phi, theta, psi) are Z-Y-X (eq. (2)).  Everything is SI inside; the
    published S(gamma) coefficient a1 is in cm and is converted only in :meth:`SGamma.from_cm` /
    :attr:`SGamma.a1_cm`; the rpm wheel speeds of the experiments belong to the scenario files.
    The IMU is at the centre of mass (x_M = y_M = 0, Sec. V-A), so eqs. (5), (13) and (15) are
    used with x_M = y_M = 0 and the IMU state is the robot state.

Map: paper equation -> code
    (2)            C_B^I(phi, theta, psi)                       -> :func:`dcm`; inline in :func:`run_filter`
    (3)-(5)        wheel-centre and IMU velocities                -> :func:`run_filter` (slip step)
    (6)            slip lambda_i = (r w_i - v_ix)/(r w_i), clipped to [-1, 1] (Sec. III-A)
                                                                  -> :func:`slip_ratio`; inline in :func:`run_filter`
    (7)            S = -v_Gy / yaw_rate                           -> :func:`reference_s_gamma_point`
    (10a)-(10e)    IMU kinematics (strapdown, Euler rates)        -> :func:`run_filter` (prediction)
    (11)           v_Bz = 0                                       -> measurement row 3
    (12)-(14)      v_Bx from encoders with sign-constrained slip  -> measurement row 1;
                                                                     (14) also as :func:`constrained_slip`
    (15)           v_By = (x_M - S) yaw_rate                      -> measurement row 2 (variant 3)
    (16)-(17)      y = C^T V_I + w                                -> measurement model
    (18)-(19)      X(k) = X(k-1) + dT f(X(k-1), u(k-1))           -> prediction
    (20)-(22)      F = I + dT df/dX, F_Theta, F_V                 -> prediction Jacobian
    (23)-(25)      H = [0, C^T, H_Theta]                          -> measurement Jacobian
    (26a)-(26f)    EKF recursion, Joseph-form covariance (26f)    -> :func:`run_filter`
    (40)           gamma = (v_Lx - v_Rx)/(v_Lx + v_Rx)            -> :func:`gamma_ratio`
    (41)           S(gamma) = a1 / (a2 |gamma| + a3)              -> :class:`SGamma`
    Sec. V-B       nonlinear least-squares fit of (41)            -> :func:`fit_s_gamma`,
                                                                     :meth:`Yi2009Ekf.calibrate`
    Fig. 5         variants 1/2/3                                 -> ``Yi2009Ekf(variant=...)``,
                                                                     :func:`ekf_v1`, :func:`ekf_v2`, :func:`ekf_v3`
    (not Yi's)     consistent configuration (issue 4): sigma_1 of (13) and sigma_2 of (15) identified on
                   calibration runs against the reference sensor   -> :func:`identify_yi_noise`,
                                                                     :func:`reference_body_velocity`,
                                                                     :func:`pseudo_measurements`,
                                                                     :func:`correlated_noise_fit`,
                                                                     :class:`Yi2009EkfConsistent`,
                                                                     :func:`ekf_v1_consistent` .. ``_v3_consistent``

How the paper estimates slip (Sec. III-C, IV-A)
    The state is the 9-vector (P_I, V_I, Theta) of eq. (18): slip is NOT augmented.  Slip is
    computed from the filter's own velocity estimate through (3)-(6) ("the calculation of wheel
    slips depends on the values of the wheel translational velocity estimates", Sec. III-C) and
    fed back into the longitudinal pseudo-measurement (13) after the sign constraint (14).  Here:
    after the update at step k, lambda(k) comes from v_B(k|k) = C^T V(k|k), the Euler yaw rate
    (10e) and the latest encoder speeds; the measurement at step k+1 uses lambda'(k) of (14) with
    the wheel speeds of step k+1.  (Using the prior of the same step instead would make (13)
    equal to the predicted velocity whenever (14) does not clip, i.e. a measurement with zero
    innovation.)  Consequently the slip level is learnt only while wheel speeds change or when
    (14) clips; at constant wheel speed (13) holds the slip ratio, a property of the paper's design.

Measured behaviour of this design (synthetic runs of tests/test_yi2009.py)
    Because (13) with fed-back slip re-measures the filter's own previous velocity, schemes 2 and 3
    have no absolute speed reference except the sign bounds of (14): their speed follows the IMU
    (pitch error -> gravity leakage) inside those bounds, and with a noisy gyro or coarse encoders
    scheme 2 can be worse than scheme 1.  Schemes 1 and 2 leave v_By and the roll angle unobserved;
    on a straight line the roll estimate wanders and the lateral position drifts.  In scheme 3 the
    unanchored speed couples with the attitude corrections of the v_y/v_z rows: even on noise-free
    data a steady turn slowly drifts to the (14) bound (not with roll/pitch frozen, not in scheme 2),
    which biases its slip estimates.  With good sensors and 10 % net slip the ordering of Fig. 5
    (3 <= 2 <= 1) is reproduced on turning paths.

Consistency (issue 4; measured on the yi_* scored paths, results/yi2009/nees_consistency.md)
    The paper configuration is heavily overconfident in velocity: the v_x row (13) is fused at 125 Hz
    as white noise with sigma_1 = r sigma_en (~0.009 m/s), but its real error is a bias with a
    correlation time of seconds (slip ignored in scheme 1; in schemes 2-3 the fed-back slip makes it
    the filter's own previous velocity error, bounded only by (14)), and scheme 3's v_y row (15)
    carries the S(gamma) error, also a slowly varying bias, fused as white with sigma_2 = 0.05 m/s.
    :class:`Yi2009EkfConsistent` runs the SAME :func:`run_filter` with sigma_1 and sigma_2 identified on
    calibration runs (:func:`identify_yi_noise`: residual of the fused pseudo-measurement against the
    reference-derived body velocity, white + AR(1) with the mean kept, correlated part inflated by the
    effective-sample factor (1 + rho)/(1 - rho) at the filter rate, as methods.liu2020.identify_noise).

Variants (Fig. 5, Sec. V-C)
    1: v_x (13) without slip (lambda' = 0) and v_z (11);  2: v_x with slip feedback (13)-(14) and
    v_z;  3: v_x with slip, v_y from (15) with S(gamma) of (41) and gamma of (40) evaluated with the
    fed-back slips, and v_z.

Choices the paper leaves open (documented, parameters in :class:`EkfParams`)
    Q and R values (Q is "a tuning parameter", R = diag(r^2 sigma_en^2, sigma_2^2, sigma_3^2));
    initial state (start pose from ``initial_pose``, the paper starts at the origin; roll/pitch by
    static accelerometer levelling when the wheels are at rest over the first samples, else 0;
    initial velocity from the first encoder pair); slip is set to 0 when r|w| is below
    ``min_wheel_speed`` (eq. (6) is 0/0 at standstill).  The v_z constraint (11) is fused at every
    IMU step; v_x and v_y only at steps with a fresh encoder pair (an encoder sample is fused once,
    at the first IMU step at or after it); a NaN encoder element drops the rows that need it.
    There is no heading measurement in (16), so there is no yaw innovation to wrap: the yaw state is
    wrapped to [-pi, pi) after every step.  The paper's (26b) writes P(k|k-1) on the right-hand
    side; it is P(k-1|k-1).  Its sigma_1^2 = r^2 sigma_en^2 + x_M^2 sigma_psi^2 reduces to
    r^2 sigma_en^2 at x_M = 0.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, replace
from typing import Any, ClassVar, Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike
from scipy.linalg import lapack
from scipy.optimize import least_squares
from scipy.signal import savgol_filter

from bench.registry import Estimate, make_estimate
from bench.run import Run, RunError, reference_position_noise

PAPER = "Yi et al. 2009, IEEE T-RO 25(5):1087-1097"
IMU_CHANNELS = ("imu_ax", "imu_ay", "imu_az", "imu_gx", "imu_gy", "imu_gz")
ENC_CHANNELS = ("enc_wl", "enc_wr")
REF_CHANNELS = ("ref_x", "ref_y", "ref_yaw")


class FilterDivergence(RuntimeError):
    """The EKF failed numerically (innovation covariance not positive definite or a non-finite
    state).  Names the run, the step index and its time."""

    def __init__(self, where: str, step: int, t: float, what: str):
        self.where, self.step, self.t = where, step, t
        super().__init__(f"{where}: Yi 2009 EKF failed at step {step} (t = {t:.6g} s): {what}")


# ------------------------------------------------------------------------------------------
# S(gamma), eq. (41), and its identification (Sec. V-B)
# ------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class SGamma:
    """Longitudinal ICR location model S(gamma) = a1 / (a2 |gamma| + a3), eq. (41); a1 in metres.

    Only the ratios a1/a3 (= S at gamma = 0) and a2/a3 are identifiable: (a1, a2, a3) and
    c (a1, a2, a3) give the same curve for any c != 0."""

    a1: float  # [m]
    a2: float  # [-]
    a3: float  # [-]

    def __post_init__(self) -> None:
        for k in ("a1", "a2", "a3"):
            v = getattr(self, k)
            if not math.isfinite(v):
                raise ValueError(f"SGamma.{k} = {v!r}: must be finite")
        if not (self.a3 > 0 and self.a2 >= 0):
            raise ValueError(f"SGamma(a2={self.a2!r}, a3={self.a3!r}): need a2 >= 0 and a3 > 0 so that "
                             "a2|gamma| + a3 > 0 for every gamma (eq. (41))")

    @classmethod
    def from_cm(cls, a1_cm: float, a2: float, a3: float) -> "SGamma":
        """Build from the paper's units (a1 in cm, Sec. V-B)."""
        return cls(a1_cm / 100.0, a2, a3)

    @property
    def a1_cm(self) -> float:
        return self.a1 * 100.0

    @property
    def s0(self) -> float:
        """S at gamma = 0 (straight driving) [m]: a1 / a3."""
        return self.a1 / self.a3

    @property
    def k(self) -> float:
        """Identifiable shape ratio a2 / a3."""
        return self.a2 / self.a3

    def __call__(self, gamma: ArrayLike) -> np.ndarray:
        """S [m] at gamma (eq. (41)); S -> 0 as |gamma| -> inf (turning on the spot)."""
        g = np.abs(np.asarray(gamma, dtype=float))
        with np.errstate(over="ignore"):
            return self.a1 / (self.a2 * g + self.a3)


PUBLISHED_S_GAMMA = SGamma.from_cm(2.148, 0.249, 0.039)  # Sec. V-B, Fig. 4


@dataclass(frozen=True)
class SGammaFit:
    """Result of :func:`fit_s_gamma`."""

    s_gamma: SGamma
    residual_rms: float  # [m]
    n_points: int
    nfev: int


def fit_s_gamma(gamma: ArrayLike, s: ArrayLike, a3: float = PUBLISHED_S_GAMMA.a3) -> SGammaFit:
    """Fit eq. (41) to points (gamma_i, S_i [m]) by nonlinear least squares (Sec. V-B, Fig. 4).

    Eq. (41) is invariant to scaling (a1, a2, a3) by a common factor, so a3 is held at a
    normalisation value (default: the published 0.039) and (a1, a2) are fitted; the identifiable
    curve does not depend on that choice.  a2 >= 0 keeps the denominator positive; a1 is free in
    sign (the paper has a1 > 0, i.e. the ICR ahead of the centre of mass)."""
    g = np.abs(np.asarray(gamma, dtype=float)).ravel()
    sv = np.asarray(s, dtype=float).ravel()
    if g.shape != sv.shape:
        raise ValueError(f"fit_s_gamma: gamma has {g.size} points, S has {sv.size}")
    bad = ~(np.isfinite(g) & np.isfinite(sv))
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(f"fit_s_gamma: point {i} is not finite (gamma={g[i]!r}, S={sv[i]!r})")
    if np.unique(g).size < 2:
        raise ValueError(f"fit_s_gamma: need points at >= 2 distinct |gamma| to fit (a1, a2); got {np.unique(g)}")
    if not (math.isfinite(a3) and a3 > 0):
        raise ValueError(f"fit_s_gamma: normalisation a3 = {a3!r} must be > 0")

    # Initial guess from the linearised model 1/S = (a2/a1)|gamma| + a3/a1 (if S keeps one sign).
    p0 = np.array([float(np.mean(sv)) * a3, 0.0])
    if np.all(sv > 0) or np.all(sv < 0):
        slope, icpt = np.polyfit(g, 1.0 / sv, 1)
        if icpt != 0 and slope / icpt >= 0:
            a1_0 = a3 / icpt
            p0 = np.array([a1_0, max(slope * a1_0, 0.0)])

    def resid(p: np.ndarray) -> np.ndarray:
        return p[0] / (p[1] * g + a3) - sv

    def jac(p: np.ndarray) -> np.ndarray:
        den = p[1] * g + a3
        return np.column_stack((1.0 / den, -p[0] * g / den**2))

    sol = least_squares(resid, p0, jac=jac, bounds=([-np.inf, 0.0], [np.inf, np.inf]), method="trf",
                        xtol=1e-15, ftol=1e-15, gtol=1e-15, max_nfev=10_000)
    a1, a2 = (float(v) for v in sol.x)
    return SGammaFit(SGamma(a1, a2, float(a3)), float(np.sqrt(np.mean(sol.fun**2))), int(g.size), int(sol.nfev))


def gamma_ratio(v_lx: ArrayLike, v_rx: ArrayLike) -> np.ndarray:
    """gamma = (v_Lx - v_Rx)/(v_Lx + v_Rx), eq. (40); +-inf when v_Lx + v_Rx = 0."""
    v_lx, v_rx = np.asarray(v_lx, float), np.asarray(v_rx, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        return (v_lx - v_rx) / (v_lx + v_rx)


def reference_s_gamma_point(run: Run, track: float, smooth_window: float = 1.0, settle: float = 1.0,
                            min_yaw_rate: float = 0.05) -> tuple[float, float, int] | None:
    """One (gamma, S [m], n_samples) point of Fig. 4 from a run's reference pose (ref_x, ref_y,
    ref_yaw), as the paper does with its vision system: velocities by numerical differentiation
    (Savitzky-Golay over ``smooth_window`` s on a uniform grid), body velocities
    v_G = R(psi)^T [xdot, ydot], then S as the least-squares solution of eq. (7) over the samples
    after ``settle`` s with |yaw rate| >= ``min_yaw_rate``, S = -sum(v_Gy psidot)/sum(psidot^2),
    and gamma the median of eq. (40) with v_Lx, v_Rx from eqs. (3)-(4) (= -W psidot / (2 v_Gx)).
    Returns None when the run does not turn enough (S is 0/0 on a straight line, Remark 1)."""
    d = run.data
    for c in REF_CHANNELS:
        if c not in d.columns:
            raise RunError(run.where, c, None, "missing reference channel needed by the S(gamma) calibration")
    ok = np.isfinite(d["ref_x"].to_numpy()) & np.isfinite(d["ref_y"].to_numpy()) & np.isfinite(d["ref_yaw"].to_numpy())
    tr = run.t[ok]
    if tr.size < 8:
        return None
    rx, ry = d["ref_x"].to_numpy()[ok], d["ref_y"].to_numpy()[ok]
    ryaw = np.unwrap(d["ref_yaw"].to_numpy()[ok])
    h = float(np.median(np.diff(tr)))
    tg = np.arange(tr[0], tr[-1] + 0.5 * h, h)
    xs, ys, yaws = (np.interp(tg, tr, v) for v in (rx, ry, ryaw))
    win = max(5, int(round(smooth_window / h)) | 1)
    if win > tg.size:
        return None
    kw = dict(window_length=win, polyorder=3, delta=h, mode="interp")
    xd, yd = savgol_filter(xs, deriv=1, **kw), savgol_filter(ys, deriv=1, **kw)
    psid = savgol_filter(yaws, deriv=1, **kw)
    psi = savgol_filter(yaws, deriv=0, **kw)
    c, s = np.cos(psi), np.sin(psi)
    v_gx, v_gy = c * xd + s * yd, -s * xd + c * yd
    m = (tg >= tg[0] + settle) & (np.abs(psid) >= min_yaw_rate)
    if m.sum() < max(10, win):
        return None
    s_val = float(-np.sum(v_gy[m] * psid[m]) / np.sum(psid[m] ** 2))  # eq. (7), least squares
    half = 0.5 * track
    gam = gamma_ratio(v_gx[m] - half * psid[m], v_gx[m] + half * psid[m])  # eqs. (3), (4), (40)
    gam = gam[np.isfinite(gam)]
    if gam.size == 0:
        return None
    return float(np.median(gam)), s_val, int(m.sum())


# ------------------------------------------------------------------------------------------
# Kinematic pieces (eqs. (2), (6), (14)) usable on arrays
# ------------------------------------------------------------------------------------------
def dcm(phi: float, theta: float, psi: float) -> np.ndarray:
    """C_B^I of eq. (2) (Z-Y-X Euler angles), body -> inertial."""
    sf, cf, st, ct, sp, cp = math.sin(phi), math.cos(phi), math.sin(theta), math.cos(theta), math.sin(psi), math.cos(psi)
    return np.array([[ct * cp, -sp * cf + cp * sf * st, sf * sp + cp * st * cf],
                     [ct * sp, cf * cp + st * sf * sp, -sf * cp + st * cf * sp],
                     [-st, ct * sf, cf * ct]])


def slip_ratio(wheel_speed: ArrayLike, v_wheel: ArrayLike, wheel_radius: float, min_speed: float = 0.01) -> np.ndarray:
    """lambda = (r w - v_x)/(r w), eq. (6), clipped to [-1, 1] (Sec. III-A); 0 where r|w| < min_speed."""
    rw = wheel_radius * np.asarray(wheel_speed, float)
    v = np.asarray(v_wheel, float)
    ok = np.abs(rw) >= min_speed
    lam = np.where(ok, (rw - v) / np.where(ok, rw, 1.0), 0.0)
    return np.clip(lam, -1.0, 1.0)


def constrained_slip(lam_l: ArrayLike, lam_r: ArrayLike, w_l: ArrayLike, w_r: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """lambda'_L, lambda'_R of eq. (14): the outer (faster) side keeps only traction slip (>= 0),
    the inner side only braking slip (<= 0); both keep traction when w_L = w_R."""
    lam_l, lam_r = np.asarray(lam_l, float), np.asarray(lam_r, float)
    w_l, w_r = np.asarray(w_l, float), np.asarray(w_r, float)
    pl = np.where(w_l >= w_r, np.maximum(lam_l, 0.0), np.minimum(lam_l, 0.0))
    pr = np.where(w_l <= w_r, np.maximum(lam_r, 0.0), np.minimum(lam_r, 0.0))
    return pl, pr


# ------------------------------------------------------------------------------------------
# The EKF (Sec. IV-A)
# ------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class EkfParams:
    """Tuning of the EKF (the paper leaves Q and the sigmas open: Sec. IV-A).

    Q per step: position (pos_noise)^2, velocity (accel_noise * dT)^2, attitude (gyro_noise * dT)^2
    (the accelerometer/gyro white noise per sample integrated over one step).
    R = diag(r^2 sigma_enc^2, sigma_vy^2, sigma_vz^2) (Sec. IV-A)."""

    accel_noise: float = 0.1  # [m/s^2] per sample, incl. unmodelled bias (the paper has no IMU error model)
    gyro_noise: float = 0.01  # [rad/s] per sample
    pos_noise: float = 1e-5  # [m] per step
    sigma_enc: float = 0.1  # sigma_en [rad/s]: wheel-speed noise; sigma_1 = r sigma_en
    sigma_vy: float = 0.05  # sigma_2 [m/s]: error of the S(gamma) lateral velocity (15)
    sigma_vz: float = 0.02  # sigma_3 [m/s]: ground topography (11)
    p0_pos: float = 1e-3  # [m]
    p0_vel: float = 0.05  # [m/s]
    p0_rollpitch: float = 0.02  # [rad]
    p0_yaw: float = 1e-3  # [rad]
    min_wheel_speed: float = 0.01  # [m/s] r|w| below which slip (6) is taken as 0
    level_samples: int = 25  # IMU samples for static levelling (if the wheels are at rest)
    gravity: float = 9.81  # [m/s^2], G = [0, 0, -g] (eq. (10b))

    def __post_init__(self) -> None:
        for k, v in asdict(self).items():
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise ValueError(f"EkfParams.{k} = {v!r}: must be finite and >= 0")
        if self.gravity <= 0:
            raise ValueError(f"EkfParams.gravity = {self.gravity!r}: must be > 0")


@dataclass(frozen=True)
class FilterResult:
    """Per-step output of :func:`run_filter` (arrays over the IMU steps)."""

    t: np.ndarray  # (n,)
    state: np.ndarray  # (n, 9): P_I (3), V_I (3), (phi, theta, psi)
    v_body: np.ndarray  # (n, 3) C^T V_I (eq. (16))
    yaw_rate: np.ndarray  # (n,) Euler yaw rate, eq. (10e)
    slip: np.ndarray  # (n, 2) lambda_L, lambda_R from the posterior (eq. (6)); NaN before the first encoder sample
    s_icr: np.ndarray  # (n,) S(gamma) used in (15) (variant 3), NaN otherwise
    n_updates: tuple[int, int, int]  # fused v_x, v_y, v_z rows
    cov: np.ndarray | None = None  # (n, 9, 9) if requested


def run_filter(t: np.ndarray, acc: np.ndarray, gyr: np.ndarray, enc: np.ndarray, *, wheel_radius: float,
               track: float, variant: int, s_gamma: SGamma, params: EkfParams, x0: np.ndarray,
               p0: np.ndarray, store_cov: bool = False, where: str = "run") -> FilterResult:
    """Run the EKF (26a)-(26f) over IMU steps.

    ``t`` (n,), ``acc`` (n, 3) specific force [m/s^2], ``gyr`` (n, 3) [rad/s] in B; ``enc`` (n, 2)
    wheel speeds [rad/s] of a fresh encoder pair at each step or NaN (dropped).  ``x0`` (9,),
    ``p0`` (9, 9).  Step k predicts with u(k-1) over t[k] - t[k-1] (eq. (18)) and then fuses the
    measurement rows available at k (R is diagonal, so dropping a row drops that element only).
    Raises :class:`FilterDivergence` with the step index when the innovation covariance is not
    positive definite (Cholesky, LAPACK dpotrf) or the state becomes non-finite."""
    if variant not in (1, 2, 3):
        raise ValueError(f"variant = {variant!r}: must be 1, 2 or 3 (Fig. 5)")
    n = int(t.size)
    r, hw = float(wheel_radius), 0.5 * float(track)
    use_slip, use_vy = variant >= 2, variant == 3
    a1, a2, a3 = s_gamma.a1, s_gamma.a2, s_gamma.a3
    g = params.gravity
    vmin = params.min_wheel_speed
    q_const = np.array([params.pos_noise**2] * 3 + [0.0] * 6)  # per step
    q_dt2 = np.array([0.0] * 3 + [params.accel_noise**2] * 3 + [params.gyro_noise**2] * 3)  # times dT^2
    r_all = ((r * params.sigma_enc) ** 2, params.sigma_vy**2, params.sigma_vz**2)
    # measurement rows fused when an encoder pair is fresh / not (v_z (11) is always available)
    rows_enc = (0, 1, 2) if use_vy else (0, 2)
    r_mat = {rows: np.diag([r_all[i] for i in rows]) for rows in (rows_enc, (2,))}
    r_vec = {rows: np.array([r_all[i] for i in rows]) for rows in (rows_enc, (2,))}

    t_l = t.tolist()
    acc_l = acc.tolist()
    gyr_l = gyr.tolist()
    enc_l = enc.tolist()
    enc_ok = np.isfinite(enc).all(axis=1).tolist()

    out: list[tuple[float, ...]] = []
    covs: list[np.ndarray] = []
    I9 = np.eye(9)
    f_tmpl = np.eye(9).ravel().tolist()
    P = np.array(p0, dtype=float, copy=True)
    px, py, pz, vx, vy, vz, phi, th, psi = (float(v) for v in x0)
    lam_l = lam_r = 0.0
    w_l = w_r = math.nan  # latest encoder pair (held for the slip output)
    s_cur = math.nan  # S(gamma) of the latest v_y row (variant 3)
    if enc_ok[0]:
        w_l, w_r = enc_l[0]
        den = r * (w_l + w_r)
        s_cur = a1 / (a2 * abs(r * (w_l - w_r) / den) + a3) if abs(den) > 1e-9 else 0.0  # (40)-(41), lambda = 0
    nx = ny = nz = 0
    two_pi = 2.0 * math.pi
    dt_last, Qk = -1.0, np.zeros((9, 9))
    potrf, potrs = lapack.dpotrf, lapack.dpotrs

    for k in range(n):
        gx, gy, gz = gyr_l[k]
        if k > 0:
            # ---------------- prediction (26a)-(26b) with u(k-1), from X(k-1|k-1) -------
            # (sf..cp, c11..c33 hold the trigonometry/DCM (2) of the posterior of step k-1)
            dt = t_l[k] - t_l[k - 1]
            ax, ay, az = acc_l[k - 1]
            ux, uy, uz = gyr_l[k - 1]
            vdx = c11 * ax + c12 * ay + c13 * az  # eq. (10b): C A_B + G
            vdy = c21 * ax + c22 * ay + c23 * az
            c3a = c31 * ax + c32 * ay + c33 * az
            tt = st / ct
            qy = sf * uy + cf * uz
            phid = ux + tt * qy  # eq. (10c)
            thd = cf * uy - sf * uz  # eq. (10d)
            psid = qy / ct  # eq. (10e)
            # F (20) with F_V (22) in rows 3-5 / cols 6-8 and I + dT F_Theta in rows/cols 6-8
            fl = f_tmpl.copy()
            fl[3] = fl[13] = fl[23] = dt
            fl[33], fl[34], fl[35] = dt * (c13 * ay - c12 * az), dt * cp * c3a, -dt * vdy
            fl[42], fl[43], fl[44] = dt * (c23 * ay - c22 * az), dt * sp * c3a, dt * vdx
            fl[51], fl[52] = dt * (c33 * ay - c32 * az), dt * (-ct * ax - st * sf * ay - st * cf * az)
            fl[60], fl[61] = 1.0 + dt * thd * tt, dt * psid / ct
            fl[69] = -dt * psid * ct
            fl[78], fl[79] = dt * thd / ct, dt * psid * tt
            F = np.array(fl).reshape(9, 9)
            px += dt * vx
            py += dt * vy
            pz += dt * vz
            vx += dt * vdx
            vy += dt * vdy
            vz += dt * (c3a - g)
            phi += dt * phid
            th += dt * thd
            psi += dt * psid
            if abs(dt - dt_last) > 1e-9 * dt:  # Q(k) for this dT (recomputed when dT changes)
                Qk, dt_last = np.diag(q_const + q_dt2 * (dt * dt)), dt
            P = F @ P @ F.T + Qk

            # ---------------- measurement (11)-(16) at the prior --------------------------
            sf, cf, st, ct = math.sin(phi), math.cos(phi), math.sin(th), math.cos(th)
            sp, cp = math.sin(psi), math.cos(psi)
            c11, c12, c13 = ct * cp, -sp * cf + cp * sf * st, sf * sp + cp * st * cf
            c21, c22, c23 = ct * sp, cf * cp + st * sf * sp, -sf * cp + st * cf * sp
            c31, c32, c33 = -st, ct * sf, cf * ct
            vbx = c11 * vx + c21 * vy + c31 * vz  # h = C^T V_I (16)
            vby = c12 * vx + c22 * vy + c32 * vz
            vbz = c13 * vx + c23 * vy + c33 * vz
            # H = [0, C^T, H_Theta] (23)-(25), one row per element
            h_x = (0.0, 0.0, 0.0, c11, c21, c31, 0.0, -st * cp * vx - st * sp * vy - ct * vz, c11 * vy - c21 * vx)
            h_z = (0.0, 0.0, 0.0, c13, c23, c33, -vby, cf * vbx, c13 * vy - c23 * vx)
            if enc_ok[k]:
                w_l, w_r = enc_l[k]
                if use_slip:  # eq. (14) on the slips of step k-1, signs from the current wheel speeds
                    pl = (lam_l if lam_l > 0.0 else 0.0) if w_l >= w_r else (lam_l if lam_l < 0.0 else 0.0)
                    pr = (lam_r if lam_r > 0.0 else 0.0) if w_l <= w_r else (lam_r if lam_r < 0.0 else 0.0)
                else:
                    pl = pr = 0.0
                y_x = 0.5 * r * ((w_l + w_r) - (pl * w_l + pr * w_r))  # eq. (13), y_M = 0
                if use_vy:
                    v_lx, v_rx = (1.0 - pl) * r * w_l, (1.0 - pr) * r * w_r
                    den = v_lx + v_rx
                    s_cur = a1 / (a2 * abs((v_lx - v_rx) / den) + a3) if abs(den) > 1e-9 else 0.0  # (40), (41)
                    y_y = -s_cur * (sf * gy + cf * gz) / ct  # eq. (15), x_M = 0, yaw rate (10e)
                    h_y = (0.0, 0.0, 0.0, c12, c22, c32, vbz, sf * vbx, c12 * vy - c22 * vx)
                    H = np.array((h_x, h_y, h_z))
                    innov = np.array((y_x - vbx, y_y - vby, -vbz))  # v_Bz = 0 (11)
                else:
                    H = np.array((h_x, h_z))
                    innov = np.array((y_x - vbx, -vbz))
                rows = rows_enc
                nx += 1
                ny += use_vy
            else:
                H = np.array((h_z,))
                innov = np.array((-vbz,))
                rows = (2,)
            nz += 1
            # ---------------- correction (26c)-(26f) ------------------------------------
            PHt = P @ H.T
            S = H @ PHt + r_mat[rows]  # (26e)
            L, info = potrf(S, lower=1)
            d = L.diagonal().tolist()
            if info != 0 or not (all(v > 0.0 for v in d) and math.isfinite(sum(d))):
                raise FilterDivergence(where, k, t_l[k], f"innovation covariance S (26e) not positive definite: {S.tolist()}")
            K = potrs(L, PHt.T, lower=1)[0].T  # (26d): W = P H^T S^-1
            IKH = I9 - K @ H
            P = IKH @ P @ IKH.T + (K * r_vec[rows]) @ K.T  # Joseph form (26f)
            P = 0.5 * (P + P.T)
            dx = (K @ innov).tolist()  # (26c)
            px += dx[0]
            py += dx[1]
            pz += dx[2]
            vx += dx[3]
            vy += dx[4]
            vz += dx[5]
            phi += dx[6]
            th += dx[7]
            psi += dx[8]
            if not math.isfinite(px + py + pz + vx + vy + vz + phi + th + psi):
                raise FilterDivergence(where, k, t_l[k], "non-finite state after the update")
            psi = (psi + math.pi) % two_pi - math.pi  # wrap the yaw state

        # ---------------- posterior DCM (2); slip from the posterior velocity, (3)-(6) ------
        sf, cf, st, ct = math.sin(phi), math.cos(phi), math.sin(th), math.cos(th)
        sp, cp = math.sin(psi), math.cos(psi)
        c11, c12, c13 = ct * cp, -sp * cf + cp * sf * st, sf * sp + cp * st * cf
        c21, c22, c23 = ct * sp, cf * cp + st * sf * sp, -sf * cp + st * cf * sp
        c31, c32, c33 = -st, ct * sf, cf * ct
        vbx = c11 * vx + c21 * vy + c31 * vz
        vby = c12 * vx + c22 * vy + c32 * vz
        vbz = c13 * vx + c23 * vy + c33 * vz
        psid = (sf * gy + cf * gz) / ct  # eq. (10e)
        if w_l == w_l:  # an encoder pair has been seen
            rwl, rwr = r * w_l, r * w_r
            lam_l = min(1.0, max(-1.0, (rwl - (vbx - hw * psid)) / rwl)) if abs(rwl) >= vmin else 0.0
            lam_r = min(1.0, max(-1.0, (rwr - (vbx + hw * psid)) / rwr)) if abs(rwr) >= vmin else 0.0
            sl_l, sl_r = lam_l, lam_r
        else:
            sl_l = sl_r = math.nan
        out.append((px, py, pz, vx, vy, vz, phi, th, psi, vbx, vby, vbz, psid, sl_l, sl_r, s_cur))
        if store_cov:
            covs.append(P)

    o = np.array(out, dtype=float).reshape(n, 16)
    s_icr = o[:, 15] if use_vy else np.full(n, np.nan)
    return FilterResult(t.copy(), o[:, :9], o[:, 9:12], o[:, 12], o[:, 13:15], s_icr, (nx, ny, nz),
                        np.array(covs) if store_cov else None)


# ------------------------------------------------------------------------------------------
# Run boundary
# ------------------------------------------------------------------------------------------
def _geometry(run: Run) -> tuple[float, float]:
    plat = run.meta.get("platform")
    if not isinstance(plat, Mapping):
        raise RunError(run.where, "meta.platform", plat, "Yi 2009 EKF needs the platform geometry (wheel_radius, track)")
    out = []
    for key in ("wheel_radius", "track"):
        v = plat.get(key)
        if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
            raise RunError(run.where, f"meta.platform.{key}", v, "must be a positive number [m]")
        out.append(float(v))
    return out[0], out[1]


def align_inputs(run: Run) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """IMU steps and the encoder pair fused at each of them.

    Filter steps are the rows with a complete IMU sample (the EKF runs at the IMU rate, Sec. V-A).
    An encoder row with both wheels finite is fused at the first IMU step at or after it (the
    latest one if several fall between two steps); a step without a fresh pair gets NaN."""
    d = run.data
    imu = np.column_stack([d[c].to_numpy(dtype=float) for c in IMU_CHANNELS])
    rows = np.flatnonzero(np.isfinite(imu).all(axis=1))
    if rows.size == 0:
        raise RunError(run.where, "imu_*", "no complete sample", "Yi 2009 EKF needs at least one IMU sample")
    t = run.t[rows]
    if not np.all(np.isfinite(t)):
        i = int(rows[np.flatnonzero(~np.isfinite(t))[0]])
        raise RunError(run.where, "t", f"row {i}: {run.t[i]}", "time must be finite")
    bad = np.flatnonzero(np.diff(t) <= 0)
    if bad.size:
        i = int(rows[bad[0] + 1])
        raise RunError(run.where, "t", f"row {i}: {run.t[i]!r}", "time must increase strictly at the IMU samples")
    wl, wr = d["enc_wl"].to_numpy(dtype=float), d["enc_wr"].to_numpy(dtype=float)
    erows = np.flatnonzero(np.isfinite(wl) & np.isfinite(wr))
    j = np.searchsorted(erows, rows, side="right") - 1  # latest encoder row <= each IMU row
    prev = np.concatenate(([-1], rows[:-1]))
    jj = np.maximum(j, 0)
    fresh = (j >= 0) & (erows[jj] > prev) if erows.size else np.zeros(rows.size, bool)
    enc = np.full((rows.size, 2), np.nan)
    if erows.size:
        src = erows[jj[fresh]]
        enc[fresh, 0], enc[fresh, 1] = wl[src], wr[src]
    return t, imu[rows, :3], imu[rows, 3:], enc


def initial_state(acc: np.ndarray, enc: np.ndarray, wheel_radius: float, params: EkfParams,
                  pose: tuple[float, float, float]) -> tuple[np.ndarray, np.ndarray]:
    """x0 and P0 (the paper does not specify them; see the module docstring)."""
    n = min(params.level_samples, acc.shape[0])
    phi = th = 0.0
    if n > 0:
        we = enc[:n][np.isfinite(enc[:n]).all(axis=1)]
        if we.size and np.all(wheel_radius * np.abs(we) < params.min_wheel_speed):  # at rest: level
            a = acc[:n].mean(axis=0)
            phi = math.atan2(a[1], a[2])
            th = math.atan2(-a[0], math.hypot(a[1], a[2]))
    first = np.flatnonzero(np.isfinite(enc).all(axis=1))
    v_b = np.zeros(3)
    if first.size and first[0] == 0:
        v_b[0] = 0.5 * wheel_radius * float(enc[0, 0] + enc[0, 1])
    v_i = dcm(phi, th, pose[2]) @ v_b
    x0 = np.array([pose[0], pose[1], 0.0, *v_i, phi, th, pose[2]])
    p0 = np.diag([params.p0_pos**2] * 3 + [params.p0_vel**2] * 3 + [params.p0_rollpitch**2] * 2 + [params.p0_yaw**2])
    return x0, p0


@dataclass(frozen=True)
class Yi2009Ekf:
    """skidbench plugin for Yi 2009's EKF (Sec. IV-A), variant 1, 2 or 3 of Fig. 5.

    ``estimate`` returns, at each IMU sample: x, y, yaw (state P_I, psi), vx, vy (C^T V_I), wz (Euler
    yaw rate (10e)), slip_l, slip_r (eq. (6) from the posterior), x_icr (S of (41) used in (15),
    variant 3 only) and the extra columns z, vz, roll, pitch (Fig. 8).  Geometry (wheel_radius,
    track = W) from ``run.meta["platform"]``.  With ``store_covariance=True`` the posterior covariance
    of (26f) at every step is ``info["P"]`` (n, 9, 9) (used by the stress tests, bench/stress.py)."""

    variant: int = 3
    s_gamma: SGamma = PUBLISHED_S_GAMMA
    params: EkfParams = field(default_factory=EkfParams)
    initial_pose: tuple[float, float, float] = (0.0, 0.0, 0.0)  # the paper starts at the origin
    calibration: SGammaFit | None = None
    calibration_points: tuple[tuple[str, float, float], ...] = ()  # (run id, gamma, S [m])
    store_covariance: bool = False  # info["P"]: (n, 9, 9) posterior covariance per step (stress tests)

    paper: ClassVar[str] = PAPER
    requires: ClassVar[frozenset[str]] = frozenset(ENC_CHANNELS + IMU_CHANNELS)

    def __post_init__(self) -> None:
        if self.variant not in (1, 2, 3):
            raise ValueError(f"Yi2009Ekf.variant = {self.variant!r}: must be 1, 2 or 3 (Fig. 5)")

    @property
    def name(self) -> str:
        return f"yi2009.ekf_v{self.variant}"

    @property
    def calibration_requires(self) -> frozenset[str]:
        """Reference channels read by :meth:`calibrate` (only variant 3 uses S(gamma))."""
        return frozenset(REF_CHANNELS) if self.variant == 3 else frozenset()

    def calibrate(self, runs: Sequence[Run]) -> "Yi2009Ekf":
        """Identify S(gamma) (41) from reference-sensor runs (Sec. V-B: 11 runs, Fig. 4).

        Variants 1 and 2 do not use S and are returned unchanged."""
        if self.variant != 3:
            return replace(self)
        pts, skipped = [], []
        for run in runs:
            _, track = _geometry(run)
            p = reference_s_gamma_point(run, track)
            (pts.append((run.id, p[0], p[1])) if p is not None else skipped.append(run.id))
        gam = np.array([p[1] for p in pts])
        if np.unique(np.abs(gam)).size < 2:
            raise RunError(", ".join(r.id for r in runs) or "(no runs)", "ref_yaw", f"{len(pts)} turning runs",
                           "S(gamma) calibration (eq. (41)) needs >= 2 turning runs at distinct gamma "
                           f"(runs without enough yaw rate: {skipped})")
        fit = fit_s_gamma(gam, [p[2] for p in pts])
        return replace(self, s_gamma=fit.s_gamma, calibration=fit, calibration_points=tuple(pts))

    def estimate(self, run: Run) -> Estimate:
        run.require(self.requires, self.name)
        r, track = _geometry(run)
        t, acc, gyr, enc = align_inputs(run)
        x0, p0 = initial_state(acc, enc, r, self.params, self.initial_pose)
        res = run_filter(t, acc, gyr, enc, wheel_radius=r, track=track, variant=self.variant, s_gamma=self.s_gamma,
                         params=self.params, x0=x0, p0=p0, store_cov=self.store_covariance, where=run.where)
        st = res.state
        cols: dict[str, np.ndarray] = dict(
            t=res.t, x=st[:, 0], y=st[:, 1], yaw=st[:, 8], vx=res.v_body[:, 0], vy=res.v_body[:, 1],
            wz=res.yaw_rate, slip_l=res.slip[:, 0], slip_r=res.slip[:, 1],
            z=st[:, 2], vz=res.v_body[:, 2], roll=st[:, 6], pitch=st[:, 7],
        )
        if self.variant == 3:
            cols["x_icr"] = res.s_icr
        info: dict[str, Any] = dict(
            variant=self.variant, paper=PAPER, wheel_radius=r, track=track,
            s_gamma=dict(a1_m=self.s_gamma.a1, a1_cm=self.s_gamma.a1_cm, a2=self.s_gamma.a2, a3=self.s_gamma.a3),
            params=asdict(self.params), n_steps=int(t.size), n_updates=dict(zip(("vx", "vy", "vz"), res.n_updates)),
            n_encoder_steps=int(np.isfinite(enc).all(axis=1).sum()), initial_state=x0.tolist(),
        )
        if self.calibration is not None:
            info["calibration"] = dict(points=list(self.calibration_points), residual_rms=self.calibration.residual_rms)
        if res.cov is not None:
            info["P"] = res.cov  # state order (P_I, V_I, phi, theta, psi), as FilterResult.state
        return make_estimate(self.name, info, **cols)


def ekf_v1(**kwargs: Any) -> Yi2009Ekf:
    """Fig. 5 scheme 1: v_x (13) without slip + v_z (11)."""
    return Yi2009Ekf(variant=1, **kwargs)


def ekf_v2(**kwargs: Any) -> Yi2009Ekf:
    """Fig. 5 scheme 2: v_x with slip feedback (13)-(14) + v_z (11)."""
    return Yi2009Ekf(variant=2, **kwargs)


def ekf_v3(**kwargs: Any) -> Yi2009Ekf:
    """Fig. 5 scheme 3: v_x with slip, v_y (15) with S(gamma) (41), v_z (11)."""
    return Yi2009Ekf(variant=3, **kwargs)


# ------------------------------------------------------------------------------------------
# Consistent configuration (not in the paper): measurement noise identified on calibration runs
# ------------------------------------------------------------------------------------------
def reference_body_velocity(run: Run, t: np.ndarray, window: float = 1.0, polyorder: int = 2
                            ) -> tuple[np.ndarray, np.ndarray, float]:
    """Body velocity (v_x, v_y) [m/s] at times ``t`` from the reference pose (ref_x, ref_y, ref_yaw),
    by Savitzky-Golay differentiation over ``window`` s (local polynomial of ``polyorder``) on the
    reference's own uniform grid, divided by the filter's gain on a turn at the smoothed yaw rate (exact
    for a steady turn), rotated by the smoothed reference yaw; NaN outside the reference span.
    Also returns the variance of the derivative's noise per axis, pos_noise^2 sum(c_k^2) with the
    filter's derivative coefficients c_k and ``meta.platform.sensors.reference.pos_noise`` (0 if absent)."""
    from scipy.signal import savgol_coeffs

    d = run.data
    for c in REF_CHANNELS:
        if c not in d.columns:
            raise RunError(run.where, c, None, "missing reference channel needed by the noise identification")
    ok = np.isfinite(d["ref_x"].to_numpy()) & np.isfinite(d["ref_y"].to_numpy()) & np.isfinite(d["ref_yaw"].to_numpy())
    tr = run.t[ok]
    h = float(np.median(np.diff(tr))) if tr.size > 1 else math.nan
    win = max(polyorder + 2, int(round(window / h)) | 1) if math.isfinite(h) else 0
    if tr.size < max(win, 8):
        raise RunError(run.where, "ref_x", f"{tr.size} samples", f"too few reference samples for a {window} s derivative")
    tg = np.arange(tr[0], tr[-1] + 0.5 * h, h)
    xs, ys, yaws = (np.interp(tg, tr, v) for v in (d["ref_x"].to_numpy()[ok], d["ref_y"].to_numpy()[ok],
                                                  np.unwrap(d["ref_yaw"].to_numpy()[ok])))
    kw = dict(window_length=win, polyorder=polyorder, delta=h, mode="interp")
    xd, yd = savgol_filter(xs, deriv=1, **kw), savgol_filter(ys, deriv=1, **kw)
    psi = savgol_filter(yaws, deriv=0, **kw)
    psid = savgol_filter(yaws, deriv=1, **kw)
    # On a turn at yaw rate w the derivative filter returns gain(w) = sum_k c_k sin(w t_k) / w of the
    # true velocity (antisymmetric c_k: no phase shift; ~2.5 % low at 1 rad/s over 1 s): divide it out.
    coef = savgol_coeffs(win, polyorder, deriv=1, delta=h, use="dot")
    tk = (np.arange(win) - win // 2) * h
    w = np.where(np.abs(psid) > 1e-6, psid, 1e-6)
    gain = (np.sin(np.outer(w, tk)) @ coef) / w
    c, s = np.cos(psi), np.sin(psi)
    vx, vy = (c * xd + s * yd) / gain, (-s * xd + c * yd) / gain
    var = reference_position_noise(run) ** 2 * float(np.sum(coef**2))
    inside = (t >= tg[0]) & (t <= tg[-1])
    return (np.where(inside, np.interp(t, tg, vx), np.nan), np.where(inside, np.interp(t, tg, vy), np.nan), var)


def pseudo_measurements(est_slip: np.ndarray, s_icr: np.ndarray, yaw_rate: np.ndarray, enc: np.ndarray,
                        wheel_radius: float, variant: int) -> tuple[np.ndarray, np.ndarray]:
    """The v_x (13) and v_y (15) pseudo-measurements the filter fused at each step, rebuilt from its
    output: slip lambda(k-1) (posterior of the previous step, eq. (6)) constrained by (14) with the
    wheel speeds of step k; v_y = -S yaw_rate (15) with the S(gamma) of the step (variant 3, else NaN).
    (The yaw rate here is the posterior's (10e); the filter uses the prior's attitude: same gyro sample.)"""
    lam = np.vstack((np.zeros((1, 2)), np.nan_to_num(est_slip[:-1])))
    wl, wr = enc[:, 0], enc[:, 1]
    if variant >= 2:
        pl, pr = constrained_slip(lam[:, 0], lam[:, 1], wl, wr)
    else:
        pl = pr = np.zeros(wl.size)
    y_x = 0.5 * wheel_radius * (wl * (1.0 - pl) + wr * (1.0 - pr))
    y_y = -s_icr * yaw_rate if variant == 3 else np.full(wl.size, np.nan)
    return y_x, y_y


def correlated_noise_fit(res: Sequence[np.ndarray], lag: int) -> tuple[float, float, float]:
    """(white variance, correlated variance s_c^2, lag-1 correlation rho) of residuals modelled as
    white + AR(1) WITHOUT removing their mean: a bias is an error the filter must cover, and it is
    the limit rho -> 1 of the AR(1).  Autocovariances pooled over the runs: C(k) = s_c^2 rho^k for
    k >= 1, so rho = (C(lag)/C(1))^(1/(lag - 1)) and s_c^2 = C(1)/rho; white = C(0) - s_c^2."""
    if lag < 2:
        raise ValueError(f"correlated_noise_fit: lag = {lag} must be >= 2")
    c = np.zeros(3)
    n = 0
    for e in res:
        e = np.asarray(e, float)
        if e.size <= lag:
            continue
        c += (float(e @ e), float(e[1:] @ e[:-1]), float(e[lag:] @ e[:-lag]))
        n += e.size
    if n == 0:
        raise ValueError(f"correlated_noise_fit: no residual longer than lag {lag}")
    c0, c1, cl = c / n
    if not (c1 > 0 and cl > 0):
        return c0, 0.0, 0.0
    rho = min((cl / c1) ** (1.0 / (lag - 1)), 1.0 - 1e-9)
    sc2 = min(c1 / rho, c0)
    return c0 - sc2, sc2, rho


@dataclass(frozen=True)
class YiNoise:
    """Identified noise of one pseudo-measurement row (:func:`identify_yi_noise`)."""

    white_var: float  # [m^2/s^2]
    corr_var: float  # [m^2/s^2] correlated part incl. bias^2, minus the reference derivative's noise
    rho_step: float  # correlation over one filter step
    factor: float  # (1 + rho)/(1 - rho)
    bias: float  # [m/s] mean residual (part of corr_var)
    sigma: float  # [m/s] fused standard deviation, sqrt(white + corr * factor)

    @property
    def corr_time(self) -> float:
        """Correlation time in filter steps (-1/ln rho)."""
        return -1.0 / math.log(self.rho_step) if 0.0 < self.rho_step < 1.0 else 0.0


def identify_yi_noise(runs: Sequence[Run], model: "Yi2009Ekf", settle: float = 1.0, lag_time: float = 0.5,
                      iterations: int = 2, max_factor: float = 1e6) -> tuple[EkfParams, dict[str, Any]]:
    """Measurement noise of the v_x (13) and v_y (15) rows identified on calibration runs against the
    reference sensor (never the truth), for the consistent configuration.

    The filter ``model`` is run on each run; the pseudo-measurements it fused (:func:`pseudo_measurements`)
    are compared with the reference body velocity (:func:`reference_body_velocity`) at the steps with a
    fresh encoder pair after ``settle`` s.  The residual is split into white + AR(1) with its mean kept
    (:func:`correlated_noise_fit`, correlation from lags 1 and ``lag_time``); the correlated part
    (minus the reference derivative's own noise) is fused at the filter rate with the effective-sample
    factor (1 + rho)/(1 - rho) (capped at ``max_factor``): n correlated samples carry the information
    of n (1 - rho)/(1 + rho) independent ones.  Repeated ``iterations`` times with the identified noise
    (slip feedback (13)-(14) depends on the filter's own velocity, so the residual depends on R).
    sigma_vz (11) is kept (the reference is planar: no v_z reference)."""
    if not runs:
        raise ValueError(f"{model.name}: identify_yi_noise needs at least one calibration run")
    if iterations < 1:
        raise ValueError(f"{model.name}: identify_yi_noise iterations = {iterations!r}: must be >= 1")
    params = model.params
    info: dict[str, Any] = {"calibration_runs": [r.id for r in runs]}
    for it in range(iterations):
        res_x: list[np.ndarray] = []
        res_y: list[np.ndarray] = []
        ref_var, dts = [], []
        for run in runs:
            run.require(model.requires | frozenset(REF_CHANNELS), f"{model.name} (calibration)")
            r, track = _geometry(run)
            t, acc, gyr, enc = align_inputs(run)
            x0, p0 = initial_state(acc, enc, r, params, model.initial_pose)
            fr = run_filter(t, acc, gyr, enc, wheel_radius=r, track=track, variant=model.variant,
                            s_gamma=model.s_gamma, params=params, x0=x0, p0=p0, where=run.where)
            y_x, y_y = pseudo_measurements(fr.slip, fr.s_icr, fr.yaw_rate, enc, r, model.variant)
            vx, vy, var = reference_body_velocity(run, t)
            m = np.isfinite(enc).all(axis=1) & (t >= t[0] + settle) & np.isfinite(vx)
            res_x.append(y_x[m] - vx[m])
            if model.variant == 3:
                res_y.append(y_y[m] - vy[m])
            ref_var.append(var)
            dts.append(float(np.median(np.diff(t))))
        dt = float(np.median(dts))
        lag = max(2, int(round(lag_time / dt)))
        vref = float(np.mean(ref_var))
        rows: dict[str, YiNoise] = {}
        for key, res in (("vx", res_x), ("vy", res_y)):
            if not res:
                continue
            white, corr, rho = correlated_noise_fit(res, lag)
            corr = max(corr - vref, 0.0)
            factor = min((1.0 + rho) / (1.0 - rho), max_factor) if rho > 0 else 1.0
            bias = float(np.mean(np.concatenate(res)))
            rows[key] = YiNoise(white, corr, rho, factor, bias, math.sqrt(max(white + corr * factor, 1e-12)))
        r0 = _geometry(runs[0])[0]
        params = replace(params, sigma_enc=rows["vx"].sigma / r0,
                         sigma_vy=rows["vy"].sigma if "vy" in rows else params.sigma_vy)
        info[f"iteration{it}"] = {k: asdict(v) | {"corr_time_s": v.corr_time * dt} for k, v in rows.items()}
    info.update({"sigma_enc": params.sigma_enc, "sigma_1": params.sigma_enc * _geometry(runs[0])[0],
                 "sigma_vy": params.sigma_vy, "sigma_vz": params.sigma_vz, "reference_velocity_var": vref, "filter_dt": dt})
    return params, info


@dataclass(frozen=True)
class Yi2009EkfConsistent(Yi2009Ekf):
    """Yi's EKF scheme 1/2/3 in a consistent configuration (NOT the paper's; issue 4): the same filter
    (:func:`run_filter`, unchanged) with sigma_1 (v_x row, (13)) and sigma_2 (v_y row, (15)) identified on
    calibration runs by :func:`identify_yi_noise`; scheme 3 also fits S(gamma) on them as the paper does.
    Process noise, sigma_3 (v_z, (11)) and the initial covariance are the paper configuration's."""

    calibrated: bool = False
    noise_info: Mapping[str, Any] = field(default_factory=dict, compare=False)

    @property
    def name(self) -> str:
        return f"yi2009.ekf_v{self.variant}_consistent"

    @property
    def calibration_requires(self) -> frozenset[str]:
        return frozenset(REF_CHANNELS)

    def calibrate(self, runs: Sequence[Run]) -> "Yi2009EkfConsistent":
        m = super().calibrate(runs)
        params, info = identify_yi_noise(runs, m)
        return replace(m, params=params, calibrated=True, noise_info=info)

    def estimate(self, run: Run) -> Estimate:
        if not self.calibrated:
            raise RunError(run.where, "calibration", "none", f"{self.name} identifies its measurement noise on "
                           "calibration runs with a reference sensor (ref_x, ref_y, ref_yaw): call calibrate first")
        est = super().estimate(run)
        est.info["noise"] = {k: v for k, v in self.noise_info.items() if isinstance(v, (int, float))}
        return est


def ekf_v1_consistent(**kwargs: Any) -> Yi2009EkfConsistent:
    """Scheme 1 with the measurement noise identified on calibration runs (not the paper's)."""
    return Yi2009EkfConsistent(variant=1, **kwargs)


def ekf_v2_consistent(**kwargs: Any) -> Yi2009EkfConsistent:
    """Scheme 2 with the measurement noise identified on calibration runs (not the paper's)."""
    return Yi2009EkfConsistent(variant=2, **kwargs)


def ekf_v3_consistent(**kwargs: Any) -> Yi2009EkfConsistent:
    """Scheme 3 with S(gamma) and the measurement noise identified on calibration runs (not the paper's)."""
    return Yi2009EkfConsistent(variant=3, **kwargs)
