"""The consistent configuration's noise, identified on calibration runs against the reference sensor (not Yi's).

:func:`identify_yi_noise`: the IMU's white noise and levelling precision from the rest at the start, the traction
slip of the v_x row and the S correction of the v_y row, and the white + Gauss-Markov models of the rows' errors,
from the rows the filter fuses compared with the reference body velocity (never the truth, never a scored run).
"""
from __future__ import annotations

import math
from dataclasses import asdict, replace
from typing import Any, Callable, NamedTuple, Sequence

import numpy as np

from bench.run import Run
from methods.yi2009.consistent.filter import run_filter_gm
from methods.yi2009.consistent.gauss_markov import (GaussMarkov, _row_gms, gauss_markov_fit, gm_sigma_steps,
                                                    yaw_rate_scale)
from methods.yi2009.consistent.initial import _initial_state_consistent
from methods.yi2009.consistent.reference import (reference_body_velocity, reference_smoothing_bias,
                                                 reference_velocity_noise_mean_var)
from methods.yi2009.consistent.rows import (IcrCorrection, TractionSlip, _gamma_wheel_speeds, _row_offsets,
                                            fit_icr_correction, fit_traction_slip, icr_features, traction_features)
from methods.yi2009.consistent.sensors import _moving, _no_slip_speed, encoder_white_floor, static_imu_noise
from methods.yi2009.ekf import EkfParams, Yi2009Ekf, _geometry, align_inputs
from methods.yi2009.s_gamma import REF_CHANNELS

def _rel_change(new: GaussMarkov | None, old: GaussMarkov | None) -> float:
    if new is None or old is None:
        return 0.0
    return max(abs(new.sigma - old.sigma) / old.sigma, abs(new.tau - old.tau) / old.tau)


class _CalibrationRun(NamedTuple):
    """A calibration run's filter inputs and reference quantities, computed once for all passes of
    :func:`identify_yi_noise`."""

    run: Run
    r: float
    track: float
    t: np.ndarray
    acc: np.ndarray
    gyr: np.ndarray
    enc: np.ndarray
    vx: np.ndarray  # reference body velocity on the filter grid
    vy: np.ndarray
    dt: float
    ref_noise: Callable[[int], float]  # reference_velocity_noise_mean_var (v_x)
    ref_noise_y: Callable[[int], float]  # reference_velocity_noise_mean_var with the yaw rotation (v_y)
    mask: np.ndarray  # encoders finite, after the settle time, inside the reference
    moving: np.ndarray  # mask and a wheel turning
    opts: dict[str, Any]  # the model's run_filter_gm options
    yaw_scale: np.ndarray  # yaw_rate_scale of the run (per_yaw_rate Gauss-Markov errors)
    x0: np.ndarray  # initial state and covariance of the consistent filter (_initial_state_consistent)
    p0: np.ndarray


