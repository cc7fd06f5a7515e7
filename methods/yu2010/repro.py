"""Reproduction of Yu 2010 on the skidbench testbed: Table I, Figs. 9-29 and Wang 2015 Fig. 5.

W. Yu, O. Y. Chuy Jr., E. G. Collins Jr., P. Hollis, "Analysis and Experimental Verification for
Dynamic Modeling of a Skid-Steered Wheeled Vehicle," IEEE Transactions on Robotics, vol. 26,
no. 2, pp. 340-353, April 2010, doi:10.1109/TRO.2010.2042540.
Wang 2015 Fig. 5: T. Wang, Y. Wu, J. Liang, C. Han, J. Chen, Q. Zhao, "Analysis and Experimental
Kinematics of a Skid-Steering Wheeled Robot Based on a Laser Scanner Sensor," Sensors 15(5),
pp. 9681-9702, 2015, doi:10.3390/s150509681 (Sec. 2.2, built on Yu's model).

Declared in ``scenarios/papers/yu2010.toml``; each function below is ``compute(ctx) -> metrics``
(:mod:`bench.reproduce`).  Paper item -> function:

  Table I, eq. (28), Sec. V-A (K, mu_sa, mu_op vs N; mu_roll, alpha) ... :func:`table1`
  Fig. 9   steady torque vs commanded radius ............................ :func:`fig9`
  Figs. 10-13  circle 0.2 m/s, R = 4 m (wheel speed, torque, path) ..... :func:`fig10_13`
  Figs. 14-16  straight 0.2 m/s, closed vs open loop ................... :func:`fig14_16`
  Fig. 17  1.5 m/s command, saturation ................................. :func:`fig17`
  Figs. 18-20  three ramps (holds / decelerates / fails) ............... :func:`fig18_20`
  Figs. 21-29  partial lemniscate, eqs. (29)-(30) ...................... :func:`fig22_29`
  Wang 2015 Fig. 5  chi vs curvature ratio from the steady state ....... :func:`wang_fig5`

Calibration runs and scored runs are different runs (DESIGN.md): the model is calibrated on the
31-radius sweep (``yu_radius_sweep``, one run per commanded radius of Sec. V-A) plus a straight
constant-speed run at 0.3 m/s for mu_roll (Sec. V-A), and on flat straight runs of each ramp's
surface for that surface's mu_roll; it is scored on the circle, the 0.2 and 1.5 m/s straight
runs, the ramps and the lemniscate, through :func:`bench.registry.calibrate` /
:func:`bench.registry.estimate` (truth withheld, scoring a calibration run refused).  The
lemniscate uses Yu's published Sec. V-C parameters instead of a calibration; it is run as the
scenario ``yu_lemniscate`` declares it and once more from curve time
:data:`~methods.yu2010.commands.LEMNISCATE_TAU0` (the plugin's reading of Fig. 21).
Metrics and figures may read the testbed's truth (velocities, pose, terrain spec); the model never
does.  Every simulation goes through ``ctx.simulate_many`` in one batch (run cache, process pool),
and the runs and the calibrated model are shared between the compute functions through
``ctx.scratch`` (key :data:`MEMO_KEY`; never persisted with the result).

Commands: a scenario's ``command.accel`` ramp (Yu: "commanded at an acceleration of 1 m/s^2")
is part of the command the model gets (:func:`ramped_command`); the testbed logs the commanded
step and ramps its PID reference at the same rate.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from bench.registry import calibrate, estimate
from bench.report.io import atomic_savefig
from bench.run import Run
from bench.spec import Scenario, load_scenario
from methods.yu2010.commands import LEMNISCATE_TAU0, commanded_radii, lemniscate_xy
from methods.yu2010.identification import evenly_spaced, identify_from_speeds
from methods.yu2010.params import YuParams
from methods.yu2010.plugin import SteadySummary, Yu2010, Yu2010OpenLoop, initial_wheel_speeds, steady_summary
from methods.yu2010.steady import steady_torques, wang2015_table1_params, wang_steady_state

TABLE1_N = (2, 3, 4, 5, 6, 7, 8, 11, 16, 31)  # Yu 2010 Table I
SWEEP_SPEED = 0.2  # [m/s] Fig. 9 / Table I sweep speed (scenario yu_radius_sweep)
CAL_STRAIGHT_SPEED = 0.3  # [m/s] straight calibration run for mu_roll (not the scored 0.2 m/s run)
FIG9_SERIES = (0, 4, 8, 10, 14, 18, 22, 26, 30)  # experiment indices (0-based) of the claim series
TREND_TOL = 0.01  # [N m] tolerance of the Fig. 9 trend claims (steady-average noise is < 1e-3)
MULTISTART = tuple((k0, 0.5, 0.3) for k0 in (3e-4, 1e-3, 3e-3, 1e-2, 3e-2))  # (K, mu_sa, mu_op) starts
LEMNISCATE_FIG21 = "yu_lemniscate_tau0_fig21"
LEMNISCATE_PARAMS = {"K": 0.0009, "mu_sa": 0.6488, "mu_op": 0.4601}  # Yu 2010 Sec. V-C
RAMPS = {  # Figs. 18-20: scenario, expected outcome
    "asphalt": ("ramp_asphalt_5p4", "holds"),
    "wood": ("ramp_wood_15", "decelerates"),
    "whiteboard": ("ramp_whiteboard_13p5", "fails"),
}
HOLD_TOL = 0.10  # holds its speed: final speed within 10 % of the command
DECEL_MARGIN = 0.02  # [m/s] decelerates: final speed below the initial speed by more than this
ACCEL_PHASE = 1.0  # [s] Yu's "acceleration phase of the motion (< 1 s)" (Sec. V-A)
WANG_RATIOS = tuple(float(k) for k in range(8))  # Wang eq. (24): lambda = 0..7
WANG_SPEEDS = (0.1, 0.2, 0.5)  # [m/s]; Wang's Fig. 5 speed is not given: his experiments span 0.1-0.5
MEMO_KEY = "_yu2010_memo"


# ----------------------------------------------------------------------------------- helpers
def _rms(a: np.ndarray) -> float:
    a = np.asarray(a, float)
    a = a[np.isfinite(a)]
    return float(np.sqrt(np.mean(a * a))) if a.size else math.nan


def _tag(x: float) -> str:
    """0.1 -> '0p1' for metric ids."""
    return f"{x:g}".replace(".", "p")


def _new_figure(w: float, h: float) -> Any:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(w, h))
    FigureCanvasAgg(fig)  # Agg canvas, no pyplot global state
    return fig


def _save(ctx: Any, fig: Any, name: str, caption: str) -> None:
    path = Path(ctx.out_dir) / name
    fig.tight_layout()
    atomic_savefig(fig, path, dpi=110, metadata={"Software": None})
    ctx.figure(path, caption)


def ramped_command(run: Run, accel: float, wheel_radius: float) -> Run:
    """``run`` with its commanded wheel speeds rate-limited at ``accel / wheel_radius`` [rad/s^2]
    per side, starting from the initial wheel speed (the model's, :func:`methods.yu2010.plugin.initial_wheel_speeds`)
    -- the command ramp Yu describes (Secs. V-B, V-C) and the testbed applies to its PID reference.  ``accel`` <= 0
    returns ``run`` unchanged.  A rate limiter is recursive, so this loops over the command samples (a few
    thousand)."""
    if accel <= 0:
        return run
    data = run.data.copy()
    limit = accel / wheel_radius
    t_all = run.t
    for cmd, w in zip(("cmd_wl", "cmd_wr"), initial_wheel_speeds(run)):
        tc, target = run.samples(cmd)
        out = np.empty_like(target)
        steps = limit * np.diff(tc, prepend=tc[0])
        tgt = target.tolist()
        stp = steps.tolist()
        for k in range(len(tgt)):
            d = tgt[k] - w
            w = tgt[k] if abs(d) <= stp[k] else w + math.copysign(stp[k], d)
            out[k] = w
        col = np.full(t_all.size, np.nan)
        col[np.isfinite(run[cmd])] = out
        data[cmd] = col
    return Run(data, dict(run.meta, command_ramp=accel))


def ramp_outcome(t: np.ndarray, v: np.ndarray, v_cmd: float, v0: float, tail: float = 0.5) -> tuple[str, float]:
    """Outcome of a hill climb from the vehicle speed ``v`` (Figs. 18-20): ``fails`` when the final
    speed (mean of the last ``tail`` s) is <= 0 (it stops or slides back), ``holds`` when it is
    within :data:`HOLD_TOL` of the command, ``decelerates`` when it ends below the initial speed
    ``v0`` by more than :data:`DECEL_MARGIN`, else ``other``.  Returns (outcome, final speed)."""
    v_end = float(np.mean(v[t >= t[-1] - tail]))
    if v_end <= 0.0:
        return "fails", v_end
    if abs(v_end - v_cmd) <= HOLD_TOL * v_cmd:
        return "holds", v_end
    if v_end < v0 - DECEL_MARGIN:
        return "decelerates", v_end
    return "other", v_end


def monotone(values: Sequence[float], increasing: bool, tol: float) -> bool:
    """Every step in the given direction within ``tol``, and an overall change in that direction."""
    v = np.asarray(values, float)
    s = 1.0 if increasing else -1.0
    return bool(np.all(s * np.diff(v) >= -tol) and s * (v[-1] - v[0]) > 0)


# ----------------------------------------------------------------------------------- runs
@dataclass(frozen=True)
class Experiments:
    """All testbed runs of the reproduction (simulated in one batch through the run cache)."""

    radii: np.ndarray
    sweep: tuple[Run, ...]  # calibration: one steady turn per commanded radius
    straight_cal: Run  # calibration: straight constant speed (mu_roll)
    flat_cal: dict[str, Run]  # calibration: flat straight run on each ramp surface (its mu_roll)
    scored: dict[str, Run]  # scored runs by scenario name
    scenarios: dict[str, Scenario]


@dataclass(frozen=True)
class Calibrated:
    """The model calibrated on the sweep + straight run, and each sweep run's steady part."""

    model: Yu2010
    summaries: tuple[SteadySummary, ...]


def _memo(ctx: Any) -> dict[str, Any]:
    """Runs and the calibrated model shared by the compute functions (``ctx.scratch``: never persisted)."""
    return ctx.scratch.setdefault(MEMO_KEY, {})


def _seed(ctx: Any) -> int:
    return int(ctx.seeds[0])


def sweep_scenarios(quick: bool) -> tuple[np.ndarray, list[Scenario]]:
    """The 31 commanded radii of Sec. V-A (all of them in quick mode too: Table I needs N = 31),
    steady CCW turns at 0.2 m/s, 8 s each (4 s in quick mode)."""
    dur = 4.0 if quick else 8.0
    radii = commanded_radii()
    return radii, [load_scenario("yu_radius_sweep", {"id": f"yu_radius_sweep_R{R:.4g}", "duration": dur,
                                                     "command.segments": [[dur, SWEEP_SPEED, float(R)]]})
                   for R in radii]


def _scored_scenarios(quick: bool) -> dict[str, Scenario]:
    out = {name: load_scenario(name) for name in
           ("circle_vinyl", "straight_0p2_vinyl", "straight_1p5_vinyl", "yu_lemniscate")}
    if quick:
        out["circle_vinyl"] = load_scenario("circle_vinyl", {"duration": 10.0,
                                                             "command.segments": [[10.0, 0.2, 4.0]]})
        out["straight_0p2_vinyl"] = load_scenario("straight_0p2_vinyl", {
            "duration": 4.0, "command.segments": [[4.0, 0.2, math.inf]]})
    # the partial lemniscate as the Yu plugin reads Fig. 21 (methods/yu2010/commands.LEMNISCATE_TAU0)
    out[LEMNISCATE_FIG21] = load_scenario("yu_lemniscate", {"id": LEMNISCATE_FIG21, "command.t0": LEMNISCATE_TAU0})
    for scn_name, _ in RAMPS.values():
        out[scn_name] = load_scenario(scn_name)
    return out


def _flat_scenario(ramp_scenario: str, dur: float) -> Scenario:
    """A straight constant-speed run on the ramp's surface laid flat (its mu_roll, Sec. V-A)."""
    return load_scenario(ramp_scenario, {"id": f"{ramp_scenario}_flat_mu_roll", "terrain.slope_deg": 0.0,
                                         "initial_speed": 0.0, "duration": dur,
                                         "command.segments": [[dur, CAL_STRAIGHT_SPEED, math.inf]]})


def experiments(ctx: Any) -> Experiments:
    memo = _memo(ctx)
    if "experiments" in memo:
        return memo["experiments"]
    seed = _seed(ctx)
    radii, sweep = sweep_scenarios(ctx.quick)
    dur = 4.0 if ctx.quick else 8.0
    straight = load_scenario("straight_0p2_vinyl", {"id": "yu_straight_0p3_vinyl_mu_roll", "duration": dur,
                                                    "command.segments": [[dur, CAL_STRAIGHT_SPEED, math.inf]]})
    flats = {key: _flat_scenario(scn, dur) for key, (scn, _) in RAMPS.items()}
    scored = _scored_scenarios(ctx.quick)
    requests = [*sweep, straight, *flats.values(), *scored.values()]
    runs = ctx.simulate_many([(s, seed) for s in requests])
    n = len(sweep)
    out = Experiments(
        radii=radii, sweep=tuple(runs[:n]), straight_cal=runs[n],
        flat_cal=dict(zip(flats, runs[n + 1:n + 1 + len(flats)])),
        scored=dict(zip(scored, runs[n + 1 + len(flats):])), scenarios=scored,
    )
    memo["experiments"] = out
    return out


def calibrated(ctx: Any) -> Calibrated:
    """Yu2010 calibrated (mu_roll from the straight run, alpha from the sweep's yaw rates, then
    K, mu_sa, mu_op by eq. (28) over all 31 radii) -- the N = 31 row of Table I."""
    memo = _memo(ctx)
    if "calibrated" not in memo:
        ex = experiments(ctx)
        model = calibrate(Yu2010(), [*ex.sweep, ex.straight_cal])
        summaries = tuple(steady_summary(r.without_truth(), model.settle) for r in ex.sweep)
        memo["calibrated"] = Calibrated(model, summaries)
    return memo["calibrated"]


def table_ii_params(platform: Mapping[str, Any]) -> YuParams:
    """Table II terrain values (vinyl lab surface) on the run's platform."""
    return YuParams().with_platform(platform)


# ----------------------------------------------------------------------------------- Table I
def published_table1() -> dict[str, float]:
    """Yu 2010 Table I as transcribed in the paper declaration (rows K_N*, mu_sa_N*, mu_op_N*)."""
    from bench.reproduce import load_paper

    decl = load_paper("yu2010")
    tab = next(t for t in decl["tables"] if t["id"] == "table1")
    return {r["metric"]: float(r["published"]) for r in tab["rows"]
            if r["metric"].split("_N")[0] in ("K", "mu_sa", "mu_op") and "published" in r}


def variation(v2: float, v31: float) -> float:
    """Yu's variation from N = 2 to 31: |v(2) - v(31)| / v(2).  (Table I: |0.00060 - 0.00050| /
    0.00060 = 16.7 %, |0.4609 - 0.4151| / 0.4609 = 9.9 %, |0.3186 - 0.2964| / 0.3186 = 7.0 %, the
    numbers of Sec. V-A; dividing by v(31) would give 20.0 %, 11.0 %, 7.5 %.)"""
    return abs(v2 - v31) / abs(v2)


def table1(ctx: Any) -> dict[str, float]:
    """Table I: eq. (28) with scipy least_squares on the testbed's steady torques at N evenly spaced
    commanded radii; mu_roll from the straight run, alpha from the yaw rates (Sec. II, eq. (1))."""
    ex = experiments(ctx)
    cal = calibrated(ctx)
    q = cal.model.params
    s = cal.summaries
    wl, wr = np.array([x.cmd_wl for x in s]), np.array([x.cmd_wr for x in s])
    tl, tr = np.array([x.tau_l for x in s]), np.array([x.tau_r for x in s])
    out: dict[str, float] = {}
    for n in TABLE1_N:
        res = identify_from_speeds(wl, wr, tl, tr, q, indices=evenly_spaced(len(s), n))
        out[f"K_N{n}"], out[f"mu_sa_N{n}"], out[f"mu_op_N{n}"] = res.K, res.mu_sa, res.mu_op
        out[f"rms_N{n}"] = res.rms
        out[f"converged_N{n}"] = float(res.success)
    for n in (3, 4):  # is the large-K solution the minimum of eq. (28) for these subsets? (several starts)
        idx = evenly_spaced(len(s), n)
        ks = [identify_from_speeds(wl, wr, tl, tr, q, x0=x0, indices=idx).K for x0 in MULTISTART]
        out[f"multistart_spread_K_N{n}"] = float((max(ks) - min(ks)) / np.median(ks))
    for p in ("K", "mu_sa", "mu_op"):
        a, b = out[f"{p}_N2"], out[f"{p}_N31"]
        out[f"d{p}"] = abs(a - b)
        out[f"var_{p}"] = variation(a, b)
        out[f"var5_{p}"] = variation(out[f"{p}_N5"], b)
    pub = published_table1()
    for p in ("K", "mu_sa", "mu_op"):
        out[f"pub_var_{p}"] = variation(pub[f"{p}_N2"], pub[f"{p}_N31"])
    out["mu_roll"] = q.mu_roll
    out["alpha"] = q.alpha
    out["K_calibrate"] = q.K  # Yu2010.calibrate on all radii: must equal the N = 31 row
    terr = ex.sweep[0].meta["terrain"]

    def radii_of(n: int) -> str:
        return ", ".join(f"{r:.3g}" for r in ex.radii[evenly_spaced(len(s), n)])

    ctx.note("table1", (
        "The testbed is not Yu's vinyl floor: its tire law is per wheel and anisotropic (Janosi-Hanamoto over "
        f"each wheel's own patch, K = {terr['shear_modulus'] * 1e3:g} mm, "
        f"K_lat = {terr['shear_modulus_lat_ratio']:g} K, "
        f"mu_lat = {terr['mu_lat_ratio']:g} mu), while Yu's model integrates the shear displacement of eqs. (12)-(16) "
        "over both patches of a side with one K. The identified values are the model's best fit to the testbed, "
        "so differences from Table I are expected: K comes out about ten times Yu's, in line with the testbed's "
        f"softer law. The friction coefficients come close to the testbed's mu_sa = {terr['mu_sa']:g} and "
        f"mu_op = {terr['mu_op']:g} (N = 31: {out['mu_sa_N31']:.4f}, {out['mu_op_N31']:.4f}). "
        f"N = 2 uses R = {radii_of(2)} m: the nearly straight run carries only rolling resistance, so three "
        "parameters meet two informative torques and least_squares ends in a flat valley (converged = "
        f"{bool(out['converged_N2'])}). N = 3 (R = {radii_of(3)} m) and N = 4 (R = {radii_of(4)} m) reach a "
        f"different minimum with large K and mu_sa (N = 3: K = {out['K_N3']:.4f} m, mu_sa = {out['mu_sa_N3']:.3f}; "
        f"the stress stays in its linear range, where only mu/K matters); least_squares from {len(MULTISTART)} "
        f"starts (K0 = 0.3..30 mm) ends there every time (relative spread of K: N = 3 "
        f"{out['multistart_spread_K_N3']:.1e}, N = 4 {out['multistart_spread_K_N4']:.1e}), so for these radii it "
        f"is the minimum of eq. (28). From N = 5 on the values settle (variation N = 5 -> 31: K {out['var5_K']:.1%}, "
        f"mu_sa {out['var5_mu_sa']:.1%}, mu_op {out['var5_mu_op']:.1%}). mu_op is fixed by the locked inner wheel "
        "at R = 0.2 m, which every subset contains. Variation is Yu's abs(v(N=2) - v(N=31)) / v(N=2): it reproduces "
        "his 16.7 / 9.9 / 7.0 % from Table I (pub_var rows), while dividing by v(N=31) would give 20.0 / 11.0 / "
        "7.5 %. Yu's Table II uses the N = 7 row. mu_roll comes from a straight 0.3 m/s calibration run: the "
        "testbed's rolling torque acts at its effective radius 0.97 r, so the nominal-radius estimate is ~3 % "
        f"below the terrain's {terr['rolling_resistance']:g}. alpha from the sweep's yaw rates (eq. (1)). RMS "
        f"torque residual at N = 31: {out['rms_N31']:.3f} N m."
        + (" Quick mode: 4 s sweep runs (8 s in full mode)." if ctx.quick else "")
    ))
    why = (f"N = 2 (R = {radii_of(2)} m) is underdetermined: least_squares converged = {bool(out['converged_N2'])}; "
           f"N = 3, 4 reach a large-K minimum (K = {out['K_N3']:.4f}, {out['K_N4']:.4f} m). Variation N = 5 -> 31: "
           f"K {out['var5_K']:.1%}, mu_sa {out['var5_mu_sa']:.1%}, mu_op {out['var5_mu_op']:.1%} (Table I note).")
    for p in ("K", "mu_sa", "mu_op"):
        ctx.note(f"converge_{p}", why)
    _figure_table1(ctx, out, pub)
    return out


def _figure_table1(ctx: Any, out: Mapping[str, float], pub: Mapping[str, float]) -> None:
    fig = _new_figure(10, 3.2)
    ns = np.array(TABLE1_N)
    for k, (p, label) in enumerate((("K", "K [m]"), ("mu_sa", "mu_sa"), ("mu_op", "mu_op"))):
        ax = fig.add_subplot(1, 3, k + 1)
        ax.plot(ns, [out[f"{p}_N{n}"] for n in TABLE1_N], "o-", label="identified on the testbed")
        ax.plot(ns, [pub[f"{p}_N{n}"] for n in TABLE1_N], "s--", label="Yu 2010 Table I")
        ax.set_xscale("log")
        ax.set_xticks(ns, [str(n) for n in TABLE1_N], fontsize=7)
        ax.minorticks_off()
        if p == "K":
            ax.set_yscale("log")
        ax.set_xlabel("N experiments")
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
        if k == 0:
            ax.legend(fontsize=7)
    _save(ctx, fig, "table1.png", "Table I: K, mu_sa, mu_op identified by eq. (28) vs N (testbed) and Yu's values")


# ----------------------------------------------------------------------------------- Fig. 9
def fig9(ctx: Any) -> dict[str, float]:
    """Fig. 9: steady torques over the commanded radii, testbed vs model (identified, Table II)."""
    ex = experiments(ctx)
    cal = calibrated(ctx)
    R = ex.radii
    tb_l = np.array([s.tau_l for s in cal.summaries])
    tb_r = np.array([s.tau_r for s in cal.summaries])
    q_id = cal.model.params.with_platform(ex.sweep[0].meta["platform"])
    q_t2 = table_ii_params(ex.sweep[0].meta["platform"])
    id_l, id_r = steady_torques(R, SWEEP_SPEED, q_id)
    t2_l, t2_r = steady_torques(R, SWEEP_SPEED, q_t2)
    out: dict[str, float] = {}
    for i in FIG9_SERIES:
        key = f"i{i + 1:02d}"
        out[f"tb_tau_l_{key}"], out[f"tb_tau_r_{key}"] = tb_l[i], tb_r[i]
        out[f"model_tau_l_{key}"], out[f"model_tau_r_{key}"] = id_l[i], id_r[i]
        out[f"table2_tau_l_{key}"], out[f"table2_tau_r_{key}"] = t2_l[i], t2_r[i]
    out["rms_identified"] = _rms(np.concatenate([id_l - tb_l, id_r - tb_r]))
    out["rms_table2"] = _rms(np.concatenate([t2_l - tb_l, t2_r - tb_r]))
    out["tb_outer_falls"] = float(monotone(tb_r, False, TREND_TOL))
    out["tb_inner_rises"] = float(monotone(tb_l, True, TREND_TOL))
    out["model_outer_falls"] = float(monotone(id_r, False, TREND_TOL))
    out["model_inner_rises"] = float(monotone(id_l, True, TREND_TOL))
    out["table2_outer_falls"] = float(monotone(t2_r, False, TREND_TOL))
    out["table2_inner_rises"] = float(monotone(t2_l, True, TREND_TOL))
    zc_tb = R[np.argmax(tb_l > 0)] if np.any(tb_l > 0) else math.nan
    zc_id = R[np.argmax(id_l > 0)] if np.any(id_l > 0) else math.nan
    out["tb_inner_sign_change_radius"] = float(zc_tb)
    out["model_inner_sign_change_radius"] = float(zc_id)
    ctx.note("fig9", (
        "Yu's 'magnitudes of both torques reduce as the radius grows' is read per side: the outer (right, CCW) "
        "torque falls and the inner (left) braking torque rises towards the straight-line rolling torque "
        f"(it changes sign: testbed at R = {zc_tb:.3g} m, identified model at R = {zc_id:.3g} m; both end at the "
        "rolling torque, so the magnitude of tau_l itself is not monotonic, in Yu's model either). Every flag is over all "
        f"simulated radii with a {TREND_TOL} N m tolerance; the claims use the 9 radii i = 1, 5, 9, 11, 15, 19, 23, "
        "27, 31. The sweep is the calibration data: rms_identified is an in-sample fit, rms_table2 (Yu's "
        "vinyl parameters) is not."
    ))
    fig = _new_figure(7, 4.2)
    ax = fig.add_subplot(1, 1, 1)
    ax.plot(R, tb_l, "o", color="C0", label="testbed left")
    ax.plot(R, tb_r, "s", color="C3", label="testbed right")
    ax.plot(R, id_l, "-", color="C0", label="model (identified) left")
    ax.plot(R, id_r, "-", color="C3", label="model (identified) right")
    ax.plot(R, t2_l, "--", color="C0", alpha=0.6, label="model (Table II) left")
    ax.plot(R, t2_r, "--", color="C3", alpha=0.6, label="model (Table II) right")
    ax.set_xscale("log")
    ax.set_xlabel("commanded turning radius R [m]")
    ax.set_ylabel("steady wheel torque per side [N m]")
    ax.axhline(0, color="k", lw=0.5)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    _save(ctx, fig, "fig9.png", "Fig. 9: steady left/right torque vs commanded radius, testbed and model (0.2 m/s CCW)")
    return out


# ----------------------------------------------------------------------------------- Figs. 10-13
def _predict(ctx: Any, model: Yu2010, name: str) -> tuple[Run, Any]:
    """Testbed run ``name`` and the model's prediction from its (ramped) command."""
    ex = experiments(ctx)
    run = ex.scored[name]
    scn = ex.scenarios[name]
    cmd = ramped_command(run, scn.command.accel, scn.platform.wheel_radius)
    return run, estimate(model, cmd)


def fig10_13(ctx: Any) -> dict[str, float]:
    """Figs. 10-13: circle at 0.2 m/s, R = 4 m, from rest: closed-loop prediction vs testbed."""
    from bench.metrics import Trajectory, final_position_error

    cal = calibrated(ctx)
    run, est = _predict(ctx, cal.model, "circle_vinyl")
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
        "rms_wl": _rms(e_wl), "rms_wr": _rms(e_wr),
        "rms_w_accel": _rms(np.concatenate([e_wl[acc], e_wr[acc]])),
        "rms_w_steady": _rms(np.concatenate([e_wl[~acc], e_wr[~acc]])),
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
    ctx.note("fig10_13", (
        "Model calibrated on the sweep (Table I, N = 31) and scored on this separate run. The model's vehicle "
        "speed is r (w_l + w_r)/2 with the nominal radius (eq. (1)); the testbed's tires roll at 0.97 r, so "
        "part of the velocity error and most of the along-track drift of the path (Figs. 12-13) is that radius "
        "effect, which the model does not have. rms_w_accel is over Yu's acceleration phase (t < 1 s), "
        "rms_w_steady after it."
    ))
    _figure_dynamic(ctx, run, est, "fig10_13.png",
                    "Figs. 10-13: circle 0.2 m/s, R = 4 m: wheel speeds, torques, path and X/Y errors, "
                    "testbed vs model")
    return out


def _figure_dynamic(ctx: Any, run: Run, est: Any, name: str, caption: str) -> None:
    t = run.t
    enc = np.isfinite(run["enc_wl"])
    tq = np.isfinite(run["tau_l"])
    fig = _new_figure(11, 7)
    ax = fig.add_subplot(2, 2, 1)
    kern = np.ones(5) / 5.0  # 50 ms mean of the quantised encoder speed (display only)
    te = t[enc][2:-2]
    for side, color in (("l", "C0"), ("r", "C3")):
        ax.plot(te, np.convolve(run[f"enc_w{side}"][enc], kern, "valid"), color=color, lw=1,
                label=f"testbed {'left' if side == 'l' else 'right'} (encoder, 50 ms mean)")
    ax.plot(est.t, est["wl"], "--", color="C0", label="model left")
    ax.plot(est.t, est["wr"], "--", color="C3", label="model right")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("wheel speed [rad/s]")
    ax.legend(fontsize=7)
    ax.grid(True, alpha=0.3)
    ax = fig.add_subplot(2, 2, 2)
    ax.plot(t[tq], run["tau_l"][tq], color="C0", lw=1, label="testbed left")
    ax.plot(t[tq], run["tau_r"][tq], color="C3", lw=1, label="testbed right")
    ax.plot(est.t, est["tau_l"], "--", color="C0", label="model left")
    ax.plot(est.t, est["tau_r"], "--", color="C3", label="model right")
    later = t >= t[0] + 1.0  # the start-up transient may peak far above the rest: clip it
    vals = np.concatenate([run["tau_l"][tq & later], run["tau_r"][tq & later],
                           est["tau_l"][later], est["tau_r"][later]])
    lo, hi = float(np.min(vals)), float(np.max(vals))
    pad = 0.3 * max(hi - lo, 0.5)
    ax.set_ylim(lo - pad, hi + pad)
    peak = max(float(np.nanmax(np.abs(run["tau_l"]))), float(np.nanmax(np.abs(run["tau_r"]))))
    if peak > hi + pad:
        ax.set_title(f"start-up peak {peak:.1f} N m (testbed) clipped", fontsize=8)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("wheel torque per side [N m]")
    ax.legend(fontsize=7)
    ax.grid(True, alpha=0.3)
    ax = fig.add_subplot(2, 2, 3)
    ax.plot(run["truth_x"], run["truth_y"], label="testbed")
    ax.plot(est["x"], est["y"], "--", label="model")
    ax.set_xlabel("X [m]")
    ax.set_ylabel("Y [m]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(fontsize=7)
    ax.grid(True, alpha=0.3)
    ax = fig.add_subplot(2, 2, 4)
    ax.plot(t, run["truth_x"] - est["x"], label="X error (testbed - model)")
    ax.plot(t, run["truth_y"] - est["y"], label="Y error (testbed - model)")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("[m]")
    ax.legend(fontsize=7)
    ax.grid(True, alpha=0.3)
    _save(ctx, fig, name, caption)


# ----------------------------------------------------------------------------------- Figs. 14-16
def fig14_16(ctx: Any) -> dict[str, float]:
    """Figs. 14-16: straight 0.2 m/s (1 m/s^2 ramp): closed loop (commands) vs open loop (the
    testbed's measured torques replayed, Fig. 16), velocity prediction RMS against the testbed."""
    cal = calibrated(ctx)
    run, closed = _predict(ctx, cal.model, "straight_0p2_vinyl")
    open_model = Yu2010OpenLoop(cal.model.params)
    opened = estimate(open_model, run)
    vx = run["truth_vx"]
    tq = np.isfinite(run["tau_l"])
    out = {
        "rms_vx_closed": _rms(closed["vx"] - vx),
        "rms_vx_open": _rms(opened["vx"] - vx),
        "rms_tau_closed": _rms(np.concatenate([(closed["tau_l"] - run["tau_l"])[tq],
                                               (closed["tau_r"] - run["tau_r"])[tq]])),
        "v_final_tb": float(vx[-1]),
        "v_final_closed": float(closed["vx"][-1]),
        "v_final_open": float(opened["vx"][-1]),
    }
    out["ratio_closed_open"] = out["rms_vx_closed"] / out["rms_vx_open"]
    # diagnostic of the replayed torque (reads truth and the platform: a metric, not the model): the
    # impulse of the logged torque above the rolling torque vs the momentum it must have produced
    plat = run.meta["platform"]
    r_eff = plat["wheel_radius"] * plat["wheel_radius_scale_l"]
    t = run.t
    tail = tq & (t >= t[-1] - 1.0)
    roll = float(np.mean(run["tau_l"][tail]) + np.mean(run["tau_r"][tail]))
    ts = t[tq]
    out["impulse_logged"] = float(np.trapezoid(run["tau_l"][tq] + run["tau_r"][tq] - roll, ts))
    spin = 2 * plat["wheel_inertia"] * (run["truth_wl"][-1] + run["truth_wr"][-1])  # two wheels per side
    out["impulse_from_motion"] = float((plat["mass"] + plat.get("payload", 0.0)) * r_eff * vx[-1] + spin)
    q = cal.model.params  # in eq. (25) straight, sum of (tau - C) = m r^2 w_dot: the excess's speed
    out["open_loop_excess_speed"] = (out["impulse_logged"] - out["impulse_from_motion"]) / (q.m * q.r)
    ctx.note("fig14_16", (
        "Open loop (Fig. 16): the testbed's logged side torques drive eq. (25) of the calibrated model, "
        "without the PID; its velocity error integrates every torque/resistance mismatch, which the closed "
        "loop's PID removes (leaving the 3 % effective-radius offset). Much of the open-loop error here is a "
        "testbed logging effect: the logged torque is the motor torque at the start of each physics step, "
        "while the testbed's semi-implicit wheel update applies it corrected by (d tau/d w) dw (PID and "
        "back-EMF slope), which is large while the wheels accelerate. Over the start-up the logged torque "
        f"above rolling carries an impulse of {out['impulse_logged']:.3f} N m s, while the motion it produced "
        f"needs {out['impulse_from_motion']:.3f} N m s (m r_eff v + wheel spin). Replayed in eq. (25) the excess "
        f"alone is worth about {out['open_loop_excess_speed']:.3f} m/s of the open loop's final speed error of "
        f"{out['v_final_open'] - out['v_final_tb']:.3f} m/s, so the verdict leans on this effect (reported to "
        "the testbed's owner)."
    ))
    ctx.note("closed_beats_open", (
        f"Estimated {out['open_loop_excess_speed']:.3f} m/s of the open loop's "
        f"{out['v_final_open'] - out['v_final_tb']:.3f} m/s final error comes from the testbed logging the "
        "torque before its implicit wheel-speed correction (Figs. 14-16 note)."
    ))
    fig = _new_figure(11, 3.4)
    for k, (e, title) in enumerate(((closed, "Fig. 14: closed loop"), (opened, "Fig. 16: open loop"))):
        ax = fig.add_subplot(1, 3, 1 + 2 * k)
        ax.plot(t, vx, label="testbed")
        ax.plot(e.t, e["vx"], "--", label="model")
        ax.set_title(title, fontsize=9)
        ax.set_xlabel("t [s]")
        ax.set_ylabel("vehicle speed [m/s]")
        ax.legend(fontsize=7)
        ax.grid(True, alpha=0.3)
    ax = fig.add_subplot(1, 3, 2)
    ax.plot(t[tq], run["tau_l"][tq], label="testbed left")
    ax.plot(closed.t, closed["tau_l"], "--", label="model left (closed loop)")
    ax.set_title("Fig. 15: torque", fontsize=9)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("wheel torque per side [N m]")
    ax.legend(fontsize=7)
    ax.grid(True, alpha=0.3)
    _save(ctx, fig, "fig14_16.png",
          "Figs. 14-16: straight 0.2 m/s, closed-loop and open-loop velocity predictions vs testbed")
    return out


# ----------------------------------------------------------------------------------- Fig. 17
def fig17(ctx: Any) -> dict[str, float]:
    """Fig. 17: an unachievable 1.5 m/s command: the final speed the motors reach."""
    cal = calibrated(ctx)
    run, est = _predict(ctx, cal.model, "straight_1p5_vinyl")
    t = run.t
    tail = t >= t[-1] - 0.5
    out = {
        "v_final_tb": float(np.mean(run["truth_vx"][tail])),
        "v_final_model": float(np.mean(est["vx"][tail])),
        "v_cmd": 1.5,
    }
    q = est.info["params"]
    ctx.note("fig17", (
        "Both saturate at the motor controller's voltage limit, eq. (27): PWM (V_CC - U_loss) = "
        f"{q['PWM']} x ({q['V_CC']} - {q['U_loss']}) V, less the armature drop; the model counts (27)'s current term "
        "R_a I on top of (26)'s (see methods/yu2010/simulate.py), the testbed once, and the testbed rolls at 0.97 r."
    ))
    fig = _new_figure(6, 3.6)
    ax = fig.add_subplot(1, 1, 1)
    ax.plot(t, run["truth_vx"], label="testbed")
    ax.plot(est.t, est["vx"], "--", label="model (closed loop)")
    ax.axhline(0.93, color="gray", ls=":", label="Yu 2010: ~0.93 m/s")
    ax.axhline(1.5, color="k", lw=0.5, label="command 1.5 m/s")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("vehicle speed [m/s]")
    ax.legend(fontsize=7)
    ax.grid(True, alpha=0.3)
    _save(ctx, fig, "fig17.png", "Fig. 17: 1.5 m/s command saturating, testbed vs model")
    return out


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
        v0 = float(scn.initial_speed)
        tb_out, tb_v = ramp_outcome(t, run["truth_vx"], v_cmd, v0)
        md_out, md_v = ramp_outcome(est.t, est["vx"], v_cmd, v0)
        out[f"{key}_mu_roll"] = mu_roll
        out[f"{key}_v0"] = v0
        out[f"{key}_v_cmd"] = v_cmd
        out[f"{key}_v_final_tb"] = tb_v
        out[f"{key}_v_final_model"] = md_v
        out[f"{key}_{expected}_tb"] = float(tb_out == expected)
        out[f"{key}_{expected}_model"] = float(md_out == expected)
        if key == "wood":  # the same prediction without the motor power limit
            free = Yu2010(model.params.replace(P_max=0.0), use_run_platform=False)
            _, est_free = _predict(ctx, free, scn_name)
            out["wood_v_final_model_no_power_limit"] = ramp_outcome(est_free.t, est_free["vx"], v_cmd, v0)[1]
        if key == "whiteboard":
            terr = run.meta["terrain"]
            out["whiteboard_mu_sa_tb"] = float(terr["mu_sa"])
            out["whiteboard_tan_slope"] = math.tan(scn.terrain.slope)
        curves[key] = (scn, t, run["truth_vx"], est.t, est["vx"], tb_out, md_out)
        texts.append(f"{key} {math.degrees(scn.terrain.slope):.1f} deg (expected: {expected}): testbed {tb_out} "
                     f"({tb_v:.3f} m/s), model {md_out} ({md_v:.3f} m/s)")
    out["all_tb"] = float(all(out[f"{k}_{e}_tb"] for k, (_, e) in RAMPS.items()))
    out["all_model"] = float(all(out[f"{k}_{e}_model"] for k, (_, e) in RAMPS.items()))
    summary = "; ".join(texts) + "."
    q = cal.model.params.with_platform(ex.scored[RAMPS["wood"][0]].meta["platform"])
    ctx.note("fig18_20", (
        f"{summary} Outcomes from the final speed (last 0.5 s): holds = within {HOLD_TOL:.0%} of the command, "
        f"decelerates = below the initial speed by > {DECEL_MARGIN} m/s, fails = <= 0. The model's power limit "
        f"(P_max = {q.P_max:g} W per motor, from the platform's motor) makes it decelerate on 15 deg; without it "
        f"the model would end at {out['wood_v_final_model_no_power_limit']:.3f} m/s (voltage-limited). The model "
        "rolls without slip on a slope (Sec. III-B: F_f = 0) and has no traction limit, so the white board's "
        "failure -- on the testbed the vehicle slides back because its friction mu_sa = "
        f"{out['whiteboard_mu_sa_tb']:g} < tan 13.5 deg = {out['whiteboard_tan_slope']:.3f} -- cannot appear in it: "
        "it predicts a power-limited climb."
    ))
    ctx.note("ramps_testbed", summary)
    ctx.note("ramps_model", summary + " The white-board failure needs a traction limit the pure-rolling model "
                                      "does not have.")
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


# ----------------------------------------------------------------------------------- Figs. 21-29
def fig22_29(ctx: Any) -> dict[str, float]:
    """Figs. 21-29: partial lemniscate with Yu's Sec. V-C terrain parameters (K = 0.0009,
    mu_sa = 0.6488, mu_op = 0.4601; alpha and mu_roll from Table II), predicted from the commands."""
    from bench.metrics import Trajectory, final_position_error, position_errors

    ex = experiments(ctx)
    run0 = ex.scored["yu_lemniscate"]
    model = Yu2010(table_ii_params(run0.meta["platform"]).replace(**LEMNISCATE_PARAMS))
    run, est = _predict(ctx, model, "yu_lemniscate")
    t = run.t
    tq = np.isfinite(run["tau_l"])
    vx, wz = run["truth_vx"], run["truth_wz"]
    ref = Trajectory.from_run(run, "truth")
    traj = Trajectory.from_estimate(est)
    _, perr = position_errors(ref, traj)
    follow = t >= 3.0
    out = {
        "rms_vx": _rms(est["vx"] - vx),
        "rms_wz": _rms(est["wz"] - wz),
        "rms_speed_tb": _rms(vx),
        "rms_yaw_rate_tb": _rms(wz),
        "rms_vx_follow": _rms((est["vx"] - vx)[follow]),
        "rms_wz_follow": _rms((est["wz"] - wz)[follow]),
        "rms_tau_l": _rms((est["tau_l"] - run["tau_l"])[tq]),
        "rms_tau_r": _rms((est["tau_r"] - run["tau_r"])[tq]),
        "rms_tau_tb": _rms(np.concatenate([run["tau_l"][tq], run["tau_r"][tq]])),
        "final_pos_err": final_position_error(ref, traj),
        "max_pos_err": float(np.max(perr)),
    }
    out["rel_rms_vx"] = out["rms_vx"] / out["rms_speed_tb"]
    out["rel_rms_wz"] = out["rms_wz"] / out["rms_yaw_rate_tb"]
    q = model.params
    turning = follow & (np.abs(wz) > 0.005)
    # the testbed's expansion factor of eq. (1) with the nominal radius (truth: a metric, not the model)
    out["tb_alpha_eff"] = float(np.median(q.r * (run["truth_wr"] - run["truth_wl"])[turning] / (q.B * wz[turning])))
    out["model_alpha"] = q.alpha
    out["tb_speed_start"] = float(np.mean(vx[follow][:50]))
    out["tb_speed_end"] = float(np.mean(vx[-50:]))
    run2, est2 = _predict(ctx, model, LEMNISCATE_FIG21)
    v2, w2 = run2["truth_vx"], run2["truth_wz"]
    out["fig21_rel_rms_vx"] = _rms(est2["vx"] - v2) / _rms(v2)
    out["fig21_rel_rms_wz"] = _rms(est2["wz"] - w2) / _rms(w2)
    tq2 = np.isfinite(run2["tau_l"])
    out["fig21_rms_tau_r"] = _rms((est2["tau_r"] - run2["tau_r"])[tq2])
    scn = ex.scenarios["yu_lemniscate"]
    ctx.note("fig22_29", (
        "The model uses Yu's published lab-surface parameters (Sec. V-C) and is not calibrated on the testbed; "
        f"the testbed's lab_lemniscate terrain has the same mu but its own tire law (K = "
        f"{run.meta['terrain']['shear_modulus'] * 1e3:g} mm). The command follows eqs. (29)-(30) from curve time "
        f"t0 = {scn.command.t0:g} s after a 1 m/s^2 ramp (scenario yu_lemniscate; Yu's Fig. 21 start point is not "
        f"given): the testbed's speed falls from {out['tb_speed_start']:.2f} to {out['tb_speed_end']:.2f} m/s, "
        "while Yu reports accelerations in [0, 0.02] m/s^2. The fig21_* rows repeat the test from curve time "
        f"{LEMNISCATE_TAU0:g} s, the Yu plugin's reading of Fig. 21 (speed 0.16 -> 0.24 m/s, radius 1.45 -> 12 m). "
        "Accuracy threshold of the claims: relative RMS (RMS error / RMS of the testbed signal) "
        "< 10 %, our reading of 'accurate' (Yu gives no number). "
        f"The yaw rate is under-predicted throughout: the model's alpha = {q.alpha:g} (Table II) against the "
        f"testbed's effective {out['tb_alpha_eff']:.3f} on this terrain; the speed is over-predicted by the "
        "testbed's 0.97 r rolling radius. Torques: with Yu's K = 0.9 mm the model's sliding resistance is far "
        f"above the testbed's (RMS torque error {out['rms_tau_l']:.2f} / {out['rms_tau_r']:.2f} N m against an "
        f"RMS testbed torque of {out['rms_tau_tb']:.2f} N m): Yu's 'reasonable predictions of torques' do not "
        "carry over to this terrain with his parameters."
    ))
    ctx.note("lemniscate_velocity", f"RMS over the whole run; after the 3 s ramp: {out['rms_vx_follow']:.4f} m/s.")
    ctx.note("lemniscate_yaw_rate", f"RMS over the whole run; after the 3 s ramp: {out['rms_wz_follow']:.4f} rad/s. "
             f"A steady under-prediction: alpha {q.alpha:g} (Table II) vs the testbed's effective "
             f"{out['tb_alpha_eff']:.3f} on this terrain.")
    whole = lemniscate_xy(np.linspace(0.0, 2 * math.pi * 50.0, 800))
    # the testbed path placed on the curve: start at the curve point of t0, along its tangent
    h = 1e-3
    x0c, y0c = (float(a) for a in lemniscate_xy(scn.command.t0))
    x1c, y1c = (float(a) for a in lemniscate_xy(scn.command.t0 + h))
    rot = math.atan2(y1c - y0c, x1c - x0c) - float(run["truth_yaw"][0])
    dx, dy = run["truth_x"] - run["truth_x"][0], run["truth_y"] - run["truth_y"][0]
    placed = (x0c + math.cos(rot) * dx - math.sin(rot) * dy, y0c + math.sin(rot) * dx + math.cos(rot) * dy)
    _figure_dynamic(ctx, run, est, "fig22_29_a.png",
                    "Figs. 24-29: lemniscate: wheel speeds, torques (Figs. 26-27), path (Fig. 28) "
                    "and X/Y errors (Fig. 29)")
    fig = _new_figure(11, 3.4)
    ax = fig.add_subplot(1, 3, 1)
    ax.plot(whole[0], whole[1], ":", color="gray", label="whole lemniscate (29)-(30)")
    ax.plot(*placed, label="testbed path (placed at the curve start)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_title("Fig. 21", fontsize=9)
    ax.legend(fontsize=7)
    ax.grid(True, alpha=0.3)
    ax = fig.add_subplot(1, 3, 2)
    ax.plot(t, vx, label="testbed")
    ax.plot(est.t, est["vx"], "--", label="model")
    ax.set_title("Fig. 24: linear velocity", fontsize=9)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("[m/s]")
    ax.legend(fontsize=7)
    ax.grid(True, alpha=0.3)
    ax = fig.add_subplot(1, 3, 3)
    ax.plot(t, wz, label="testbed")
    ax.plot(est.t, est["wz"], "--", label="model")
    ax.set_title("Fig. 25: angular velocity", fontsize=9)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("[rad/s]")
    ax.legend(fontsize=7)
    ax.grid(True, alpha=0.3)
    _save(ctx, fig, "fig22_29_b.png", "Figs. 21, 24-25: lemniscate path, linear and angular velocity, testbed vs model")
    return out


# ----------------------------------------------------------------------------------- Wang Fig. 5
def wang_fig5(ctx: Any) -> dict[str, float]:
    """Wang 2015 Fig. 5: chi vs curvature ratio 0..7 from Yu's model in steady state (Wang eqs.
    (16)-(23), Table 1 parameters), at 0.1, 0.2 and 0.5 m/s."""
    q = wang2015_table1_params()
    out: dict[str, float] = {}
    series = {}
    for v in WANG_SPEEDS:
        st = wang_steady_state(q, np.array(WANG_RATIOS), v)
        series[v] = st.chi
        for lam, c in zip(WANG_RATIOS, st.chi):
            out[f"chi_v{_tag(v)}_l{int(lam)}"] = float(c)
        out[f"decreasing_v{_tag(v)}"] = float(monotone(st.chi, False, 0.0))
        out[f"max_residual_v{_tag(v)}"] = float(np.max(st.residual))
    ctx.note("wang_fig5", (
        "Belongs to Wang 2015 Sec. 2.2 (Fig. 5), computed with this package's Yu model (methods/yu2010/steady.py): "
        "force and moment balance of Wang eq. (16) with Yu's shear-stress friction, Wang's Table 1 parameters. "
        "Fig. 5 is a plot without numbers or speed; the claim uses 0.1 m/s (the slowest speed of Wang's "
        "experiments, closest to his constant-velocity assumption). At higher speed the centripetal term bends "
        f"the curve: at 0.2 m/s chi falls to {out['chi_v0p2_l2']:.4f} at curvature ratio 2 and then stays flat within "
        f"{np.ptp(series[0.2][2:]):.4f} (a rise of {np.max(np.diff(series[0.2])):.4f}, below the quadrature's "
        "accuracy, "
        f"so 'decreasing' is {bool(out['decreasing_v0p2'])}); at 0.5 m/s it dips to {out['chi_v0p5_l1']:.3f} at "
        f"curvature ratio 1 and rises to {out['chi_v0p5_l7']:.3f} at 7."
    ))
    fig = _new_figure(6, 3.8)
    ax = fig.add_subplot(1, 1, 1)
    for v, chi in series.items():
        ax.plot(WANG_RATIOS, chi, "o-", label=f"v = {v} m/s")
    ax.set_xlabel("curvature ratio (v_l + v_r)/(v_r - v_l)")
    ax.set_ylabel("chi = (y_l - y_r)/B")
    ax.legend(fontsize=8)
    ax.grid(True, alpha=0.3)
    _save(ctx, fig, "wang_fig5.png", "Wang 2015 Fig. 5: chi vs curvature ratio from Yu's steady-state model")
    return out


__all__ = [
    "TABLE1_N", "Experiments", "Calibrated", "ramped_command", "ramp_outcome", "monotone", "variation",
    "published_table1", "sweep_scenarios", "experiments", "calibrated", "table1", "fig9", "fig10_13",
    "fig14_16", "fig17", "fig18_20", "fig22_29", "wang_fig5",
]
