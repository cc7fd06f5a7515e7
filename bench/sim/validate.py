"""Physics checks of the testbed against the papers (``skidbench validate-testbed``).

Each check simulates short runs and compares with a paper's measurement or a closed form:

* chi over curvature ratio 0..7 at 0.1..0.5 m/s (Wang 2015 Table 3 / Fig. 12: 1.47 -> 1.41),
  measured as Wang does, eq. (25): chi = (S_r - S_l) / (phi B) over the steady part of a run;
* closed form: Coulomb friction, equal loads, pure rotation: chi = 1 + (a/b)^2 (1.456 for P3-AT);
* steady motor torque magnitude vs Yu's 31 commanded radii (Yu 2010 Fig. 9: decreasing);
* 1.5 m/s straight command saturating (Yu Fig. 17: 0.93 m/s);
* ramps (Yu Figs. 18-20): 5.4 deg asphalt holds its speed, 15 deg wood decelerates from 0.49 m/s,
  13.5 deg white board fails to climb.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from bench.sim import simulate
from bench.spec import CommandSpec, Scenario, Segment, load_scenario

WANG_CHI_TABLE3 = (1.4662, 1.4480, 1.4394, 1.4341, 1.4215, 1.4232, 1.4165, 1.4115)  # lambda = 0..7


def yu_commanded_radii() -> np.ndarray:
    """Yu 2010 Sec. V-A: {0.2, 0.3, ..., 1, 2, ..., 10, 10^1.2, ..., 10^2, 10^2.2, ..., 10^3.2, 10^3.6, 10^4}.

    Read as: 0.2..1.0 in steps of 0.1 (9), 2..10 in steps of 1 (9), 10^1.2..10^3.2 in steps of
    10^0.2 (11), then 10^3.6 and 10^4 (2): 31 radii, matching the paper's N = 31.
    """
    a = np.round(np.arange(2, 11) * 0.1, 10)
    b = np.arange(2, 11, dtype=float)
    c = 10.0 ** np.round(np.arange(1.2, 3.2001, 0.2), 10)
    d = 10.0 ** np.array([3.6, 4.0])
    return np.concatenate([a, b, c, d])


def chi_eq25(run_data: Any, platform: Any, t_from: float) -> float:
    """Wang eq. (25) on the truth of a run: chi = (S_r - S_l) / (phi B) from t_from to the end."""
    d = run_data[run_data["t"] >= t_from]
    t = d["t"].to_numpy()
    dt = np.diff(t)
    r_l = platform.wheel_radius * platform.wheel_radius_scale_l
    r_r = platform.wheel_radius * platform.wheel_radius_scale_r
    s_l = np.sum(d["truth_wl"].to_numpy()[:-1] * dt) * r_l
    s_r = np.sum(d["truth_wr"].to_numpy()[:-1] * dt) * r_r
    yaw = np.unwrap(d["truth_yaw"].to_numpy())
    return float((s_r - s_l) / ((yaw[-1] - yaw[0]) * platform.track))


@dataclass(frozen=True)
class Check:
    name: str
    passed: bool
    measured: Any
    expected: str
    source: str


def _with_command(base: Scenario, cmd: CommandSpec, duration: float, **kw: Any) -> Scenario:
    return dataclasses.replace(base, command=cmd, duration=duration, **kw)


def chi_grid(base: Scenario, speeds=(0.1, 0.2, 0.3, 0.4, 0.5), ratios=range(8), duration: float = 6.0,
             settle: float = 3.0, seed: int = 0) -> np.ndarray:
    out = np.empty((len(speeds), len(ratios)))
    for i, v in enumerate(speeds):
        for j, lam in enumerate(ratios):
            cmd = CommandSpec(kind="v_curvature_ratio", segments=(Segment(duration, v, float(lam)),))
            run = simulate(_with_command(base, cmd, duration), seed)
            out[i, j] = chi_eq25(run.data, base.platform, settle)
    return out


def torque_vs_radius(base: Scenario, v: float = 0.2, duration: float = 8.0, settle: float = 4.0,
                     seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    radii = yu_commanded_radii()
    tl, tr = np.empty(radii.size), np.empty(radii.size)
    for k, R in enumerate(radii):
        cmd = CommandSpec(kind="v_radius", segments=(Segment(duration, v, float(R)),))
        run = simulate(_with_command(base, cmd, duration), seed)
        d = run.data[run.data["t"] >= settle]
        tl[k], tr[k] = np.nanmean(d["tau_l"]), np.nanmean(d["tau_r"])
    return radii, tl, tr


def _final_speed(name: str, seed: int = 0, tail: float = 1.0) -> tuple[float, np.ndarray, np.ndarray]:
    scn = load_scenario(name)
    run = simulate(scn, seed)
    t, v = run.data["t"].to_numpy(), run.data["truth_vx"].to_numpy()
    return float(np.mean(v[t >= t[-1] - tail])), t, v


def run_checks(progress: Callable[[str], None] | None = None, quick: bool = False) -> list[Check]:
    say = progress or (lambda s: None)
    checks: list[Check] = []
    base = load_scenario("circle_vinyl")

    say("chi over curvature ratio and speed (Wang 2015 Table 3)")
    speeds = (0.1, 0.3, 0.5) if quick else (0.1, 0.2, 0.3, 0.4, 0.5)
    grid = chi_grid(base, speeds=speeds)
    in_band = bool(np.all((grid >= 1.2) & (grid <= 1.8)))
    noise = 0.01  # Wang Table 3's largest sigma is 0.008
    non_increasing = bool(np.all(np.diff(grid, axis=1) <= noise))
    spread = float(np.max((grid.max(axis=0) - grid.min(axis=0)) / grid.mean(axis=0)))
    checks.append(Check("chi_in_band", in_band, grid.round(4).tolist(), "every chi in [1.2, 1.8]", "issue; Wang 2015 Table 3"))
    checks.append(Check("chi_non_increasing", non_increasing, grid.mean(axis=0).round(4).tolist(),
                        f"chi non-increasing in curvature ratio 0..7 (within {noise}); Wang: {list(WANG_CHI_TABLE3)}",
                        "Wang 2015 Table 3, Fig. 12a"))
    checks.append(Check("chi_speed_invariant", spread < 0.05, round(spread, 4),
                        "relative spread over 0.1-0.5 m/s < 5% at each curvature ratio", "Wang 2015 Fig. 12b"))

    say("closed form: Coulomb pure rotation chi = 1 + (a/b)^2")
    coul = dataclasses.replace(base.terrain, model="coulomb", mu_lat_ratio=1.0)
    rot = CommandSpec(kind="rotation", v=0.2)
    run = simulate(dataclasses.replace(base, terrain=coul, command=rot, duration=6.0), 0)
    a, b = base.platform.wheelbase / 2, base.platform.track / 2
    expect = 1 + (a / b) ** 2
    got = chi_eq25(run.data, base.platform, 3.0)
    checks.append(Check("coulomb_rotation_closed_form", abs(got / expect - 1) < 0.02, round(got, 4),
                        f"{expect:.4f} within 2% (Wang Table 3 measured 1.4662)", "issue closed-form anchor"))

    say("steady torque vs Yu's 31 commanded radii (Fig. 9)")
    radii, tl, tr = torque_vs_radius(base)
    mag = np.abs(tl) + np.abs(tr)
    # non-increasing within 2% of the range (numerical noise of the steady averages)
    tol = 0.02 * (mag.max() - mag.min())
    checks.append(Check("torque_decreases_with_radius", bool(np.all(np.diff(mag) <= tol)),
                        {"radius": radii.round(3).tolist(), "tau_l": tl.round(3).tolist(), "tau_r": tr.round(3).tolist()},
                        "|tau_l| + |tau_r| non-increasing as the commanded radius grows", "Yu 2010 Fig. 9"))

    say("speed saturation at a 1.5 m/s command (Fig. 17)")
    v_sat, _, _ = _final_speed("straight_1p5_vinyl")
    checks.append(Check("saturation_speed", 0.85 <= v_sat <= 1.0, round(v_sat, 4), "in [0.85, 1.0] m/s (Yu: 0.93)", "Yu 2010 Fig. 17"))

    say("ramps (Figs. 18-20)")
    v_asph, t, v = _final_speed("ramp_asphalt_5p4")
    cmd = 0.7
    checks.append(Check("ramp_5p4_holds_speed", abs(v_asph - cmd) / cmd < 0.1 and bool(np.all(np.diff(v[t > 2]) > -1e-3)),
                        round(v_asph, 4), "holds ~0.7 m/s (within 10%)", "Yu 2010 Fig. 18"))
    v_wood, t, v = _final_speed("ramp_wood_15")
    checks.append(Check("ramp_15_decelerates", v_wood < 0.49 - 0.02, round(v_wood, 4),
                        "speed falls below the 0.49 m/s initial speed", "Yu 2010 Fig. 19"))
    v_wb, t, v = _final_speed("ramp_whiteboard_13p5")
    checks.append(Check("ramp_13p5_fails", v_wb <= 0.0, round(v_wb, 4), "does not climb: speed <= 0 at the end", "Yu 2010 Fig. 20"))
    return checks
