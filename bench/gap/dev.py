"""Development table for the selection thresholds of :mod:`bench.gap.select`.

    python -m bench.gap.dev [--seeds 0 1] [--out dev.json]

Runs the workflow blind on testbed data with one effect hidden at its development magnitude
(``DEV_HIDDEN``) in the development scenarios (``DEV_SCENARIOS``), on the null case and on the
development out-of-catalogue case, and prints per run: verdict, the gains of every round (accepted
or not), the explained fraction.  The thresholds were set between the largest gain a wrong or
spurious candidate reached and the smallest gain of a true effect in this table (see the
docstring of :mod:`bench.gap.select`).  The tests (``tests/test_gap_hidden.py``) use other
scenarios, seeds and magnitudes.
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from typing import Any

from bench.report.io import atomic_write_json, dumps_json

DEV_SCENARIOS = ("gap_dev_coulomb", "gap_dev_janosi")
DEV_SEEDS = (0, 1, 2, 3, 4)
DEV_HIDDEN: dict[str, dict[str, Any]] = {
    "rolling_resistance": {"terrain.rolling_resistance": 0.07},
    "friction": {"terrain.mu_sa": 0.4437 * 0.68, "terrain.mu_op": 0.3093 * 0.68},
    "shear_displacement": {"terrain.model": "janosi", "terrain.shear_modulus": 0.009},
    "wheel_radius": {"platform.wheel_radius_scale_l": 0.94},
    "cg_offset": {"platform.cg_offset_x": 0.05},
    "payload": {"platform.payload": 8.0},
    "slope": {"terrain.slope": math.radians(4.0)},
    "motor_saturation": {"platform.motor.max_current": 1.2},
    "actuator_delay": {"platform.actuator_delay": 0.08},
    "command_map": {"platform.command_gain_sum": 1.1, "platform.command_gain_diff": 0.8},
    "command_limit": {"platform.command_limit_mean": 4.0, "platform.command_limit_diff": 1.2},
    "encoder_scale": {"platform.sensors.encoder.scale_error_r": 0.03},
    "gyro_bias": {"platform.sensors.imu.gyro_bias_z": 0.01},
}
DEV_TWO = {"wheel_radius+payload": {"platform.wheel_radius_scale_l": 0.94, "platform.payload": 8.0}}  # names joined by +
DEV_OUTSIDE = {"friction_patch": {"terrain.friction_patches": [
    {"x_min": 0.8, "x_max": 2.2, "y_min": -1e3, "y_max": 1e3, "mu_scale": 0.45, "t_period": 2.5}]}}


def hidden_for(scenario: str, name: str) -> dict[str, Any]:
    """Development overrides; the friction scale follows the scenario's terrain."""
    from bench.spec import load_scenario

    h = dict(DEV_HIDDEN.get(name) or DEV_TWO.get(name) or DEV_OUTSIDE[name])
    if name == "friction":
        t = load_scenario(scenario).terrain
        h = {"terrain.mu_sa": t.mu_sa * 0.68, "terrain.mu_op": t.mu_op * 0.68}
    return h


def one(scenario: str, seed: int, name: str) -> dict[str, Any]:
    from bench.gap import find_gap
    from bench.sim import simulate
    from bench.spec import load_scenario, scenario_data

    _, data = scenario_data(scenario)
    hidden = {} if name == "null" else hidden_for(scenario, name)
    if name == "shear_displacement" and data["terrain"].get("model", "janosi") == "janosi":
        hidden = {"terrain.shear_modulus": 2.5 * load_scenario(scenario).terrain.shear_modulus}
    measured = simulate(load_scenario(scenario, hidden), seed)
    t0 = time.perf_counter()
    res = find_gap(measured, scenario)
    rounds = [{"gain": r["gain"], "accepted": r["accepted"],
               "best": (r["fits"] and min(r["fits"], key=lambda f: f["cost_cv"])["effects"][-1]) or None,
               "reason": r["reason"]} for r in res.candidates]
    return {"scenario": scenario, "seed": seed, "hidden": name, "verdict": res.verdict, "kind": res.verdict_kind,
            "named": res.named, "partial": [e["name"] for e in res.partial],
            "params": {e["name"]: e["parameters"] for e in res.effects + res.partial},
            "cost": res.cost, "rounds": rounds, "runtime": time.perf_counter() - t0, "sims": res.n_simulations}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, nargs="*", default=[0])
    ap.add_argument("--null-seeds", type=int, nargs="*", default=list(DEV_SEEDS))
    ap.add_argument("--scenarios", nargs="*", default=list(DEV_SCENARIOS))
    ap.add_argument("--effects", nargs="*", default=list(DEV_HIDDEN) + list(DEV_TWO) + list(DEV_OUTSIDE))
    ap.add_argument("--out", default="")
    a = ap.parse_args(argv)
    rows = []
    for scn in a.scenarios:
        for seed in a.null_seeds:
            rows.append(one(scn, seed, "null"))
            print(dumps_json(rows[-1]), flush=True)
        for name in a.effects:
            for seed in a.seeds:
                rows.append(one(scn, seed, name))
                print(dumps_json(rows[-1]), flush=True)
    if a.out:
        atomic_write_json(a.out, rows)
    print(dumps_json(summarise(rows), indent=1))
    return 0


def summarise(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """The margins the thresholds sit between (all costs in units of J_noise)."""
    def jn(r):
        return r["cost"]["j_noise"]

    null = [r for r in rows if r["hidden"] == "null"]
    single = [r for r in rows if r["hidden"] in DEV_HIDDEN]
    two = [r for r in rows if r["hidden"] in DEV_TWO]
    out_ = [r for r in rows if r["hidden"] in DEV_OUTSIDE]
    true_gains = [r["rounds"][0]["gain"] / jn(r) for r in single if r["rounds"]]
    true_gains += [g["gain"] / jn(r) for r in two for g in r["rounds"]]
    spurious = [g["gain"] / jn(r) for r in single for g in r["rounds"][1:]]
    return {
        "null_excess_max": max(((r["cost"]["nominal"] - jn(r)) / jn(r) for r in null), default=None),
        "null_named": sum(bool(r["named"]) for r in null),
        "true_gain_min": min(true_gains, default=None),
        "spurious_gain_max": max(spurious, default=None),
        "single_correct": sum(r["named"][:1] == [r["hidden"]] for r in single), "single_total": len(single),
        "two_correct": sum(set(r["named"]) == set(r["hidden"].split("+")) for r in two), "two_total": len(two),
        "single_left_max": max((1 - r["cost"]["explained_fraction"] for r in single), default=None),
        "outside_left_min": min((1 - r["cost"]["explained_fraction"] for r in out_), default=None),
        "outside_unexplained": sum(r["kind"] == "unexplained_residual" for r in out_), "outside_total": len(out_),
    }


if __name__ == "__main__":
    sys.exit(main())
