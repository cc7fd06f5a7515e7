"""Yu 2010 reproduction, Figs. 10-13: circle at 0.2 m/s, R = 4 m, from rest (wheel speeds, torques, path,
X/Y errors): the closed-loop model (eqs. (25)-(27), Fig. 4 PID) calibrated on the sweep vs the testbed.

W. Yu, O. Y. Chuy Jr., E. G. Collins Jr., P. Hollis, "Analysis and Experimental Verification for
Dynamic Modeling of a Skid-Steered Wheeled Vehicle," IEEE Transactions on Robotics, vol. 26,
no. 2, pp. 340-353, April 2010, doi:10.1109/TRO.2010.2042540.
"""
from __future__ import annotations

from typing import Any

import numpy as np

from bench.registry import estimate
from methods.yu2010.plugin import Yu2010OpenLoop
from methods.yu2010.repro.figures import _figure_dynamic
from methods.yu2010.repro.runs import _predict, _rms, calibrated

ACCEL_PHASE = 1.0  # [s] Yu's "acceleration phase of the motion (< 1 s)" (Sec. V-A)
# [s] windows from the start over which closed_beats_open_yaw_rate's ratio is also reported: Yu gives no run length
# for Figs. 10-13 and the verdict is over the scenario's whole run (circle_vinyl.toml), so the note says how it moves
YAW_RATE_WINDOWS = (5.0, 10.0)


def fig10_13(ctx: Any) -> dict[str, float]:
    """Figs. 10-13: circle at 0.2 m/s, R = 4 m, from rest: closed-loop prediction vs testbed, and the open loop
    (the testbed's measured torques replayed, as Fig. 16 does on the straight) for the abstract's comparison of
    the linear and angular velocities."""
    from bench.metrics import Trajectory, final_position_error

    cal = calibrated(ctx)
    run, est = _predict(ctx, cal.model, "circle_vinyl")
    opened = estimate(Yu2010OpenLoop(cal.model.params), run)
    t = run.t
    enc = np.isfinite(run["enc_wl"])
    tq = np.isfinite(run["tau_l"])
    e_wl = (est["wl"] - run["enc_wl"])[enc]
    e_wr = (est["wr"] - run["enc_wr"])[enc]
    acc = t[enc] < ACCEL_PHASE
    steady_tq = tq & (t >= t[-1] - 0.25 * (t[-1] - t[0]))
    ref = Trajectory.from_run(run, "truth")
    traj = Trajectory.from_estimate(est)
    path = float(np.sum(np.hypot(np.diff(run["truth_x"]), np.diff(run["truth_y"]))))
    out = {
        "rms_vx": _rms(est["vx"] - run["truth_vx"]),
        "rms_wz": _rms(est["wz"] - run["truth_wz"]),
        "rms_vx_open": _rms(opened["vx"] - run["truth_vx"]),
        "rms_wz_open": _rms(opened["wz"] - run["truth_wz"]),
        "rms_wl": _rms(e_wl), "rms_wr": _rms(e_wr),
        "rms_w_accel": _rms(np.concatenate([e_wl[acc], e_wr[acc]])),
        "rms_w_steady": _rms(np.concatenate([e_wl[~acc], e_wr[~acc]])),
        # against the true wheel speeds: the encoders' own differencing lag in the acceleration phase exceeds the
        # model's steady error, so against them any prediction would be worse while accelerating
        "rms_w_accel_truth": _rms(np.concatenate([(est[w] - run[f"truth_{w}"])[t < ACCEL_PHASE] for w in ("wl", "wr")])),
        "rms_w_steady_truth": _rms(np.concatenate([(est[w] - run[f"truth_{w}"])[t >= ACCEL_PHASE] for w in ("wl", "wr")])),
        "rms_w_accel_encoder_vs_truth": _rms(np.concatenate(
            [(run[f"enc_{w}"] - run[f"truth_{w}"])[enc & (t < ACCEL_PHASE)] for w in ("wl", "wr")])),
        "rms_tau_l": _rms((est["tau_l"] - run["tau_l"])[tq]),
        "rms_tau_r": _rms((est["tau_r"] - run["tau_r"])[tq]),
        "tb_tau_l_steady": float(np.mean(run["tau_l"][steady_tq])),
        "tb_tau_r_steady": float(np.mean(run["tau_r"][steady_tq])),
        "model_tau_l_steady": float(np.mean(est["tau_l"][steady_tq])),
        "model_tau_r_steady": float(np.mean(est["tau_r"][steady_tq])),
        "final_pos_err": final_position_error(ref, traj),
        "path_length": path,
    }
    out["final_pos_err_rel"] = out["final_pos_err"] / path
    for w in YAW_RATE_WINDOWS:
        m = t < t[0] + w
        out[f"ratio_wz_first_{w:g}s"] = (_rms((est["wz"] - run["truth_wz"])[m])
                                         / _rms((opened["wz"] - run["truth_wz"])[m]))
    ctx.note("closed_beats_open_yaw_rate", (
        f"Over the whole {t[-1] - t[0]:.0f} s run: closed {out['rms_wz']:.4f}, open {out['rms_wz_open']:.4f} rad/s. "
        "Yu gives no run length for Figs. 10-13 and the verdict depends on it: the closed/open ratio over the first "
        + ", ".join(f"{w:g} s is {out[f'ratio_wz_first_{w:g}s']:.2f}" for w in YAW_RATE_WINDOWS)
        + ". The closed loop's yaw error is its alpha (eq. (1)) against the testbed's turn; the open loop's speed "
        "drifts with the resistance mismatch at R = 4 m and crosses the true yaw rate on the way, so it is close "
        "early and far late."))
    ctx.note("fig10_13", (
        "Model calibrated on the sweep (Table I, N = 31) and scored on this separate run. The model's vehicle "
        "speed is r (w_l + w_r)/2 with the nominal radius (eq. (1)); the testbed's tires roll at their loaded radius (~0.995 r), so "
        "part of the velocity error and most of the along-track drift of the path (Figs. 12-13) is that radius "
        "effect, which the model does not have. rms_w_accel is over Yu's acceleration phase (t < 1 s), "
        "rms_w_steady after it, against the encoders; the claim reads the *_truth pair (against the true wheel "
        f"speeds): the encoders' own error while accelerating, {out['rms_w_accel_encoder_vs_truth']:.4f} rad/s, "
        f"exceeds the model's steady one against them, {out['rms_w_steady']:.4f}. Against the true speeds any "
        "prediction that settles on the command has a near-zero steady error (the testbed's PID drives the wheels "
        "there): the claim fails only for a model that follows the start-up transient as well as the steady state. The *_open rows replay the testbed's logged torques in the same model without "
        "the PID (Fig. 16's open loop; the paper shows it on the straight only)."
    ))
    _figure_dynamic(ctx, run, est, "fig10_13.png",
                    "Figs. 10-13: circle 0.2 m/s, R = 4 m: wheel speeds, torques, path and X/Y errors, "
                    "testbed vs model")
    return out
