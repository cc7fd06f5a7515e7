"""Liu's UKF+ICR and MI-UKF (Sec. IV, Appendix): parameters, the filter run over a Run, the two plugins.

Paper equation -> code
    (15) initial state and covariance .................... run_liu_filter (first GNSS fix; LiuUkfParams.p0_*)
    (16)-(24) UKF ......................................... bench.estimation.ukf.Ukf (built by run_liu_filter)
    (25)-(28) multi-innovation update, p = 2 (Sec. IV-B-2)  bench.estimation.ukf.Ukf(mi_weights=...), MiUkf
    (29) lambda_1 = 1, lambda_i = a/(p - 1), a = 0.5 ...... bench.estimation.ukf.mi_weights, LiuUkfParams.mi_a
    (30) process noise w_k ................................ LiuUkfParams.q_*
    (31), (32), Appendix: noise v, block 2 (encoder-ICR) .. LiuUkfParams.r_gnss / r_encoder, run_liu_filter
    (11) A_ICR of the encoder speeds ...................... run_liu_filter (encoder pseudo-measurement)
    (2), (3), (5) the online ICR, after each update ....... run_liu_filter -> methods.liu2020.icr.icr_from_state
    Sec. V-B-3 initial ICR (B/2, -B/2, 0), clamp [-20, 20]  run_liu_filter, LiuUkfParams.icr_clamp
    Sec. IV-A ICR carried through a GNSS outage ........... LiuUkfParams.icr_hold_gnss_timeout / icr_hold_window
    Table 2 / Figs. 6-20 "UKF+ICR", "MI-UKF" .............. UkfIcr, MiUkf

* State: the ICR locations are not states: after each update they are computed from the posterior
  velocities and the latest encoder speeds with (2), (3), (5), clamped to [-20, 20] (Sec. V-B-3), and
  used in A_ICR for the next encoder measurement (Sec. IV-A: "Then the ICR parameters (y_l, y_r, x)
  can be generated to build the ICR kinematic model").  Initial ICR: (B/2, -B/2, 0) (Sec. V-B-3).
  Two guards the paper does not state keep A_ICR finite: an ICR is recomputed only when
  ``|theta_dot| >= icr_min_yaw_rate`` and accepted only when ``y_l - y_r >= icr_min_separation``;
  otherwise the previous ICR is held.
* Measurement (32): block 1 is :func:`methods.liu2020.model._gnss_block`; block 2 is the encoder
  pseudo-measurement of the Appendix: the previous posterior pose advanced one step with the A_ICR
  velocities of the encoder speeds at k+1, and those velocities.  The Appendix noise vector is read
  as standard deviations (0.3 m matches the DGNSS accuracy quoted in Sec. III-B-3): R = diag(v^2).
  A GNSS outage or any missing element shrinks the vector (after (32)).  As in the paper, the
  encoder pose pseudo-measurement, built from the previous posterior, is fused as if independent of
  the state; a consequence (measured on synthetic data, see tests/methods/liu2020/test_ukf.py) is
  that the position covariance hardly grows during a GNSS outage: the filter is overconfident there
  (pose NEES >> 3) and recovers slowly when the GNSS returns.
* A_ICR (8), (11): its printed second row is garbled; eq. (5) ``v_y = -x theta_dot`` is used in the
  encoder pseudo-measurement (as in ``bench.kinematics.icr_forward``).
* ICR during a GNSS outage: see :mod:`methods.liu2020.icr` (the hold is off by default).
* ICR during an encoder dropout (always; not Liu's).  Eqs. (2), (3), (5) give the ICR from the
  posterior and the wheel speeds of the same instant; the paper does not treat missing encoder
  samples.  Recomputed from the last wheel speeds held through a dropout, the ICR is no observation:
  on the 1-hour DUBHE stress run (tests/test_stress.py, 10 s dropout at 1800 s, seed 1) it went to the
  clamp (y_l 20, y_r 19.9 m) and, when the encoders returned, MI-UKF's error rose to 3.2 m and took
  12.1 s to come back within 2x its pre-fault 0.036 m.  So the ICR is held while the latest encoder
  pair is older than 1.5 encoder sample intervals (:func:`methods.liu2020.inputs._encoder_fresh`);
  with the encoders present this changes nothing.  For the same reason the wheel speeds ``wl``,
  ``wr`` and the slip rates (10) of the UKF outputs are NaN at the stale steps (the held pair is no
  measurement of the step).
* Heading: Liu's MI-UKF chatters at the -pi/pi crossing (Figs. 16-17) because old innovations are
  merged.  Here every heading innovation is wrapped when formed, the stored past corrections are
  those wrapped products, sigma-point heading means use sin/cos averaging and the state is wrapped
  after every update (bench.estimation.ukf), so there is no chattering.
* Process noise w_k (30): Liu gives no sigma_1..4; they are densities per sqrt(second)
  (``q_pos``, ``q_yaw``, ``q_vel``, ``q_yaw_rate``), Q = diag(q^2) dT.  Liu gives no UKF alpha:
  ``SigmaParams()`` (alpha = 1, beta = 2, kappa = 0).
* Not Liu's: the fields of :class:`LiuUkfParams` under "consistent configuration" (``encoder_pose``,
  ``gnss_bias_*``, ``icr_min_expansion``, ``mi_covariance``) and the branches of :func:`run_liu_filter`
  that read them serve :mod:`methods.liu2020.consistent`; their defaults leave the paper's filter
  unchanged.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, ClassVar, Sequence

import numpy as np

from bench.registry import Estimate, make_estimate
from bench.run import Run
from bench.estimation.ukf import FilterError, SigmaParams, Ukf, mi_weights
from methods.liu2020.gnss_bias import liu_fx_gnss_bias, liu_hx_gnss_bias
from methods.liu2020.icr import _icr_update_allowed, _icr_window_fit, icr_from_state, slip_rates
from methods.liu2020.inputs import (
    ENCODERS,
    GNSS_POSE,
    GNSS_VEL,
    IMU,
    PAPER,
    _check_channels,
    _encoder_fresh,
    _ffill,
    _initial_pose,
    geometry,
)
from methods.liu2020.model import STATE_NAMES, _gnss_block, liu_fx, liu_hx


@dataclass(frozen=True)
class LiuUkfParams:
    """Parameters of the UKF+ICR / MI-UKF (Liu Sec. IV and Appendix); SI units."""

    innovation_length: int = 1  # p of eq. (26); 2 for the MI-UKF (Sec. IV-B-2)
    mi_a: float = 0.5  # a of eq. (29)
    sigma: SigmaParams = SigmaParams()
    # Appendix: measurement noise (std devs) of block 1 (GNSS x, y, yaw, v_x, v_y; gyro) and block 2 (encoder)
    r_gnss: tuple[float, float, float, float, float, float] = (0.3, 0.3, 0.3, 0.01, 0.01, 0.01)
    r_encoder: tuple[float, float, float, float, float, float] = (0.5, 0.5, 0.5, 0.02, 0.02, 0.02)
    # process noise densities per sqrt(s) of w_k in (30): sigma_1,2 (m), sigma_3 (rad), a dT (m/s), sigma_4 (rad/s)
    q_pos: float = 0.05
    q_yaw: float = 0.01
    q_vel: float = 0.2
    q_yaw_rate: float = 1.0
    # initial standard deviations (eq. (15)) of pose and velocities
    p0_pos: float = 0.3
    p0_yaw: float = 0.1
    p0_vel: float = 0.2
    p0_yaw_rate: float = 0.1
    icr_clamp: float = 20.0  # Sec. V-B-3
    icr_min_yaw_rate: float = 1e-3  # [rad/s] below: ICR held (not in the paper; avoids 0/0)
    icr_min_separation: float = 0.05  # [m] y_l - y_r below: ICR held (keeps A_ICR finite)
    transport_terms: bool = True
    joseph: bool = True
    gate: float | None = None  # Mahalanobis gate per element [std]; off as in the paper
    slip_min_speed: float = 0.05  # [m/s]
    store_covariance: bool = True  # Estimate.info["P"]: (T, 6, 6) for NEES
    # ICR hold during a GNSS outage (Sec. IV-A, see the module docstring): None = the per-update ICR
    # recomputation as written (default); a number = hold the ICR while the latest GNSS position fix
    # is older than this many seconds (choose it above the GNSS sample period, e.g. 1 s at 10 Hz)
    icr_hold_gnss_timeout: float | None = None
    # [s] the held ICR is the least-squares fit of (2), (3), (5) over the GNSS-aided steps of the last
    # icr_hold_window seconds (_icr_window_fit); 0 = the latest per-step ICR (a literal freeze)
    icr_hold_window: float = 20.0
    # ---- consistent configuration (not in the paper; defaults leave the paper's filter unchanged) ----
    # fuse the encoder pose pseudo-measurement of the Appendix (built from the previous posterior);
    # False: only its velocity elements are fused (the pose elements repeat the prior: double counting)
    encoder_pose: bool = True
    # GNSS position error as two first-order Gauss-Markov bias states (b_x, b_y) appended to the state:
    # db = -b / tau dt + w, std of b at t_0 ``gnss_bias_p0`` [m] per axis, driving noise density
    # ``gnss_bias_q`` [m/sqrt(s)]; None: the GNSS error is white (paper)
    gnss_bias_tau: float | None = None
    gnss_bias_p0: float = 0.0
    gnss_bias_q: float = 0.0
    # ICR accepted only when y_l - y_r >= max(icr_min_separation, icr_min_expansion * B) (B: track);
    # 1.0 = the expansion factor chi = (y_l - y_r)/B of a skid-steered vehicle is at least 1
    icr_min_expansion: float = 0.0
    # MI-UKF covariance that includes the re-applied past correction of eq. (28) (bench.estimation.ukf.Ukf mi_covariance;
    # p = 2 only); False: eq. (24), the current gain only (paper)
    mi_covariance: bool = False

    def __post_init__(self) -> None:
        if self.innovation_length < 1:
            raise ValueError(f"innovation_length = {self.innovation_length!r}: expected >= 1")
        for nm in ("r_gnss", "r_encoder"):
            v = getattr(self, nm)
            if len(v) != 6 or not all(x > 0 for x in v):
                raise ValueError(f"{nm} = {v!r}: expected six positive standard deviations")
        if not self.icr_clamp > 0:
            raise ValueError(f"icr_clamp = {self.icr_clamp!r}: expected > 0")
        h = self.icr_hold_gnss_timeout
        if h is not None and not (isinstance(h, (int, float)) and math.isfinite(h) and h > 0):
            raise ValueError(f"icr_hold_gnss_timeout = {h!r}: expected None or a finite number of seconds > 0")
        if not (math.isfinite(self.icr_hold_window) and self.icr_hold_window >= 0):
            raise ValueError(f"icr_hold_window = {self.icr_hold_window!r}: expected a finite number of seconds >= 0")
        for nm in ("q_pos", "q_yaw", "q_vel", "q_yaw_rate", "p0_pos", "p0_yaw", "p0_vel", "p0_yaw_rate",
                   "icr_min_yaw_rate", "icr_min_separation", "slip_min_speed", "gnss_bias_p0", "gnss_bias_q",
                   "icr_min_expansion"):
            v = getattr(self, nm)
            if not (math.isfinite(v) and v >= 0):
                raise ValueError(f"LiuUkfParams.{nm} = {v!r}: expected a finite number >= 0")
        tau = self.gnss_bias_tau
        if tau is not None:
            if not (isinstance(tau, (int, float)) and math.isfinite(tau) and tau > 0):
                raise ValueError(f"gnss_bias_tau = {tau!r}: expected None or a finite number of seconds > 0")
            if not self.p0_pos > self.gnss_bias_p0:
                raise ValueError(f"p0_pos = {self.p0_pos!r} must exceed gnss_bias_p0 = {self.gnss_bias_p0!r}: the "
                                 "initial position is the first GNSS fix, whose error is the bias plus white noise")


@dataclass(frozen=True)
class _LiuUkf:
    params: LiuUkfParams = LiuUkfParams()

    name: ClassVar[str] = "liu2020._ukf"
    paper: ClassVar[str] = PAPER
    requires: ClassVar[frozenset[str]] = ENCODERS | GNSS_POSE | GNSS_VEL | IMU

    def calibrate(self, runs: Sequence[Run]) -> "_LiuUkf":
        """Nothing to calibrate: the ICR locations are estimated online (Sec. IV-A)."""
        return self

    def estimate(self, run: Run) -> Estimate:
        _check_channels(run, self.requires, self.name)
        return run_liu_filter(run, self.params, self.name)


def run_liu_filter(run: Run, p: LiuUkfParams, name: str = "liu2020.mi_ukf", make_filter: Any = Ukf) -> Estimate:
    """UKF+ICR / MI-UKF over a Run (one filter step per log row).

    ``make_filter`` builds the filter with :class:`bench.estimation.ukf.Ukf`'s constructor signature and must
    offer ``x``, ``P``, ``step``, ``predict(dt, u, Q)`` and ``update(z) -> n_fused``; it exists so
    that tests and benchmarks can run the identical model on a second UKF implementation."""
    g = geometry(run)
    B, r = g.track, g.wheel_radius
    t = run.t
    T = t.size
    dts = np.diff(t)
    if np.any(~(dts > 0)):
        run.validate()
    zg = _gnss_block(run)
    wl_raw, wr_raw = run["enc_wl"], run["enc_wr"]
    enc_ok = np.isfinite(wl_raw) & np.isfinite(wr_raw)
    wl_h, wr_h = _ffill(wl_raw), _ffill(wr_raw)  # latest encoder speeds (for ICR and slip)
    ax, ay = _ffill(run["imu_ax"]), _ffill(run["imu_ay"])

    x0, y0, yaw0, i0 = _initial_pose(run)
    vx0 = float(zg[i0, 3]) if np.isfinite(zg[i0, 3]) else 0.0
    vy0 = float(zg[i0, 4]) if np.isfinite(zg[i0, 4]) else 0.0
    gz_first = np.flatnonzero(np.isfinite(zg[:, 5]))
    w0 = float(zg[gz_first[0], 5]) if gz_first.size else 0.0
    P0 = np.diag(np.square([p.p0_pos, p.p0_pos, p.p0_yaw, p.p0_vel, p.p0_vel, p.p0_yaw_rate]))
    qc = np.square([p.q_pos, p.q_pos, p.q_yaw, p.q_vel, p.q_vel, p.q_yaw_rate])
    R = np.diag(np.square(np.concatenate((p.r_gnss, p.r_encoder))))
    x_init = [x0, y0, yaw0, vx0, vy0, w0]
    fx, hx = liu_fx, liu_hx
    bias_tau = p.gnss_bias_tau
    if bias_tau is not None:  # consistent configuration: GNSS bias states b_x, b_y (columns 6, 7)
        fx, hx = liu_fx_gnss_bias, liu_hx_gnss_bias
        vb = p.gnss_bias_p0 ** 2
        P0 = np.pad(P0, ((0, 2), (0, 2)))
        # the initial position is the first GNSS fix, p + b + n: its error is b + n and the bias
        # estimate 0 has error -b, so cov(position error, bias error) = -var(b)
        P0[6, 6] = P0[7, 7] = vb
        P0[0, 6] = P0[6, 0] = P0[1, 7] = P0[7, 1] = -vb
        qc = np.concatenate((qc, [p.gnss_bias_q ** 2] * 2))
        x_init += [0.0, 0.0]
    kf = make_filter(fx, hx, x_init, P0, np.diag(qc), R, sigma=p.sigma,
                     x_angles=(2,), z_angles=(2, 8), joseph=p.joseph, gate=p.gate,
                     mi_weights=mi_weights(p.innovation_length, p.mi_a),
                     **({"mi_covariance": True} if p.mi_covariance else {}))
    enc_pose = bool(p.encoder_pose)

    X = np.empty((T, 6))
    icr = np.empty((T, 3))
    Ps = np.empty((T, 6, 6)) if p.store_covariance else None
    X[0] = kf.x[:6]
    if Ps is not None:
        Ps[0] = kf.P[:6, :6]
    Bs = None if bias_tau is None else np.zeros((T, 2))
    yl, yr, xi = 0.5 * B, -0.5 * B, 0.0  # initial ICR (Sec. V-B-3)
    icr[0] = (yl, yr, xi)
    clamp, wmin, dmin = p.icr_clamp, p.icr_min_yaw_rate, max(p.icr_min_separation, p.icr_min_expansion * B)
    transport = bool(p.transport_terms)
    icr_free_a = _icr_update_allowed(t, zg, p.icr_hold_gnss_timeout)
    icr_free = icr_free_a.tolist()
    enc_fresh_a = _encoder_fresh(t, enc_ok)
    enc_fresh = enc_fresh_a.tolist()
    win = p.icr_hold_window
    z = np.empty(12)
    nan6 = np.full(6, np.nan)
    last_dt, Q = None, None
    n_fused = np.zeros(T, dtype=np.int16)
    dts_l, ax_l, ay_l = dts.tolist(), ax.tolist(), ay.tolist()
    wl_l, wr_l, wlh_l, wrh_l, enc_l = wl_raw.tolist(), wr_raw.tolist(), wl_h.tolist(), wr_h.tolist(), enc_ok.tolist()
    try:
        for k in range(1, T):
            dt = dts_l[k - 1]
            if dt != last_dt:
                Q, last_dt = np.diag(qc * dt), dt
            Xp, Yp, php = kf.x[:3].tolist()  # posterior at k-1
            kf.step = k - 1
            if bias_tau is None:
                kf.predict(dt, (ax_l[k - 1], ay_l[k - 1], transport), Q)
            else:
                kf.predict(dt, (ax_l[k - 1], ay_l[k - 1], transport, math.exp(-dt / bias_tau)), Q)
            z[:6] = zg[k]
            if enc_l[k]:  # Appendix: encoder-ICR pseudo-measurement with A_ICR of eq. (11)
                v_l, v_r = r * wl_l[k], r * wr_l[k]
                d = yl - yr
                evx = (yl * v_r - yr * v_l) / d
                ew = (v_r - v_l) / d
                evy = -xi * ew
                ph = php + ew * dt
                c, s = math.cos(ph), math.sin(ph)
                z[6:] = (Xp + (evx * c - evy * s) * dt, Yp + (evx * s + evy * c) * dt, ph, evx, evy, ew)
                if not enc_pose:
                    z[6:9] = nan6[:3]
            else:
                z[6:] = nan6
            n_fused[k] = kf.update(z)
            xk = kf.x[:6]
            X[k] = xk
            if Ps is not None:
                Ps[k] = kf.P[:6, :6]
            if Bs is not None:
                Bs[k] = kf.x[6:]
            vx_, vy_, wz = xk[3:].tolist()
            if icr_free[k] and enc_fresh[k] and abs(wz) >= wmin:  # eqs. (2), (3), (5), clamped to [-20, 20]
                a, b, c_ = icr_from_state(vx_, vy_, wz, r * wlh_l[k], r * wrh_l[k], clamp)
                if a - b >= dmin:
                    yl, yr, xi = a, b, c_
            elif win > 0 and not icr_free[k] and icr_free[k - 1]:  # hold starts: ICR fitted over the window
                held = _icr_window_fit(X, wl_h, wr_h, r, icr_free_a & enc_fresh_a, t, k, win, wmin, clamp)
                if held is not None and held[0] - held[1] >= dmin:
                    yl, yr, xi = held
            icr[k] = (yl, yr, xi)
    except FilterError as exc:
        raise FilterError(exc.step, exc.stage,
                          f"{exc.detail} ({name}, run {run.where}, t = {t[min(exc.step, T - 1)]:.3f} s)") from None

    # the held wheel speeds are no measurement of a stale step: NaN there, and in the slips (10) made from them
    wl_o, wr_o = np.where(enc_fresh_a, wl_h, np.nan), np.where(enc_fresh_a, wr_h, np.nan)
    sl, sr = slip_rates(r * wl_o, r * wr_o, X[:, 3], X[:, 5], B, p.slip_min_speed)
    info: dict[str, Any] = {
        "state": STATE_NAMES, "params": dataclasses.asdict(p), "n_fused": n_fused,
        "gnss_updates": int(np.isfinite(zg[:, 0]).sum()),
        "icr_held_steps": int(T - np.count_nonzero(icr_free_a)),
        "icr_stale_encoder_steps": int(T - np.count_nonzero(enc_fresh_a)),
    }
    if Ps is not None:
        info["P"] = Ps  # the six navigation states (the GNSS bias states are marginalised out)
    if Bs is not None:
        info["gnss_bias"] = Bs
    return make_estimate(
        name, info, t=t, x=X[:, 0], y=X[:, 1], yaw=X[:, 2], vx=X[:, 3], vy=X[:, 4], wz=X[:, 5],
        y_l=icr[:, 0], y_r=icr[:, 1], x_icr=icr[:, 2], chi=(icr[:, 0] - icr[:, 1]) / B,
        slip_l=sl, slip_r=sr, wl=wl_o, wr=wr_o,
    )


@dataclass(frozen=True)
class UkfIcr(_LiuUkf):
    """UKF+ICR of Liu Figs. 6-20 / Table 2: the MI-UKF with lambda_2 = 0 (standard UKF, eq. (24))."""

    params: LiuUkfParams = LiuUkfParams(innovation_length=1)
    name: ClassVar[str] = "liu2020.ukf_icr"


@dataclass(frozen=True)
class MiUkf(_LiuUkf):
    """MI-UKF of Liu Sec. IV: multi-innovation update (28) with p = 2, a = 0.5 (eq. (29))."""

    params: LiuUkfParams = LiuUkfParams(innovation_length=2, mi_a=0.5)
    name: ClassVar[str] = "liu2020.mi_ukf"
