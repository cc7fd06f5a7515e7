"""Yu 2010 reproduction: the testbed runs and the model calibrated on them, shared by the compute functions.

W. Yu, O. Y. Chuy Jr., E. G. Collins Jr., P. Hollis, "Analysis and Experimental Verification for
Dynamic Modeling of a Skid-Steered Wheeled Vehicle," IEEE Transactions on Robotics, vol. 26,
no. 2, pp. 340-353, April 2010, doi:10.1109/TRO.2010.2042540.

Every simulation of the reproduction goes through ``ctx.simulate_many`` in one batch (:func:`experiments`:
the 31-radius sweep of Sec. V-A, the straight 0.3 m/s mu_roll run, a flat run per ramp surface, the same sweep
and straight run on the lemniscate's surface, the scored runs); :func:`calibrated` is Yu2010 calibrated on the
vinyl sweep + straight run (eq. (28), the N = 31 row of Table I), :func:`calibrated_lemniscate` the same
procedure on the lemniscate's surface (Yu: the parameters "must be determined for each surface").  They live in
``ctx.scratch`` (key :data:`MEMO_KEY`; never persisted with the result).  The
command the model gets is the scenario's command with its ``command.accel`` ramp (:func:`ramped_command`,
Secs. V-B, V-C); :func:`_predict` is the model's prediction of a scored run.  The two measures the metrics
use: :func:`_rms` and :func:`monotone`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np

from bench.registry import calibrate, estimate
from bench.run import Run
from bench.spec import Scenario, load_scenario
from methods.yu2010.commands import commanded_radii
from methods.yu2010.params import YuParams
from methods.yu2010.plugin import SteadySummary, Yu2010, initial_wheel_speeds, steady_summary

SWEEP_SPEED = 0.2  # [m/s] Fig. 9 / Table I sweep speed (scenario yu_radius_sweep)
CAL_STRAIGHT_SPEED = 0.3  # [m/s] straight calibration run for mu_roll (not the scored 0.2 m/s run)
LEMNISCATE_SWEEP = "yu_lemniscate_sweep"  # the 31 radii on the lemniscate's surface (calibration)
RAMPS = {  # Figs. 18-20: scenario, expected outcome
    "asphalt": ("ramp_asphalt_5p4", "holds"),
    "wood": ("ramp_wood_15", "decelerates"),
    "whiteboard": ("ramp_whiteboard_13p5", "fails"),
}
MEMO_KEY = "_yu2010_memo"


# ----------------------------------------------------------------------------------- measures
def _rms(a: np.ndarray) -> float:
    a = np.asarray(a, float)
    a = a[np.isfinite(a)]
    return float(np.sqrt(np.mean(a * a))) if a.size else math.nan


def monotone(values: Sequence[float], increasing: bool, tol: float) -> bool:
    """Every step in the given direction within ``tol``, and an overall change in that direction."""
    v = np.asarray(values, float)
    s = 1.0 if increasing else -1.0
    return bool(np.all(s * np.diff(v) >= -tol) and s * (v[-1] - v[0]) > 0)


# ----------------------------------------------------------------------------------- commands
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


# ----------------------------------------------------------------------------------- runs
@dataclass(frozen=True)
class Experiments:
    """All testbed runs of the reproduction (simulated in one batch through the run cache)."""

    radii: np.ndarray
    sweep: tuple[Run, ...]  # calibration: one steady turn per commanded radius
    straight_cal: Run  # calibration: straight constant speed (mu_roll)
    flat_cal: dict[str, Run]  # calibration: flat straight run on each ramp surface (its mu_roll)
    lem_sweep: tuple[Run, ...]  # calibration: the 31 radii on the lemniscate's surface
    lem_straight: Run  # calibration: straight constant speed on the lemniscate's surface (mu_roll)
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


def sweep_scenarios(quick: bool, base: str = "yu_radius_sweep") -> tuple[np.ndarray, list[Scenario]]:
    """The 31 commanded radii of Sec. V-A (all of them in quick mode too: Table I needs N = 31),
    steady CCW turns at 0.2 m/s, 8 s each (4 s in quick mode), on the surface of scenario ``base``."""
    dur = 4.0 if quick else 8.0
    radii = commanded_radii()
    return radii, [load_scenario(base, {"id": f"{base}_R{R:.4g}", "duration": dur,
                                        "command.segments": [[dur, SWEEP_SPEED, float(R)]]})
                   for R in radii]


def _straight_cal_scenario(base: str, dur: float) -> Scenario:
    """The straight constant-speed mu_roll run (Sec. V-A) on the surface of scenario ``base``."""
    return load_scenario(base, {"id": f"{base}_straight_{CAL_STRAIGHT_SPEED:g}_mu_roll", "duration": dur,
                                "initial_speed": 0.0,
                                "command.segments": [[dur, CAL_STRAIGHT_SPEED, math.inf]]})


def _scored_scenarios(quick: bool) -> dict[str, Scenario]:
    out = {name: load_scenario(name) for name in
           ("circle_vinyl", "straight_0p2_vinyl", "straight_1p5_vinyl", "yu_lemniscate")}
    if quick:
        out["circle_vinyl"] = load_scenario("circle_vinyl", {"duration": 10.0,
                                                             "command.segments": [[10.0, 0.2, 4.0]]})
        out["straight_0p2_vinyl"] = load_scenario("straight_0p2_vinyl", {
            "duration": 4.0, "command.segments": [[4.0, 0.2, math.inf]]})
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
    _, lem_sweep = sweep_scenarios(ctx.quick, LEMNISCATE_SWEEP)
    lem_straight = _straight_cal_scenario(LEMNISCATE_SWEEP, dur)
    scored = _scored_scenarios(ctx.quick)
    requests = [*sweep, straight, *flats.values(), *lem_sweep, lem_straight, *scored.values()]
    runs = iter(ctx.simulate_many([(s, seed) for s in requests]))

    def take(k: int) -> list[Run]:
        return [next(runs) for _ in range(k)]

    out = Experiments(
        radii=radii, sweep=tuple(take(len(sweep))), straight_cal=take(1)[0],
        flat_cal=dict(zip(flats, take(len(flats)))), lem_sweep=tuple(take(len(lem_sweep))),
        lem_straight=take(1)[0], scored=dict(zip(scored, take(len(scored)))), scenarios=scored,
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


def calibrated_lemniscate(ctx: Any) -> Yu2010:
    """Yu2010 calibrated on the lemniscate's surface by the procedure of :func:`calibrated` (mu_roll from
    its straight run, alpha from its sweep's yaw rates, K, mu_sa, mu_op by eq. (28) over its 31 radii): Yu
    identified this surface's K = 0.0009, mu_sa = 0.6488, mu_op = 0.4601 the same way (Secs. V-A, V-C)."""
    memo = _memo(ctx)
    if "calibrated_lemniscate" not in memo:
        ex = experiments(ctx)
        memo["calibrated_lemniscate"] = calibrate(Yu2010(), [*ex.lem_sweep, ex.lem_straight])
    return memo["calibrated_lemniscate"]


def table_ii_params(platform: Mapping[str, Any]) -> YuParams:
    """Table II terrain values (vinyl lab surface) on the run's platform."""
    return YuParams().with_platform(platform)


# ----------------------------------------------------------------------------------- prediction
def _predict(ctx: Any, model: Yu2010, name: str) -> tuple[Run, Any]:
    """Testbed run ``name`` and the model's prediction from its (ramped) command."""
    ex = experiments(ctx)
    run = ex.scored[name]
    scn = ex.scenarios[name]
    cmd = ramped_command(run, scn.command.accel, scn.platform.wheel_radius)
    return run, estimate(model, cmd)