def identify_yi_noise(runs: Sequence[Run], model: "Yi2009Ekf", settle: float = 1.0,
                      windows: Sequence[float] = (2.0, 4.0, 8.0, 16.0), max_iterations: int = 8, tol: float = 0.05
                      ) -> tuple[EkfParams, GaussMarkov, GaussMarkov | None, TractionSlip | None,
                                 IcrCorrection | None, dict[str, Any]]:
    """Noise of the consistent configuration identified on calibration runs with the reference sensor
    (never the truth, never a scored run).

    1. IMU white noise per sample from the initial rest (:func:`static_imu_noise`) -> ``accel_noise``,
       ``gyro_noise`` (Q of V and Theta), and ``p0_rollpitch`` = accel_noise / (g sqrt(level_samples)), the
       precision of the static levelling (used only when a run starts at rest, see :class:`Yi2009EkfConsistent`).
       When no calibration run starts at rest (e.g. the league's calibration set) the model's ``accel_noise`` /
       ``gyro_noise`` and P0 are kept (``info["imu_noise_source"]`` = "paper default", else "rest").
    2. The v_x (13) and, for scheme 3, v_y (15) pseudo-measurement errors as white + Gauss-Markov
       (:func:`gauss_markov_fit`, moving-mean variances over ``windows`` s): the augmented filter
       (:func:`run_filter_gm`, with the model's :meth:`Yi2009EkfConsistent.filter_options`) is run on each run and
       the rows it fused are compared with the reference body velocity (:func:`reference_body_velocity`, its
       smoothing error at speed and turn changes predicted from the gyro and encoders and removed,
       :func:`reference_smoothing_bias`; ``info["reference_bias_rms"]``: RMS of that correction (v_x, v_y)) on the
       filter's time grid; steps without a fused row, before ``settle`` s or outside the reference are NaN.  The
       known parts of the residual are subtracted at every window: the reference derivative's noise
       (:func:`reference_velocity_noise_mean_var`, rotated into the body frame at the run's gyro yaw rates on the
       used steps; not rotated with ``model.reference_turn_noise`` False) and, with quantisation states, the
       encoder quantisation u_k - u_(k-1) (variance 2 enc_quant^2 / W^2 for a W-sample mean: it telescopes).
       The white part is floored
       at a physical bound: v_x row :func:`encoder_white_floor` (without quantisation states; with them the
       quantisation is the states'), v_y row gyro_noise x the RMS of the row's gain from the yaw rate (S(gamma),
       plus :meth:`IcrCorrection.gyro_gain` with the S correction) on the moving steps.  Steps with the wheels at rest
       (r|w| < min_wheel_speed) count as zero error (the row is exact at standstill: both sides 0); steps whose v_x
       row is not fused (traction transients, ``vx_skip`` of the model's options) are NaN.  With
       ``model.vy_per_yaw_rate`` the v_y row's model is per yaw rate (:func:`gauss_markov_fit` with
       :func:`yaw_rate_scale` as the scale; its sigma in m per rad/s).  Repeated until
       sigma and tau of every row change by less than ``tol`` (relative) between passes, at most
       ``max_iterations`` passes (with slip feedback (13)-(14) the fused row depends on the filter's own velocity);
       the first pass starts from the paper's sigmas as white parts and sigma = 0.05 m/s, tau = 1 s.  ``info``
       reports every pass, the last relative change and whether it converged.
    0. With ``model.traction_slip`` (slip as a state only): the traction slip of the v_x row (:class:`TractionSlip`)
       is fitted first (:func:`fit_traction_slip`, no-slip row r (w_L + w_R)/2 minus the reference v_x on the
       moving steps after ``settle`` outside the traction transients) and subtracted from the row in step 2
       (``vx_offset``), so that the Gauss-Markov state carries only the rest of the row's error.  With
       ``model.icr_correction`` (scheme 3, slip
       state): pass 0 fuses the uncorrected v_y row (15); the S correction (:class:`IcrCorrection`) is fitted on its
       residual against the reference on the moving steps (:func:`fit_icr_correction`; the row (15) with the slip
       as a state depends on the encoders and the gyro only) and subtracted from it before that pass's Gauss-Markov
       fit and from the row in later passes (``vy_offset``).
    sigma_vz (11) is the paper's (the reference is planar: no v_z reference).
    Returns (params, gm_x, gm_y (scheme 3, else None), traction (None without ``model.traction_slip``), icr (None
    without ``model.icr_correction``), info)."""
    if not runs:
        raise ValueError(f"{model.name}: identify_yi_noise needs at least one calibration run")
    if max_iterations < 1:
        raise ValueError(f"{model.name}: identify_yi_noise max_iterations = {max_iterations!r}: must be >= 1")
    for run in runs:
        run.require(model.requires | frozenset(REF_CHANNELS), f"{model.name} (calibration)")
    imu = static_imu_noise(runs, required=False)
    if imu is not None:
        sa, sg, n_static = imu
        params = replace(model.params, accel_noise=sa, gyro_noise=sg,
                         p0_rollpitch=sa / (model.params.gravity * math.sqrt(max(model.params.level_samples, 1))))
    else:
        n_static, params = 0, model.params
    r0 = _geometry(runs[0])[0]
    floor_x, floor_src = encoder_white_floor(runs[0])
    gm_x = GaussMarkov(0.05, 1.0, r0 * model.params.sigma_enc)
    gm_y = GaussMarkov(0.05, 1.0, model.params.sigma_vy) if model.variant == 3 else None
    info: dict[str, Any] = {"calibration_runs": [r.id for r in runs], "accel_noise": params.accel_noise,
                            "gyro_noise": params.gyro_noise, "static_samples": n_static,
                            "p0_rollpitch": params.p0_rollpitch,
                            "imu_noise_source": "rest" if imu is not None else "paper default",
                            "vx_white_floor": floor_x, "vx_white_floor_source": floor_src}
    # everything that does not depend on the filter's pass, once per run: inputs, reference body velocity, its noise
    cal, ref_bias = [], []
    for run in runs:
        r, track = _geometry(run)
        t, acc, gyr, enc = align_inputs(run)
        vx, vy, _ = reference_body_velocity(run, t)
        bx, by = reference_smoothing_bias(run, t, gyr, enc, r)
        vx, vy = vx - bx, vy - by
        ref_bias.append(np.column_stack((bx, by))[np.isfinite(vx)])
        dt_run = float(np.median(np.diff(t)))
        m = np.isfinite(enc).all(axis=1) & (t >= t[0] + settle) & np.isfinite(vx)
        x0, p0 = _initial_state_consistent(acc, enc, r, params, model.initial_pose, model.params.p0_rollpitch,
                                           getattr(model, "start_yaw_sd", None))
        speed_ms = float(np.mean(np.square(_no_slip_speed(enc, r)[m]))) if m.any() else 0.0
        turn_rates = gyr[m, 2] if getattr(model, "reference_turn_noise", True) else None
        cal.append(_CalibrationRun(run, r, track, t, acc, gyr, enc, vx, vy, dt_run,
                                   reference_velocity_noise_mean_var(run, dt_run, yaw_rates=turn_rates),
                                   reference_velocity_noise_mean_var(run, dt_run, speed_ms=speed_ms,
                                                                     yaw_rates=turn_rates), m,
                                   m & _moving(enc, r, model.params.min_wheel_speed),
                                   model.filter_options(run, t, acc, enc, odometer=False),  # the rows of every step
                                   yaw_rate_scale(gyr, t),
                                   x0, p0))
    dt = float(np.median([c.dt for c in cal]))
    info["reference_bias_rms"] = np.sqrt(np.mean(np.square(np.vstack(ref_bias)), axis=0)).tolist()
    traction = None
    if getattr(model, "traction_slip", False):
        res_t = [np.where(c.moving & ~c.opts["vx_skip"], _no_slip_speed(c.enc, c.r) - c.vx, np.nan) for c in cal]
        traction, fit_info = fit_traction_slip(res_t, [traction_features(c.acc, c.gyr) for c in cal], dt)
        info["traction"] = {**asdict(traction), **fit_info}
    offsets = [_row_offsets(traction, None, c.acc, c.gyr, c.enc, c.r, model.params)[0] for c in cal]

    def known_x(w: int) -> float:  # reference noise + quantisation (u_k - u_(k-1): its W-mean telescopes)
        return float(np.mean([c.ref_noise(w) + 2.0 * c.opts["enc_quant"] * c.opts["enc_quant"] / (w * w) for c in cal]))

    def known_y(w: int) -> float:  # reference noise
        return float(np.mean([c.ref_noise_y(w) for c in cal]))

    want_icr = model.variant == 3 and bool(getattr(model, "icr_correction", False))
    icr: IcrCorrection | None = None
    offsets_y: list[np.ndarray | None] = [None] * len(cal)
    change, it = math.inf, 0
    for it in range(max_iterations):
        res_x: list[np.ndarray] = []
        res_y: list[np.ndarray] = []
        s_runs: list[np.ndarray] = []  # S(gamma) of (15) per run (scheme 3)
        for i, (c, off) in enumerate(zip(cal, offsets)):
            fr, _, fused = run_filter_gm(c.t, c.acc, c.gyr, c.enc, wheel_radius=c.r, track=c.track,
                                         variant=model.variant, s_gamma=model.s_gamma, params=params, x0=c.x0,
                                         p0=c.p0, gm_x=gm_x, gm_y=gm_y, where=c.run.where, vx_offset=off,
                                         vy_offset=offsets_y[i],
                                         gm_sigma=gm_sigma_steps(_row_gms(gm_x, gm_y, model.variant), c.yaw_scale),
                                         **c.opts)
            y_x, y_y = fused[:, 0], fused[:, 1]
            res_x.append(np.where(c.mask & np.isfinite(y_x), np.where(c.moving, y_x - c.vx, 0.0), np.nan))
            if model.variant == 3:
                res_y.append(np.where(c.mask, np.where(c.moving, y_y - c.vy, 0.0), np.nan))
                s_runs.append(fr.s_icr)
        if want_icr and icr is None:  # pass 0 fused the uncorrected row (15): fit the S correction on its residual
            feats = [icr_features(c.gyr, _gamma_wheel_speeds(c.opts, c.enc), c.r) for c in cal]
            icr, icr_info = fit_icr_correction([np.where(c.moving, e, np.nan) for c, e in zip(cal, res_y)], feats, dt)
            info["icr"] = {**asdict(icr), **icr_info}
            offsets_y = [_row_offsets(None, icr, c.acc, c.gyr, c.enc, c.r, model.params, _gamma_wheel_speeds(c.opts, c.enc))[1]
                         for c in cal]
            res_y = [e - o for e, o in zip(res_y, offsets_y)]  # the row the next passes fuse (its S is not filtered)

        new_x = gauss_markov_fit(res_x, dt, windows, known_x, floor_x if not model.quantisation_states else 0.0)
        new_y = None
        if model.variant == 3:  # the gyro's white noise through the row: RMS of its gain d y_y / d w_z x gyro_noise
            gain = [np.where(c.moving, s_ + (icr.gyro_gain(c.gyr, _gamma_wheel_speeds(c.opts, c.enc), c.r) if icr else 0.0), np.nan)
                    for c, s_ in zip(cal, s_runs)]
            gain_all = np.concatenate(gain)  # (no moving step: no floor)
            floor_y = (float(np.sqrt(np.nanmean(gain_all**2))) * params.gyro_noise
                       if np.isfinite(gain_all).any() else 0.0)
            info["vy_white_floor"] = floor_y
            scale = [c.yaw_scale for c in cal] if getattr(model, "vy_per_yaw_rate", False) else None
            new_y = gauss_markov_fit(res_y, dt, windows, known_y, floor_y, scale=scale)
        change = max(_rel_change(new_x, gm_x), _rel_change(new_y, gm_y))
        gm_x, gm_y = new_x, new_y
        info[f"iteration{it}"] = {**{k: asdict(v) for k, v in (("vx", gm_x), ("vy", gm_y)) if v is not None},
                                  "change": change}
        if it > 0 and change < tol:
            break
    info.update({"vx": asdict(gm_x), "vy": asdict(gm_y) if gm_y is not None else None, "filter_dt": dt,
                 "iterations": it + 1, "last_change": change, "converged": bool(it > 0 and change < tol)})
    return params, gm_x, gm_y, traction, icr, info
