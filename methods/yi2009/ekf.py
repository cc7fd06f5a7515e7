"""The EKF of Yi 2009 Sec. IV-A as the paper defines it (the 9 states, white R) and its skidbench plugin.

Equations: C_B^I of eq. (2) (:func:`dcm`); the strapdown prediction (10), (18)-(22), the measurement rows (11),
(13)-(14) and, in scheme 3, (15) with S(gamma) (40)-(41), the measurement model (16)-(17), (23)-(25) and the
recursion (26a)-(26f) (:func:`run_filter`: the one EKF loop, :func:`methods.yi2009.consistent.filter.run_filter_gm`,
without error states and with its default options, i.e. Yi's rows); the run boundary (:func:`align_inputs`,
:func:`initial_state`); the plugin :class:`Yi2009Ekf` with the three schemes of Fig. 5 (:func:`ekf_v1`,
:func:`ekf_v2`, :func:`ekf_v3`), whose :meth:`Yi2009Ekf.calibrate` fits S(gamma) (41) as in Sec. V-B and whose
:meth:`Yi2009Ekf.window_models` are Yi's kinematics on real-data windows (:mod:`methods.yi2009.windows`).

How the paper estimates slip (Sec. III-C, IV-A)
    The state is the 9-vector (P_I, V_I, Theta) of eq. (18): slip is NOT augmented.  Slip is
    computed from the filter's own velocity estimate through (3)-(6) ("the calculation of wheel
    slips depends on the values of the wheel translational velocity estimates", Sec. III-C) and
    fed back into the longitudinal pseudo-measurement (13) after the sign constraint (14).  Here:
    after the update at step k, lambda(k) comes from v_B(k|k) = C^T V(k|k), the Euler yaw rate
    (10e) and the latest encoder speeds; the measurement at step k+1 uses lambda'(k) of (14) with
    the wheel speeds of step k+1.  (Using the prior of the same step instead would make (13)
    equal to the predicted velocity whenever (14) does not clip, i.e. a measurement with zero
    innovation.)  Consequently the encoder speeds enter (13) only through the sign bounds of (14): the
    side whose slip (14) sets to 0 contributes its r w; where (14) keeps the fed-back slip, the row
    re-measures the filter's own previous velocity (scaled by the change of that wheel's speed).
    (14) is applied with the cases of the sentence that derives it (Sec. III-C, p. ~1090: "if
    w_L <= w_R ... lambda_L <= 0 and lambda_R >= 0"; "if w_L > w_R, then lambda_L > 0 and
    lambda_R < 0"): at equal wheel speeds the left side keeps only braking slip and the right only
    traction slip (:func:`methods.yi2009.slip.constrained_slip`), so on a straight line one wheel's
    encoder speed always enters (13).  The printed (14) puts w_L = w_R in its ">=" case for lambda'_L
    (traction on both sides): v_x is then bounded from above only.  On the testbed's straight line
    (30/30 rpm, both encoders 8 whole counts per sample) the speed fell behind the wheels after the
    start from rest (a pitch error of -0.035 rad taken up in the spin-up), the slip (6) reached the +1
    clip, (13) measured v_x = 0 and held it: slip at the clip 32 % of the time after 1 s, scheme 3
    position RMS 2.85 m on the 5.4 m path (with the sentence's cases: 0 % and 0.006 m, seed 0).

Measured behaviour of this design (the testbed paths of the reproduction, tests/methods/yi2009/test_ekf.py)
    Inside the bounds of (14) schemes 2 and 3 have no absolute speed reference: their speed follows
    the IMU (pitch error -> gravity leakage) between the bounds, which on a turn are two-sided (inner
    tread >= its encoder speed, outer <= its: about +-13 % of the speed on the 80/40 rpm circle).
    Schemes 1 and 2 leave v_By and the roll angle unobserved (no row measures them; Sec. IV-B assumes
    the attitude known): the roll estimate wanders inside its initial uncertainty (P0 0.02 rad: no
    levelling when the wheels turn within the 25 levelling samples, as on every scored path) and
    gravity leaks into the lateral velocity, g droll, which integrates twice into the position, so on
    the 20 s straight line their lateral error dominates (metres; the paper reports only that "the
    first scheme has a large error").  How many metres is set by that P0, which the paper does not give:
    with 0.002 rad (a levelled start) scheme 1 is 0.2-0.7 m there over seeds 0-4 (their mean is the
    reproduction's levelled.* row).  The v_z row's
    roll column -v_By (25), evaluated at the drifted estimate, reports roll information that does not
    exist, and the roll error grows beyond the gyro's own integration error.  With good sensors and
    10 % net slip the ordering of Fig. 5 (3 <= 2 <= 1) is reproduced on turning paths.

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
from typing import TYPE_CHECKING, Any, ClassVar, Mapping, Sequence

import numpy as np

from bench.estimation.consistency import Linearisation
from bench.registry import Estimate, make_estimate
from bench.run import Run, RunError
from methods.yi2009.s_gamma import (PUBLISHED_S_GAMMA, REF_CHANNELS, SGamma, SGammaFit, fit_s_gamma,
                                    reference_s_gamma_point)

if TYPE_CHECKING:
    from bench.real.windows import WindowModel

PAPER = "Yi et al. 2009, IEEE T-RO 25(5):1087-1097"
IMU_CHANNELS = ("imu_ax", "imu_ay", "imu_az", "imu_gx", "imu_gy", "imu_gz")
ENC_CHANNELS = ("enc_wl", "enc_wr")


class FilterDivergence(RuntimeError):
    """The EKF failed numerically (innovation covariance not positive definite or a non-finite
    state).  Names the run, the step index and its time."""

    def __init__(self, where: str, step: int, t: float, what: str):
        self.where, self.step, self.t = where, step, t
        super().__init__(f"{where}: Yi 2009 EKF failed at step {step} (t = {t:.6g} s): {what}")


def dcm(phi: float, theta: float, psi: float) -> np.ndarray:
    """C_B^I of eq. (2) (Z-Y-X Euler angles), body -> inertial."""
    sf, cf, st, ct, sp, cp = math.sin(phi), math.cos(phi), math.sin(theta), math.cos(theta), math.sin(psi), math.cos(psi)
    return np.array([[ct * cp, -sp * cf + cp * sf * st, sf * sp + cp * st * cf],
                     [ct * sp, cf * cp + st * sf * sp, -sf * cp + st * cf * sp],
                     [-st, ct * sf, cf * ct]])


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
    lin: Linearisation | None = None  # error recursion of run_filter_gm(store_lin=True)
    r_vx: np.ndarray | None = None  # (n,) [m^2/s^2] the v_x row's R at each step, run_filter_gm(adaptive_vx > 0)


def run_filter(t: np.ndarray, acc: np.ndarray, gyr: np.ndarray, enc: np.ndarray, *, wheel_radius: float,
               track: float, variant: int, s_gamma: SGamma, params: EkfParams, x0: np.ndarray,
               p0: np.ndarray, store_cov: bool = False, where: str = "run",
               slip_rows: str = "feedback") -> FilterResult:
    """Run the EKF (26a)-(26f) over IMU steps, as the paper defines it (the 9 states, white R).

    ``t`` (n,), ``acc`` (n, 3) specific force [m/s^2], ``gyr`` (n, 3) [rad/s] in B; ``enc`` (n, 2)
    wheel speeds [rad/s] of a fresh encoder pair at each step or NaN (dropped).  ``x0`` (9,),
    ``p0`` (9, 9).  Step k predicts with u(k-1) over t[k] - t[k-1] (eq. (18)) and then fuses the
    measurement rows available at k (R is diagonal, so dropping a row drops that element only).
    Raises :class:`FilterDivergence` with the step index when the innovation covariance is not
    positive definite (Cholesky, LAPACK dpotrf) or the state becomes non-finite.
    The loop is :func:`run_filter_gm`'s without error states (``gm_x=None``) and with its default options (Yi's
    rows): one implementation serves the paper and the consistent configuration.  ``slip_rows`` is Yi's
    ``"feedback"`` of (13)-(14); ``"state"`` (lambda' = 0, no error state) only for the reproduction's diagnosis
    (:func:`methods.yi2009.repro.evaluation.attribution_estimate`)."""
    from methods.yi2009.consistent.filter import run_filter_gm  # the one loop (it imports this module)

    return run_filter_gm(t, acc, gyr, enc, wheel_radius=wheel_radius, track=track, variant=variant, s_gamma=s_gamma,
                         params=params, x0=x0, p0=p0, gm_x=None, store_cov=store_cov, where=where,
                         slip_rows=slip_rows)[0]


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


def _estimate_output(model: "Yi2009Ekf", res: FilterResult, t: np.ndarray, enc: np.ndarray, r: float, track: float,
                     x0: np.ndarray) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """Columns and info of an estimate from a :class:`FilterResult` (paper and consistent plugins alike)."""
    st = res.state
    cols: dict[str, np.ndarray] = dict(
        t=res.t, x=st[:, 0], y=st[:, 1], yaw=st[:, 8], vx=res.v_body[:, 0], vy=res.v_body[:, 1],
        wz=res.yaw_rate, slip_l=res.slip[:, 0], slip_r=res.slip[:, 1],
        z=st[:, 2], vz=res.v_body[:, 2], roll=st[:, 6], pitch=st[:, 7],
    )
    if model.variant == 3:
        cols["x_icr"] = res.s_icr
    info: dict[str, Any] = dict(
        variant=model.variant, paper=PAPER, wheel_radius=r, track=track,
        s_gamma=dict(a1_m=model.s_gamma.a1, a1_cm=model.s_gamma.a1_cm, a2=model.s_gamma.a2, a3=model.s_gamma.a3),
        params=asdict(model.params), n_steps=int(t.size), n_updates=dict(zip(("vx", "vy", "vz"), res.n_updates)),
        n_encoder_steps=int(np.isfinite(enc).all(axis=1).sum()), initial_state=x0.tolist(),
    )
    if model.calibration is not None:
        info["calibration"] = dict(points=list(model.calibration_points), residual_rms=model.calibration.residual_rms)
    return cols, info


@dataclass(frozen=True)
class Yi2009Ekf:
    """skidbench plugin for Yi 2009's EKF (Sec. IV-A), variant 1, 2 or 3 of Fig. 5.

    ``estimate`` returns, at each IMU sample: x, y, yaw (state P_I, psi), vx, vy (C^T V_I), wz (Euler
    yaw rate (10e)), slip_l, slip_r (eq. (6) from the posterior), x_icr (S of (41) used in (15),
    variant 3 only) and the extra columns z, vz, roll, pitch (Fig. 8).  Geometry (wheel_radius,
    track = W) from ``run.meta["platform"]``.  With ``store_covariance=True`` the posterior covariance
    of (26f) at every step is ``info["P"]`` (n, 9, 9) (used by the stress tests, bench/robustness/stress.py)."""

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
        return self.estimate_rows(run)

    def estimate_rows(self, run: Run, slip_rows: str = "feedback", name: str | None = None) -> Estimate:
        """:meth:`estimate` with :func:`run_filter`'s ``slip_rows`` (Yi's ``"feedback"``, the plugin's) and the
        estimate named ``name`` (default: the plugin's)."""
        run.require(self.requires, self.name)
        r, track = _geometry(run)
        t, acc, gyr, enc = align_inputs(run)
        x0, p0 = initial_state(acc, enc, r, self.params, self.initial_pose)
        res = run_filter(t, acc, gyr, enc, wheel_radius=r, track=track, variant=self.variant, s_gamma=self.s_gamma,
                         params=self.params, x0=x0, p0=p0, store_cov=self.store_covariance, where=run.where,
                         slip_rows=slip_rows)
        cols, info = _estimate_output(self, res, t, enc, r, track, x0)
        if res.cov is not None:
            info["P"] = res.cov  # state order (P_I, V_I, phi, theta, psi), as FilterResult.state
        return make_estimate(name or self.name, info, **cols)

    def window_models(self, wheel_radius: float, track: float) -> list[WindowModel]:
        """Yi's kinematics as real-data window models (the protocol of :mod:`bench.real.windows`): the EKF itself
        cannot run on DRIVE windows (they lack the roll and pitch gyro rates of (10c)-(10e)), so its window path is
        :class:`methods.yi2009.windows.YiSGamma` (eqs. (6), (8), (13), (15), (40), (41)), the same for the three
        schemes: the rows ``yi2009_s_gamma`` (yaw rate from the wheel speeds) and ``yi2009_s_gamma_gyro`` (the
        gyro's yaw rate), for a platform of this wheel radius and track [m] (imported here: the window path needs
        scipy and :mod:`bench.real`, which the filter's own path does not)."""
        from methods.yi2009.windows import YiSGamma

        return [YiSGamma(wheel_radius, track), YiSGamma.gyro(wheel_radius, track)]


def ekf_v1(**kwargs: Any) -> Yi2009Ekf:
    """Fig. 5 scheme 1: v_x (13) without slip + v_z (11)."""
    return Yi2009Ekf(variant=1, **kwargs)


def ekf_v2(**kwargs: Any) -> Yi2009Ekf:
    """Fig. 5 scheme 2: v_x with slip feedback (13)-(14) + v_z (11)."""
    return Yi2009Ekf(variant=2, **kwargs)


def ekf_v3(**kwargs: Any) -> Yi2009Ekf:
    """Fig. 5 scheme 3: v_x with slip, v_y (15) with S(gamma) (41), v_z (11)."""
    return Yi2009Ekf(variant=3, **kwargs)
