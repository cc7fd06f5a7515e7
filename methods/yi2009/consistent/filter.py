"""The EKF loop of Yi 2009 Sec. IV-A with the consistent configuration's error states and options: run_filter_gm.

One loop serves the paper and the consistent configuration: without error states (``gm_x=None``) and with its
default options it is the paper's filter, :func:`methods.yi2009.ekf.run_filter` (the strapdown prediction (10),
(18)-(22), the rows (11), (13)-(14), (15) with S(gamma) (40)-(41), the model (16)-(17), (23)-(25), the recursion
(26a)-(26f)); the Gauss-Markov error states of the rows, the quantisation and odometer states, the row offsets, the
gates, the trapezoidal IMU integration and the adaptive R are not Yi's (:func:`run_filter_gm`).
"""
from __future__ import annotations

import math
from collections import deque
from typing import Sequence

import numpy as np
from scipy.linalg import lapack

from bench.estimation.consistency import Linearisation
from methods.yi2009.consistent.gauss_markov import GaussMarkov
from methods.yi2009.ekf import EkfParams, FilterDivergence, FilterResult
from methods.yi2009.s_gamma import SGamma

ADAPTIVE_R_FLOOR = 1e-4  # [m/s] floor of the adaptive v_x row R (run_filter_gm adaptive_vx): 1 % of the quantisation
SLIP_CLIP_TOL = 1e-9  # |lambda| >= 1 - tol: the slip (6) is at its clip (diagnostics of the consistent configuration)
SLIP_ROWS = ("feedback", "state")  # v_x row of run_filter_gm: Yi's (13) with fed-back slip / slip as the b_x state


