"""Yu 2010 reproduction, Figs. 18-20: hill climbing on three ramps (holds its speed / decelerates / fails to
climb), the motor saturation and power limits of the model (eq. (27), Sec. V-B) against the testbed.

W. Yu, O. Y. Chuy Jr., E. G. Collins Jr., P. Hollis, "Analysis and Experimental Verification for
Dynamic Modeling of a Skid-Steered Wheeled Vehicle," IEEE Transactions on Robotics, vol. 26,
no. 2, pp. 340-353, April 2010, doi:10.1109/TRO.2010.2042540.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from bench.registry import calibrate
from bench.run import encoder_count_speed
from methods.yu2010.plugin import Yu2010
from methods.yu2010.repro.figures import _new_figure, _save
from methods.yu2010.repro.runs import RAMPS, _predict, calibrated, experiments

TAIL = 0.5  # [s] the outcome is read from the mean over the run's last half second
OUTCOMES = ("holds", "decelerates", "fails", "other")


def ramp_outcome(t: np.ndarray, v: np.ndarray, w: np.ndarray, w_cmd: float, v0: float, resolution: float,
                 tail: float = TAIL) -> tuple[str, float]:
    """Outcome of a hill climb (Figs. 18-20, Yu's three cases) from the vehicle speed ``v`` [m/s] and the mean
    wheel speed ``w`` [rad/s] of both sides: ``fails`` when the final vehicle speed (mean of the last ``tail`` s)
    is <= 0 (it stops or slides back); ``holds`` ("traverse a ramp at the commanded velocity") when the final
    wheel speed is within ``resolution`` (one encoder count per sample: what the speed loop resolves) of the
    commanded wheel speed ``w_cmd``; ``decelerates`` when it ends below its initial speed ``v0``; else
    ``other``.  Returns (outcome, final vehicle speed)."""
    last = t >= t[-1] - tail
    v_end = float(np.mean(v[last]))
    w_end = float(np.mean(w[last]))
    if v_end <= 0.0:
        return "fails", v_end
    if abs(w_end - w_cmd) <= resolution:
        return "holds", v_end
    if v_end < v0:
        return "decelerates", v_end
    return "other", v_end


# ----------------------------------------------------------------------------------- Figs. 18-20
def fig18_20(ctx: Any) -> dict[str, float]:
    """Figs. 18-20: three ramps; the testbed's and the model's outcome (holds speed / decelerates /
    fails to climb).  Model: the vinyl calibration with the ramp's slope (known to the
    experimenter) and the surface's mu_roll calibrated on a flat straight run of that surface."""
    ex = experiments(ctx)
    cal = calibrated(ctx)
    out: dict[str, float] = {}
    curves = {}
    texts = []
    for key, (scn_name, expected) in RAMPS.items():
        scn = ex.scenarios[scn_name]
        flat = calibrate(Yu2010(cal.model.params), [ex.flat_cal[key]])
        mu_roll = flat.params.mu_roll
        model = Yu2010(cal.model.params.replace(mu_roll=mu_roll, slope=scn.terrain.slope, n_table=2048))
        run, est = _predict(ctx, model, scn_name)
        t = run.t
        v_cmd = float(scn.command.segments[-1].a)
        w_cmd = 0.5 * float(run.samples("cmd_wl")[1][-1] + run.samples("cmd_wr")[1][-1])  # final commanded wheel speed
        v0 = float(scn.initial_speed)
        res = encoder_count_speed(run) or 0.0
        tb_out, tb_v = ramp_outcome(t, run["truth_vx"], 0.5 * (run["truth_wl"] + run["truth_wr"]), w_cmd, v0, res)
        md_out, md_v = ramp_outcome(est.t, est["vx"], 0.5 * (est["wl"] + est["wr"]), w_cmd, v0, res)
        out[f"{key}_mu_roll"] = mu_roll
        out[f"{key}_v0"] = v0
        out[f"{key}_v_cmd"] = v_cmd
        out[f"{key}_v_final_tb"] = tb_v
        out[f"{key}_v_final_model"] = md_v
        out[f"{key}_outcome_tb"] = float(OUTCOMES.index(tb_out))
        out[f"{key}_outcome_model"] = float(OUTCOMES.index(md_out))
        out[f"{key}_{expected}_tb"] = float(tb_out == expected)
        out[f"{key}_{expected}_model"] = float(md_out == expected)
        out[f"{key}_model_predicts"] = float(md_out == tb_out)
        if key == "wood":  # the same prediction without the motor power limit
            free = Yu2010(model.params.replace(P_max=0.0), use_run_platform=False)
            _, est_free = _predict(ctx, free, scn_name)
            out["wood_v_final_model_no_power_limit"] = float(np.mean(est_free["vx"][est_free.t >= t[-1] - TAIL]))
            out["wood_err_model"] = abs(md_v - tb_v)
            out["wood_err_model_no_power_limit"] = abs(out["wood_v_final_model_no_power_limit"] - tb_v)
        if key == "whiteboard":
            terr = run.meta["terrain"]
            out["whiteboard_mu_sa_tb"] = float(terr["mu_sa"])
            out["whiteboard_tan_slope"] = math.tan(scn.terrain.slope)
        out["encoder_resolution"] = res
        curves[key] = (scn, t, run["truth_vx"], est.t, est["vx"], tb_out, md_out)
        texts.append(f"{key} {math.degrees(scn.terrain.slope):.1f} deg (Yu: {expected}): testbed {tb_out} "
                     f"({tb_v:.3f} m/s), model {md_out} ({md_v:.3f} m/s)")
    out["all_tb"] = float(all(out[f"{k}_{e}_tb"] for k, (_, e) in RAMPS.items()))
    out["all_model"] = float(all(out[f"{k}_{e}_model"] for k, (_, e) in RAMPS.items()))
    summary = "; ".join(texts) + "."
    q = cal.model.params.with_platform(ex.scored[RAMPS["wood"][0]].meta["platform"])
    ctx.note("fig18_20", (
        f"{summary} Outcomes from the last {TAIL} s: fails = vehicle speed <= 0; holds = mean wheel speed within "
        f"one encoder count per sample ({out['encoder_resolution']:.4f} rad/s) of the commanded wheel speed; "
        "decelerates = vehicle speed below the initial speed. The model's power limit "
        f"(P_max = {q.P_max:g} W per motor, from the platform's motor) makes it decelerate on 15 deg; without it "
        f"the model would end at {out['wood_v_final_model_no_power_limit']:.3f} m/s (voltage-limited). The model "
        "rolls without slip on a slope (Sec. III-B: F_f = 0) and has no traction limit, so the white board's "
        "failure -- on the testbed the vehicle slides back because its friction mu_sa = "
        f"{out['whiteboard_mu_sa_tb']:g} < tan 13.5 deg = {out['whiteboard_tan_slope']:.3f} -- cannot appear in it: "
        "it predicts a power-limited climb."
    ))
    fig = _new_figure(12, 3.4)
    for k, (key, (scn, t, v_tb, te, v_md, tb_out, md_out)) in enumerate(curves.items()):
        ax = fig.add_subplot(1, 3, k + 1)
        ax.plot(t, v_tb, label=f"testbed ({tb_out})")
        ax.plot(te, v_md, "--", label=f"model ({md_out})")
        ax.axhline(float(scn.command.segments[-1].a), color="k", lw=0.5, label="command")
        ax.set_title(f"Fig. {18 + k}: {key}, {math.degrees(scn.terrain.slope):.1f} deg", fontsize=9)
        ax.set_xlabel("t [s]")
        ax.set_ylabel("vehicle speed [m/s]")
        ax.legend(fontsize=7)
        ax.grid(True, alpha=0.3)
    _save(ctx, fig, "fig18_20.png", "Figs. 18-20: hill climbing on three ramps, testbed vs model")
    return out