def run_filter_gm(t: np.ndarray, acc: np.ndarray, gyr: np.ndarray, enc: np.ndarray, *, wheel_radius: float,
                  track: float, variant: int, s_gamma: SGamma, params: EkfParams, x0: np.ndarray, p0: np.ndarray,
                  gm_x: GaussMarkov | None, gm_y: GaussMarkov | None = None, store_cov: bool = False, where: str = "run",
                  slip_rows: str = "feedback", roll_model_jacobian: bool = False, enc_quant: float = 0.0,
                  vx_offset: np.ndarray | None = None, store_lin: bool = False, vy_offset: np.ndarray | None = None,
                  imu_mean: bool = False, enc_gamma: np.ndarray | None = None, gm_sigma: np.ndarray | None = None,
                  vx_skip: np.ndarray | None = None, vy_skip: np.ndarray | None = None, adaptive_vx: int = 0,
                  adaptive_floor: float = ADAPTIVE_R_FLOOR, odo_window: int = 0, odo_sd: float = 0.0,
                  shared_init: Sequence[int] = ()) -> tuple[FilterResult, np.ndarray, np.ndarray]:
    """:func:`run_filter` with the pseudo-measurement errors augmented as Gauss-Markov states (not Yi's).

    State (P_I, V_I, phi, theta, psi, b_x[, b_y][, u_prev, u][, d]): b_x is the correlated error of the v_x row (13),
    b_y of the v_y row (15) (scheme 3; ``gm_y`` required then).  Prediction of b: a = exp(-dT/tau), Q_b = sigma^2
    (1 - a^2); measurement y_x = v_Bx + b_x [+ u_k - u_(k-1)] + white (R = gm_x.white^2), y_y = v_By + b_y + white.
    Everything else (strapdown (10), S(gamma) (40)-(41), the v_z row (11) with sigma_vz, Joseph update, yaw wrap)
    is :func:`run_filter`'s, except where an option below says otherwise.

    ``slip_rows`` "feedback" (Yi's (13)-(14)): v_x = r (w_L (1 - lambda'_L) + w_R (1 - lambda'_R))/2 with the
    constrained slips lambda' (14) of the previous posterior.  Where (14) keeps the fed-back slip lambda(k-1),
    r w (1 - lambda) is the filter's own contact velocity of step k-1 (eq. (6) inverted): the row is a copy of the
    previous posterior, with no new information; fused as a measurement it counts the prior again.  What the row
    does carry are the sign bounds of (14): the side whose slip (14) sets to 0 contributes its encoder speed r w.
    (14) is applied with the cases of the sentence before it (Sec. III-C: "if w_L <= w_R ... lambda_L <= 0 and
    lambda_R >= 0"; "if w_L > w_R, then lambda_L > 0 and lambda_R < 0"), so that at equal encoder speeds the left
    side keeps only braking slip and the right only traction slip, as at w_L < w_R.  The printed (14) puts
    w_L = w_R in its ">=" case for lambda'_L, i.e. traction on both sides: then v_x is bounded from above only,
    and with encoder pairs that read exactly equal (the testbed's 30/30 rpm straight line: 8 whole counts per
    sample on each wheel) a speed that falls behind the wheels is never pulled back; at the +1 clip of (6) the row
    reads 0 and holds the estimate there (the latch of the earlier versions: slip at the clip 32 % of the time,
    position RMS 2.9 m on the 5.4 m straight; tests/methods/yi2009/test_ekf.py, the start from rest).  "state": the slip is not fed back (lambda' = 0 in (13) and in gamma (40)): the net slip velocity
    r (lambda_L w_L + lambda_R w_R)/2 is the Gauss-Markov state -b_x, estimated with its covariance like any other
    error state; the slips (6) are still output from the posterior.  With "state", schemes 1 and 2 fuse the same
    rows (scheme 2's distinction is the feedback).  (Tried and not kept: fusing only the wheels whose slip (14)
    sets to zero, i.e. the sign bounds of (14) as active inequality constraints: on the straight path both sides
    keep traction slip, nothing anchors the speed from below and it drifts; position RMS 18 m, 5 seeds.)
    ``roll_model_jacobian`` (schemes 1-2 only): the roll column of the v_z row (11), -v_By, is evaluated at
    v_By = 0, the lateral velocity these schemes assume (no lateral slip is modelled; Yi's (15) with S = 0),
    instead of at the estimate.  Schemes 1-2 measure neither v_By nor roll, so at the true state (v_By ~ 0 on a
    straight line) the pair (roll, v_By) is unobservable; linearised at a drifted estimate v_By the v_z row
    reports roll information that does not exist and the filter becomes overconfident in roll while gravity leaks
    into v_By (the first-estimates / observability-constrained EKF argument: Huang, Mourikis, Roumeliotis 2010,
    IJRR 29(5)).  Scheme 3 measures v_By, so its Jacobian is left at the estimate.
    ``enc_quant`` > 0 [m/s]: the encoder quantisation of the v_x row as states (:func:`encoder_quantisation`).
    Each wheel speed is a count difference over the sample interval, so its quantisation error is u_k - u_(k-1)
    with u_k the residual of the count at sample k (uniform, independent between samples): a moving-average error
    whose sum over N samples telescopes to (u_N - u_0), which a white R would let shrink only as sqrt(N).  At each
    fused v_x row a fresh u_k ~ N(0, enc_quant^2) enters the state (row +1 on u, -1 on u_prev), and after the
    update it becomes u_prev of the next row (augmentation for moving-average measurement noise: Bar-Shalom, Li,
    Kirubarajan 2001 Sec. 8.4).
    ``vx_offset`` (n,) [m/s] (``slip_rows="state"`` only): a known part of the v_x row's error subtracted from the
    row, y_x = r (w_L + w_R)/2 - vx_offset(k) (the traction slip of :class:`TractionSlip`); b_x is then the rest.
    ``vy_offset`` (n,) [m/s] (scheme 3): a known part of the v_y row's error subtracted from the row,
    y_y = -S(gamma) psi_dot - vy_offset(k) (the S correction of :class:`IcrCorrection`); b_y is then the rest.
    ``imu_mean``: the prediction from step k-1 to k uses the mean of the IMU samples k-1 and k (the trapezoidal
    rule for the strapdown integral of (10)) instead of sample k-1 alone (Yi's (26a), forward Euler).  The IMU
    samples the rates at instants; held over the step, a sample lags the rate's mean over it by half a sample,
    which on a turn at w leaves the heading w dT/2 behind for as long as the turn lasts (4 mrad at 1 rad/s and
    125 Hz) and rotates the fused body velocities by it: an error that no noise term of the filter represents.
    The process noise is unchanged (the sum of the means of consecutive white samples is the same random walk).
    ``enc_gamma`` (n, 2) [rad/s] (scheme 3, ``slip_rows="state"``): the wheel speeds from which gamma (40) and
    S(gamma) (41) of the v_y row are computed, instead of the step's encoder pair (:func:`trailing_mean` of the
    encoders in :class:`Yi2009EkfConsistent`); the other rows use the step's pair.
    ``gm_sigma`` (n, nb) [m/s]: the Gauss-Markov states' stationary std per step instead of their ``sigma``
    (:func:`gm_sigma_steps`; variance-modulated, Q_b(k) = sigma_k^2 (1 - a^2), P0 at sigma_0^2).
    ``vx_skip`` (n,) bool: steps whose v_x row is not fused (:func:`traction_transient`); with quantisation states the
    next row's u_(k-1) is then a fresh residual.
    ``vy_skip`` (n,) bool (scheme 3): steps whose v_y row (15) is not fused (its b_y state is still propagated).
    ``adaptive_vx`` > 0: the v_x row's white R is estimated from the filter's own post-fit residuals instead of
    held at ``gm_x.white^2`` (residual-based covariance matching, Mohamed & Schwarz 1999, J. Geodesy 73:193-203,
    eq. (33): R = C_eps + H P+ H^T, C_eps the mean of eps^2 = (y - h(x+))^2): after each fused v_x row, R of the
    next is the mean of eps^2 + h P+ h^T over the last ``adaptive_vx`` fused rows, floored at ``adaptive_floor``^2
    [m/s]; ``gm_x.white^2`` until a quarter of the window is filled.  Unbiased when the rest of the model is true;
    the R used at each step is ``FilterResult.r_vx``.
    ``odo_window`` > 0 [steps] (``slip_rows="state"``, no quantisation states, no adaptive R): the v_x row is fused
    as an odometer instead of per step.  A state d integrates the row's model since the last window,
    d += dT (v_Bx + dT/2 dv_Bx + b_x) (the trapezoid of the strapdown step, F row dT (C^T)_x, dT dv_Bx/dTheta, dT on
    b_x); the rows y_x dT are summed over the same steps (each row is the count difference over its step, so the sum
    is the displacement of the window's end counts), and after ``odo_window`` rows the sum is fused as z = d with
    R = ``odo_sd``^2 [m] (:func:`encoder_odometer_sd`: the quantisation of the two end counts, which is all that
    is left of the rows' quantisation errors after the telescoping).  Then d restarts at exactly 0 (its row and
    column of P zeroed, and the error recursion of ``store_lin`` too).  A step without its row (encoder missing or
    ``vx_skip``) breaks the window: it restarts after that step, unfused.  Stochastic cloning of the odometer
    displacement (Roumeliotis & Burdick 2002, ICRA) reduced to the one coordinate the row measures.
    ``store_lin``: also return the filter's linearised error recursion (``FilterResult.lin``, a
    :class:`bench.estimation.consistency.Linearisation`: A_k = (I - K H) F, C_k = (I - K H) Q' (I - K H)^T + K R K^T, P_k,
    with Q' = Q without the Gauss-Markov states' driving noise, which is the ``shared`` loading (I - K H) G_b Q_b^(1/2)
    instead, and at k = 0 their initial sd (P0's): the rows' errors b are functions of the path, the same in every
    seed of a scenario) for the null distribution of the NEES test (not with quantisation states).
    ``shared_init`` (``store_lin``): the navigation states (indices 0-8) whose initial error is shared too: x0 took
    them from the scenario, not from the run's sensors, so e_0 there is the path's (x0 minus the truth's start), the
    same in every seed; the square root of their block of P0 is ``Linearisation.shared0`` (nx, 9), column j for state
    j in every run, zero for the states not shared (P0 must not couple the shared states with the others).
    ``gm_x`` None: no error states, the white R of the paper (r^2 sigma_en^2, sigma_2^2 of ``params``; ``gm_y``
    ignored): :func:`run_filter`, the paper's filter.
    Returns (FilterResult with the 9-state part and, when ``store_cov``, the (n, nx, nx) covariance, b (n, nb),
    rows (n, 2): the v_x and v_y rows fused at each step, NaN where not fused)."""
    if variant not in (1, 2, 3):
        raise ValueError(f"variant = {variant!r}: must be 1, 2 or 3 (Fig. 5)")
    if variant == 3 and gm_x is not None and gm_y is None:
        raise ValueError("run_filter_gm: scheme 3 needs gm_y (the v_y row's Gauss-Markov error)")
    if slip_rows not in SLIP_ROWS:
        raise ValueError(f"run_filter_gm: slip_rows = {slip_rows!r}: must be one of {SLIP_ROWS}")
    if not (math.isfinite(enc_quant) and enc_quant >= 0):
        raise ValueError(f"run_filter_gm: enc_quant = {enc_quant!r}: must be finite and >= 0")
    n = int(t.size)
    if vx_offset is not None:
        vx_offset = np.asarray(vx_offset, float)
        if slip_rows != "state" or vx_offset.shape != (n,) or not np.isfinite(vx_offset).all():
            raise ValueError(f"run_filter_gm: vx_offset needs slip_rows='state' (got {slip_rows!r}) and {n} finite "
                             f"values (got shape {vx_offset.shape}, {int(np.sum(~np.isfinite(vx_offset)))} non-finite)")
    off_l = vx_offset.tolist() if vx_offset is not None else None
    if vy_offset is not None:
        vy_offset = np.asarray(vy_offset, float)
        if variant != 3 or vy_offset.shape != (n,) or not np.isfinite(vy_offset).all():
            raise ValueError(f"run_filter_gm: vy_offset needs scheme 3 (got {variant}) and {n} finite values (got "
                             f"shape {vy_offset.shape}, {int(np.sum(~np.isfinite(vy_offset)))} non-finite)")
    offy_l = vy_offset.tolist() if vy_offset is not None else None
    if enc_gamma is not None:
        enc_gamma = np.asarray(enc_gamma, float)
        if variant != 3 or slip_rows != "state" or enc_gamma.shape != (n, 2):
            raise ValueError(f"run_filter_gm: enc_gamma needs scheme 3 (got {variant}), slip_rows='state' (got "
                             f"{slip_rows!r}) and shape ({n}, 2) (got {enc_gamma.shape})")
    encg_l = enc_gamma.tolist() if enc_gamma is not None else None
    if vx_skip is not None and np.shape(vx_skip) != (n,):
        raise ValueError(f"run_filter_gm: vx_skip needs shape ({n},) (got {np.shape(vx_skip)})")
    skip_l = np.zeros(n, bool).tolist() if vx_skip is None else np.asarray(vx_skip, bool).tolist()
    if vy_skip is not None and (variant != 3 or np.shape(vy_skip) != (n,)):
        raise ValueError(f"run_filter_gm: vy_skip needs scheme 3 (got {variant}) and shape ({n},) (got "
                         f"{np.shape(vy_skip)})")
    skipy_l = np.zeros(n, bool).tolist() if vy_skip is None else np.asarray(vy_skip, bool).tolist()
    if store_lin and enc_quant > 0:
        raise ValueError("run_filter_gm: store_lin is not available with quantisation states (enc_quant > 0)")
    shared_init = sorted(set(int(i) for i in shared_init))
    if shared_init and not (store_lin and 0 <= shared_init[0] and shared_init[-1] < 9):
        raise ValueError(f"run_filter_gm: shared_init = {shared_init} needs store_lin and navigation states 0-8")
    lin_a: list[np.ndarray] = []
    lin_c: list[np.ndarray] = []
    lin_p: list[np.ndarray] = []
    lin_s: list[np.ndarray] = []
    r, hw = float(wheel_radius), 0.5 * float(track)
    use_slip, use_vy = variant >= 2, variant == 3
    gms = () if gm_x is None else (gm_x, gm_y) if use_vy else (gm_x,)
    nb = len(gms)
    gms_l = None
    if gm_sigma is not None and nb:
        gm_sigma = np.asarray(gm_sigma, float)
        if gm_sigma.shape != (n, nb) or not (np.isfinite(gm_sigma).all() and (gm_sigma > 0).all()):
            raise ValueError(f"run_filter_gm: gm_sigma needs shape ({n}, {nb}) of finite values > 0 (got shape "
                             f"{gm_sigma.shape})")
        gms_l = (gm_sigma**2).tolist()
    nq = 2 if enc_quant > 0 else 0  # quantisation residuals (previous, current) of the v_x row
    no = 1 if odo_window else 0  # odometer: the integral of the row's v_Bx + b_x since the last window
    if no and (nq or adaptive_vx or slip_rows != "state" or not odo_sd > 0):
        raise ValueError(f"run_filter_gm: odo_window = {odo_window!r} needs slip_rows='state', no quantisation "
                         f"states, no adaptive R and odo_sd > 0 (got {odo_sd!r})")
    nx = 9 + nb + nq + no
    iod = 9 + nb + nq
    iqc, iqu = 9 + nb, 10 + nb
    a1, a2, a3 = s_gamma.a1, s_gamma.a2, s_gamma.a3
    g = params.gravity
    vmin = params.min_wheel_speed
    q_const = np.array([params.pos_noise**2] * 3 + [0.0] * (6 + nb + nq + no))
    q_dt2 = np.array([0.0] * 3 + [params.accel_noise**2] * 3 + [params.gyro_noise**2] * 3 + [0.0] * (nb + nq + no))
    if gm_x is None:  # R = diag(r^2 sigma_en^2, sigma_2^2, sigma_3^2) (Sec. IV-A)
        r_all = ((r * params.sigma_enc) ** 2, params.sigma_vy**2, params.sigma_vz**2)
    else:
        r_all = (odo_sd**2 if no else gm_x.white**2, gm_y.white**2 if use_vy else 0.0, params.sigma_vz**2)

    # R (diagonal) and its diagonal for each set of fused rows (0: v_x, 1: v_y, 2: v_z)
    r_sets = {rows: (np.diag([r_all[i] for i in rows]), np.array([r_all[i] for i in rows]))
              for rows in ((0, 1, 2), (0, 2), (1, 2), (2,))}

    if not (isinstance(adaptive_vx, int) and not isinstance(adaptive_vx, bool) and adaptive_vx >= 0
            and adaptive_floor > 0):
        raise ValueError(f"run_filter_gm: adaptive_vx = {adaptive_vx!r} must be an int >= 0 and adaptive_floor = "
                         f"{adaptive_floor!r} > 0")
    if adaptive_vx and gm_x is None:
        raise ValueError("run_filter_gm: adaptive_vx needs gm_x (the paper's filter keeps its R)")
    ad_terms: deque[float] = deque(maxlen=max(adaptive_vx, 1))  # eps^2 + h P+ h^T of the last fused v_x rows
    r_x_cur = r_all[0]
    r_vx = np.full(n, np.nan) if adaptive_vx else None

    t_l, acc_l, gyr_l, enc_l = t.tolist(), acc.tolist(), gyr.tolist(), enc.tolist()
    if imu_mean and n > 1:  # the input of the step k-1 -> k: mean of samples k-1 and k
        accp_l = np.vstack((0.5 * (acc[:-1] + acc[1:]), acc[-1:])).tolist()
        gyrp_l = np.vstack((0.5 * (gyr[:-1] + gyr[1:]), gyr[-1:])).tolist()
    else:
        accp_l, gyrp_l = acc_l, gyr_l
    enc_ok = np.isfinite(enc).all(axis=1).tolist()
    out: list[tuple[float, ...]] = []
    covs: list[np.ndarray] = []
    Ix = np.eye(nx)
    f_tmpl = np.eye(nx).ravel().tolist()

    def ix(i: int, j: int) -> int:
        return i * nx + j

    i03, i14, i25 = ix(0, 3), ix(1, 4), ix(2, 5)
    i36, i37, i38, i46, i47, i48 = ix(3, 6), ix(3, 7), ix(3, 8), ix(4, 6), ix(4, 7), ix(4, 8)
    i56, i57, i66, i67, i76, i86, i87 = ix(5, 6), ix(5, 7), ix(6, 6), ix(6, 7), ix(7, 6), ix(8, 6), ix(8, 7)
    ib = [ix(9 + j, 9 + j) for j in range(nb)]
    zb = (0.0,) * nb
    ex = (1.0, 0.0)[:nb] + ((-1.0, 1.0) if nq else ()) + (0.0,) * no
    ey = (0.0, 1.0)[:nb]
    zq = (0.0,) * (nq + no)
    h_odo = (0.0,) * iod + (1.0,)
    iod3, iod4, iod5, iod7, iod8 = (ix(iod, j) for j in (3, 4, 5, 7, 8)) if no else (0,) * 5
    iodb = ix(iod, 9) if no and nb else None
    od = z_acc = 0.0
    n_acc = 0
    shift_q = np.eye(nx)
    if nq:
        shift_q[iqc, iqc], shift_q[iqc, iqu], shift_q[iqu, iqu] = 0.0, 1.0, 0.0
        var_q = enc_quant**2
    P = np.zeros((nx, nx))
    P[:9, :9] = p0
    for j, gmj in enumerate(gms):  # the error states start at their stationary variance
        P[9 + j, 9 + j] = gmj.sigma**2 if gms_l is None else gms_l[0][j]
    px, py, pz, vx, vy, vz, phi, th, psi = (float(v) for v in x0)
    b = [0.0] * nb
    qc = qu = 0.0
    if nq:
        P[iqc, iqc] = P[iqu, iqu] = enc_quant**2
    lam_l = lam_r = 0.0
    w_l = w_r = math.nan
    s_cur = math.nan
    if enc_ok[0]:
        w_l, w_r = enc_l[0]
        g_l, g_r = encg_l[0] if encg_l is not None else (w_l, w_r)
        den = r * (g_l + g_r)
        s_cur = a1 / (a2 * abs(r * (g_l - g_r) / den) + a3) if abs(den) > 1e-9 else 0.0
    nxu = nyu = nzu = 0
    slip_state = slip_rows == "state"
    two_pi = 2.0 * math.pi
    dt_last, Qk, ab = -1.0, np.zeros((nx, nx)), [1.0] * nb
    potrf, potrs = lapack.dpotrf, lapack.dpotrs

    for k in range(n):
        gx, gy, gz = gyr_l[k]
        row_k = (math.nan, math.nan)
        x_fused = False
        if k > 0:
            # ------ prediction (26a)-(26b) with u(k-1) (imu_mean: mean of u(k-1), u(k)), from X(k-1|k-1) ------
            # (sf..cp, c11..c33 hold the trigonometry/DCM (2) of the posterior of step k-1)
            dt = t_l[k] - t_l[k - 1]
            ax, ay, az = accp_l[k - 1]
            ux, uy, uz = gyrp_l[k - 1]
            vdx = c11 * ax + c12 * ay + c13 * az  # eq. (10b): C A_B + G
            vdy = c21 * ax + c22 * ay + c23 * az
            c3a = c31 * ax + c32 * ay + c33 * az
            tt = st / ct
            qy = sf * uy + cf * uz
            phid = ux + tt * qy  # eq. (10c)
            thd = cf * uy - sf * uz  # eq. (10d)
            psid = qy / ct  # eq. (10e)
            if abs(dt - dt_last) > 1e-9 * dt:  # Q(k) for this dT (recomputed when dT changes)
                ab = [math.exp(-dt / gmj.tau) for gmj in gms]
                qb = [gmj.sigma**2 * (1.0 - aj * aj) for gmj, aj in zip(gms, ab)]
                Qk, dt_last = np.diag(q_const + q_dt2 * (dt * dt) + np.array([0.0] * 9 + qb + [0.0] * (nq + no))), dt
            if gms_l is not None:
                for j in range(nb):
                    Qk[9 + j, 9 + j] = gms_l[k][j] * (1.0 - ab[j] * ab[j])
            # F (20) with F_V (22) in rows 3-5 / cols 6-8 and I + dT F_Theta in rows/cols 6-8; a on b's diagonal
            fl = f_tmpl.copy()
            fl[i03] = fl[i14] = fl[i25] = dt
            fl[i36], fl[i37], fl[i38] = dt * (c13 * ay - c12 * az), dt * cp * c3a, -dt * vdy
            fl[i46], fl[i47], fl[i48] = dt * (c23 * ay - c22 * az), dt * sp * c3a, dt * vdx
            fl[i56], fl[i57] = dt * (c33 * ay - c32 * az), dt * (-ct * ax - st * sf * ay - st * cf * az)
            fl[i66], fl[i67] = 1.0 + dt * thd * tt, dt * psid / ct
            fl[i76] = -dt * psid * ct
            fl[i86], fl[i87] = dt * thd / ct, dt * psid * tt
            if no:  # odometer: d += dT (v_Bx + b_x), v_Bx at the trapezoid of the step (posterior k-1 attitude)
                od += dt * (c11 * vx + c21 * vy + c31 * vz + 0.5 * dt * (c11 * vdx + c21 * vdy + c31 * (c3a - g))
                            + (b[0] if nb else 0.0))
                fl[iod3], fl[iod4], fl[iod5] = dt * c11, dt * c21, dt * c31
                fl[iod7], fl[iod8] = dt * (-st * cp * vx - st * sp * vy - ct * vz), dt * (c11 * vy - c21 * vx)
                if iodb is not None:
                    fl[iodb] = dt
            for j in range(nb):
                fl[ib[j]] = ab[j]
                b[j] *= ab[j]
            F = np.array(fl).reshape(nx, nx)
            px += dt * vx
            py += dt * vy
            pz += dt * vz
            vx += dt * vdx
            vy += dt * vdy
            vz += dt * (c3a - g)
            phi += dt * phid
            th += dt * thd
            psi += dt * psid
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
            # H = [0, C^T, H_Theta] (23)-(25), one row per element, then the error-state columns
            h_x = (0.0, 0.0, 0.0, c11, c21, c31, 0.0, -st * cp * vx - st * sp * vy - ct * vz, c11 * vy - c21 * vx) + ex
            h_z = (0.0, 0.0, 0.0, c13, c23, c33, 0.0 if roll_model_jacobian and not use_vy else -vby, cf * vbx,
                   c13 * vy - c23 * vx) + zb + zq
            if enc_ok[k]:
                w_l, w_r = enc_l[k]
                if use_slip and not slip_state:  # eq. (14) on the slips of step k-1, signs from the current speeds
                    # (the cases of Sec. III-C's sentence: w_L <= w_R -> lambda_L <= 0 <= lambda_R; w_L > w_R -> the
                    # reverse; equal speeds belong to the first case for both wheels: slip.constrained_slip)
                    pl = (lam_l if lam_l > 0.0 else 0.0) if w_l > w_r else (lam_l if lam_l < 0.0 else 0.0)
                    pr = (lam_r if lam_r > 0.0 else 0.0) if w_l <= w_r else (lam_r if lam_r < 0.0 else 0.0)
                else:
                    pl = pr = 0.0
                y_x = 0.5 * r * ((w_l + w_r) - (pl * w_l + pr * w_r))  # eq. (13), y_M = 0
                if off_l is not None:
                    y_x -= off_l[k]
                if use_vy:
                    if encg_l is not None:  # (40) from the smoothed speeds (slip state: pl = pr = 0)
                        v_lx, v_rx = r * encg_l[k][0], r * encg_l[k][1]
                    else:
                        v_lx, v_rx = (1.0 - pl) * r * w_l, (1.0 - pr) * r * w_r
                    den = v_lx + v_rx
                    s_cur = a1 / (a2 * abs((v_lx - v_rx) / den) + a3) if abs(den) > 1e-9 else 0.0  # (40), (41)
                    y_y = -s_cur * (sf * gy + cf * gz) / ct  # eq. (15), x_M = 0, yaw rate (10e)
                    if offy_l is not None:
                        y_y -= offy_l[k]
                    h_y = (0.0, 0.0, 0.0, c12, c22, c32, vbz, sf * vbx, c12 * vy - c22 * vx) + ey + zq
                hs, inn, rows = [], [], []
                if no:  # the row's displacement over the window, fused at its end as the odometer
                    if y_x == y_x and not skip_l[k]:
                        z_acc += y_x * dt
                        n_acc += 1
                        if n_acc >= odo_window:
                            x_fused = True
                            hs.append(h_odo)
                            inn.append(z_acc - od)
                            rows.append(0)
                            nxu += 1
                    else:
                        n_acc = -1  # a hole in the window: restart it after this step
                elif y_x == y_x and not skip_l[k]:
                    x_fused = True
                    if nq:  # a fresh quantisation residual u_k (prior N(0, enc_quant^2)); row adds u_k - u_(k-1)
                        P[iqu, :] = 0.0
                        P[:, iqu] = 0.0
                        P[iqu, iqu] = var_q
                        qu = 0.0
                    hs.append(h_x)
                    inn.append(y_x - vbx - (b[0] if nb else 0.0) - (qu - qc if nq else 0.0))
                    rows.append(0)
                    nxu += 1
                y_fused = use_vy and not skipy_l[k]
                if y_fused:
                    hs.append(h_y)
                    inn.append(y_y - vby - (b[1] if nb else 0.0))
                    rows.append(1)
                    nyu += 1
                row_k = (y_x if x_fused else math.nan, y_y if y_fused else math.nan)
                hs.append(h_z)
                inn.append(-vbz)  # v_Bz = 0 (11)
                rows.append(2)
                H = np.array(hs)
                innov = np.array(inn)
                r_mat, r_k = r_sets[tuple(rows)]
                if adaptive_vx and x_fused:  # the v_x row is the first of the fused rows
                    r_k = r_k.copy()
                    r_k[0] = r_vx[k] = r_x_cur
                    r_mat = np.diag(r_k)
            else:
                H = np.array((h_z,))
                innov = np.array((-vbz,))
                r_mat, r_k = r_sets[(2,)]
                n_acc = -1
            nzu += 1
            # ---------------- correction (26c)-(26f) ------------------------------------
            PHt = P @ H.T
            S = H @ PHt + r_mat  # (26e)
            L, info = potrf(S, lower=1)
            d = L.diagonal().tolist()
            if info != 0 or not (all(v > 0.0 for v in d) and math.isfinite(sum(d))):
                raise FilterDivergence(where, k, t_l[k], f"innovation covariance S (26e) not positive definite: {S.tolist()}")
            K = potrs(L, PHt.T, lower=1)[0].T  # (26d): W = P H^T S^-1
            IKH = Ix - K @ H
            if store_lin:  # error recursion e_k = (I - K H)(F e + w) + K v, with P the prior F P F^T + Q here
                lin_a.append(IKH @ F)  # the Gauss-Markov states' driving noise (Q diagonal) apart: shared by seeds
                q_run = np.diag(Qk).copy()
                lin_s.append(IKH[:, 9:9 + nb] * np.sqrt(q_run[9:9 + nb]))
                q_run[9:9 + nb] = 0.0
                lin_c.append((IKH * q_run) @ IKH.T + (K * r_k) @ K.T)
            P = IKH @ P @ IKH.T + (K * r_k) @ K.T  # Joseph form (26f)
            P = 0.5 * (P + P.T)
            kin = K @ innov
            dx = kin.tolist()  # (26c)
            if adaptive_vx and x_fused:  # post-fit residual of the v_x row (linear in dx) and h P+ h^T
                h0 = H[0]
                eps = inn[0] - float(h0 @ kin)
                ad_terms.append(eps * eps + float(h0 @ P @ h0))
                if 4 * len(ad_terms) >= adaptive_vx:
                    r_x_cur = max(adaptive_floor**2, math.fsum(ad_terms) / len(ad_terms))
            px += dx[0]
            py += dx[1]
            pz += dx[2]
            vx += dx[3]
            vy += dx[4]
            vz += dx[5]
            phi += dx[6]
            th += dx[7]
            psi += dx[8]
            for j in range(nb):
                b[j] += dx[9 + j]
            if nq and x_fused:  # u_k becomes the previous residual of the next v_x row
                qc = qu + dx[iqu]
                P = shift_q @ P @ shift_q.T
                P[iqu, iqu] = var_q
            elif nq:  # no v_x row: the next row's u_(k-1) is a fresh residual, independent of the states
                P[iqc, :] = 0.0
                P[:, iqc] = 0.0
                P[iqc, iqc] = var_q
                qc = 0.0
            if no:
                od += dx[iod]
                if x_fused or n_acc < 0:  # window closed (fused or broken): the odometer restarts at 0, known
                    od = z_acc = 0.0
                    n_acc = 0
                    P[iod, :] = 0.0
                    P[:, iod] = 0.0
                    if store_lin:  # the reset in the error recursion: d's error is 0 after it
                        lin_a[-1][iod, :] = 0.0
                        lin_c[-1][iod, :] = 0.0
                        lin_c[-1][:, iod] = 0.0
                        lin_s[-1][iod, :] = 0.0
            if not math.isfinite(px + py + pz + vx + vy + vz + phi + th + psi + sum(b)):
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
        out.append((px, py, pz, vx, vy, vz, phi, th, psi, vbx, vby, vbz, psid, sl_l, sl_r, s_cur, *row_k, *b))
        if store_cov:
            covs.append(P)
        if store_lin:
            lin_p.append(P)
            if k == 0:  # e_0 ~ N(0, P0): the Gauss-Markov states' part and that of shared_init are shared
                lin_a.append(Ix)
                lin_c.append(np.zeros((nx, nx)))
                lin_s.append(Ix[:, 9:9 + nb] * np.sqrt(np.diag(P)[9:9 + nb]))
                rest = [j for j in range(nx) if j not in shared_init]
                if shared_init and np.any(P[np.ix_(shared_init, rest)] != 0.0):
                    raise ValueError(f"run_filter_gm: P0 couples the shared_init states {shared_init} with the others")
                shared0 = np.zeros((nx, 9))  # column j: navigation state j (zero where per run), in every run
                if shared_init:
                    blk = P[np.ix_(shared_init, shared_init)]  # diagonal: column j is state j's sd
                    shared0[np.ix_(shared_init, shared_init)] = (np.diag(np.sqrt(np.diag(blk)))
                                                                 if np.count_nonzero(blk - np.diag(np.diag(blk))) == 0
                                                                 else np.linalg.cholesky(blk))

    o = np.array(out, dtype=float).reshape(n, 18 + nb)
    s_icr = o[:, 15] if use_vy else np.full(n, np.nan)
    lin = None
    if store_lin:
        lin = Linearisation(np.array(lin_a), np.array(lin_c), np.array(lin_p), np.array(lin_s) if nb else None,
                            shared0 if shared_init else None)
    res = FilterResult(t.copy(), o[:, :9], o[:, 9:12], o[:, 12], o[:, 13:15], s_icr, (nxu, nyu, nzu),
                       np.array(covs) if store_cov else None, lin, r_vx)
    return res, o[:, 18:], o[:, 16:18]
