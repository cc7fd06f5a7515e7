"""Mandow 2007 on the testbed, repeated over seeds: the 95 % intervals behind the claims of Sec. IV-C and IV-D.

Two compute functions of ``scenarios/papers/mandow2007.toml`` (re-exported by :mod:`methods.mandow2007.repro`):

``indexes`` (Sec. IV-C: y_ICRv, chi of eq. (9), e of eq. (10) and alpha across the six terrain / tire conditions)
    The GA of Sec. III (the plugin ``mandow2007.asymmetric_ga``, the mode's settings) identifies K on each
    calibration path ALONE (``Settings.interval_seeds``; quick: the 30 s paths), so that every condition has one K
    per seed.  Per condition: the mean over seeds and the half-width of its 95 % Student-t interval
    (:func:`bench.reproduce.half_width`).  Each comparative statement of Sec. IV-C is a paired difference per seed
    (the same seed draws the same joystick path on every terrain and tire): its mean is the difference of the
    compared means and the half-width of its 95 % interval is the claim's margin.

``validation`` (Sec. IV-D, Fig. 6: whole-path dead reckoning against the DGPS)
    The models of Table III (GA asymmetric, P3-AT default, symmetric of eqs. (11)-(12); DE beside them), calibrated
    as in :mod:`methods.mandow2007.repro`, dead-reckon the joystick paths of ``Settings.validation_seeds_full``
    (quick: ``validation_seeds_quick``; none of them a calibration seed) from the first DGPS pose; position RMS
    against the DGPS.  Per validated condition: mean over seeds per model, and the 95 % half-width of the paired
    per-seed difference between the asymmetric model and the better of the two others (by mean).
"""
from __future__ import annotations

from typing import Any, Mapping, Sequence

import numpy as np

from bench import registry
from bench.metrics import Trajectory, position_rms
from bench.reproduce import half_width

__all__ = ["half_width", "paired_statistics", "indexes", "validation", "INDEX_NAMES"]

INDEX_NAMES = ("y_icr_v", "chi", "e", "alpha_dev")
_SEEDS_KEY = "_mandow2007_seed_identifications"


def paired_statistics(a: Sequence[float], b: Sequence[float]) -> tuple[float, float, float]:
    """(mean of a, mean of b, 95 % half-width of the mean of the paired differences a - b)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(a.mean()), float(b.mean()), half_width(a - b)


def _index_values(params: Any, track: float) -> dict[str, float]:
    return {"y_icr_v": float(params.y_icr_v), "chi": float(params.steering_efficiency(track)),
            "e": float(params.eccentricity()),
            "alpha_dev": 0.5 * (abs(1.0 - params.alpha_l) + abs(1.0 - params.alpha_r))}


def _per_seed(ctx: Any) -> dict[tuple[str, str], list[dict[str, float]]]:
    """(terrain, tire) -> one dict of indexes per interval seed (GA on that seed's joystick path alone)."""
    cached = ctx.scratch.get(_SEEDS_KEY)
    if cached is not None:
        return cached
    from methods.mandow2007 import repro as R

    s = R.SETTINGS
    quick = bool(ctx.quick)
    dur = s.quick_duration if quick else None
    seeds = s.interval_seeds
    runs = ctx.simulate_many([(R._scenario("joystick", t, w, dur), seed) for t, w in R.CONDITIONS for seed in seeds])
    ga = s.ga_quick if quick else s.ga_full
    jobs = [("ga", ga, s.segment_period, [run]) for run in runs]
    methods = R._identify_all(jobs, getattr(ctx.runner, "workers", 1))
    out: dict[tuple[str, str], list[dict[str, float]]] = {}
    for i, cond in enumerate(R.CONDITIONS):
        track = R._scenario("joystick", *cond).platform.track
        out[cond] = [_index_values(m.params, track) for m in methods[i * len(seeds):(i + 1) * len(seeds)]]
    ctx.scratch[_SEEDS_KEY] = out
    ctx.info["interval_seeds"] = list(seeds)
    return out


def indexes(ctx: Any) -> dict[str, float]:
    """Sec. IV-C across the six conditions, per calibration seed: means, 95 % half-widths and the paired
    differences of the section's statements."""
    from methods.mandow2007 import repro as R

    per = _per_seed(ctx)
    key = {c: f"{c[0]}_{R.SHORT[c[1]]}" for c in R.CONDITIONS}
    out: dict[str, float] = {}
    for c, vals in per.items():
        for name in INDEX_NAMES:
            x = [v[name] for v in vals]
            out[f"{key[c]}_{name}_mean"] = float(np.mean(x))
            out[f"{key[c]}_{name}_half95"] = half_width(x)
    n = len(R.SETTINGS.interval_seeds)
    col = {name: {c: np.array([v[name] for v in per[c]]) for c in R.CONDITIONS} for name in INDEX_NAMES}
    # y_ICRv: "always about 1 cm behind of the frame origin" -- mean over the six conditions, per seed
    y = np.mean([col["y_icr_v"][c] for c in R.CONDITIONS], axis=0)
    out["y_icr_v_mean"], out["y_icr_v_half95"] = float(y.mean()), half_width(y)
    ymeans = [out[f"{key[c]}_y_icr_v_mean"] for c in R.CONDITIONS]
    out["y_icr_v_max"], out["y_icr_v_min"] = max(ymeans), min(ymeans)
    pub_y = [R.published_parameters(t, w)["y_icr_v"] for t, w in R.CONDITIONS]
    out["published_y_icr_v_mean"] = float(np.mean(pub_y))
    # chi lower on asphalt than on smooth concrete (50 psi, the only tire for which Tables I-II support it)
    a, b = col["chi"][("asphalt", "pneumatic_50psi")], col["chi"][("smooth_concrete", "pneumatic_50psi")]
    out["chi_asphalt_minus_concrete_50psi"], out["chi_asphalt_concrete_50psi_half95"] = float(np.mean(a - b)), \
        half_width(a - b)
    # solid tires: better steering efficiency than pneumatic ones (every terrain, both pressures)
    pneu = [c for c in R.CONDITIONS if c[1] != "solid"]
    solid = [c for c in R.CONDITIONS if c[1] == "solid"]
    pmax = np.max([col["chi"][c] for c in pneu], axis=0)
    smin = np.min([col["chi"][c] for c in solid], axis=0)
    out["pneumatic_max_chi"], out["solid_min_chi"], out["chi_pneumatic_solid_half95"] = paired_statistics(pmax, smin)
    # alpha closer to 1 at 50 psi than at 20 psi, per terrain
    for terrain in R.TERRAINS:
        d50, d20 = col["alpha_dev"][(terrain, "pneumatic_50psi")], col["alpha_dev"][(terrain, "pneumatic_20psi")]
        out[f"{terrain}_alpha_dev_50psi"], out[f"{terrain}_alpha_dev_20psi"], out[f"{terrain}_alpha_dev_half95"] = \
            paired_statistics(d50, d20)
    # e: "always very close to zero"
    out["e_abs_max"] = max(abs(out[f"{key[c]}_e_mean"]) for c in R.CONDITIONS)
    out["n_seeds"] = float(n)
    ctx.note("indexes", (
        f"GA (Sec. III, {'quick' if ctx.quick else 'full'} settings) on each calibration path alone, seeds "
        f"{list(R.SETTINGS.interval_seeds)} ({'30 s' if ctx.quick else '60 s'} each): one K per condition and seed. "
        "*_half95: half-width of the 95 % Student-t interval of the mean over the seeds; the comparisons are paired "
        "per seed (a seed draws the same joystick path on every terrain and tire). Published values (real robot): "
        "Tables I-II; the testbed's tire platforms differ in wheel radius, tire pressure or modulus and rolling "
        "resistance (scenarios/platforms/p3at_*.toml), and its centre of mass is the labelled testbed draw "
        "(-4.0, +2.6) mm from the frame origin. " + R.terrain_text()))
    f = {k: f"{v:+.4f}" for k, v in out.items()}
    ctx.note("y_icr_v_behind", "y_ICRv per condition (mean over seeds): " + ", ".join(
        f"{key[c]} {f[key[c] + '_y_icr_v_mean']}" for c in R.CONDITIONS) + f" m; published mean "
        f"{f['published_y_icr_v_mean']} m")
    ctx.note("chi_asphalt_lt_concrete_50psi", (
        f"chi 50 psi: asphalt {out['asphalt_50psi_chi_mean']:.4f}, smooth concrete "
        f"{out['smooth_concrete_50psi_chi_mean']:.4f}; paired difference {f['chi_asphalt_minus_concrete_50psi']} "
        f"+- {out['chi_asphalt_concrete_50psi_half95']:.4f} (95 %); published "
        f"{R.published_parameters('asphalt', 'pneumatic_50psi')['chi']:.4f} vs "
        f"{R.published_parameters('smooth_concrete', 'pneumatic_50psi')['chi']:.4f}"))
    ctx.note("chi_solid_gt_pneumatic", "chi per condition: " + ", ".join(
        f"{key[c]} {out[key[c] + '_chi_mean']:.4f}" for c in R.CONDITIONS))
    for terrain in R.TERRAINS:
        ctx.note(f"alpha_closer_to_1_at_50psi_{terrain}", (
            f"mean abs(1 - alpha): 50 psi {out[f'{terrain}_alpha_dev_50psi']:.4f}, 20 psi "
            f"{out[f'{terrain}_alpha_dev_20psi']:.4f} (+- {out[f'{terrain}_alpha_dev_half95']:.4f}, 95 %, paired)"))
    ctx.note("e_near_zero", "e per condition: " + ", ".join(f"{key[c]} {f[key[c] + '_e_mean']}" for c in R.CONDITIONS))
    return out


def _validation_runs(ctx: Any) -> dict[tuple[str, str], list[Any]]:
    from methods.mandow2007 import repro as R

    s = R.SETTINGS
    ev = R._evaluate(ctx)
    seeds = s.validation_seeds_quick if ctx.quick else s.validation_seeds_full
    dur = s.quick_duration if ctx.quick else None
    validated = [c for c, cond in ev.conditions.items() if cond.symmetric is not None]
    runs = ctx.simulate_many([(R._scenario("joystick", t, w, dur), seed) for t, w in validated for seed in seeds])
    ctx.info["validation_seeds"] = list(seeds)
    return {c: runs[i * len(seeds):(i + 1) * len(seeds)] for i, c in enumerate(validated)}


def _truth_segments(k: str, runs: Sequence[Any], ests: Mapping[str, Sequence[Any]]) -> dict[str, float]:
    """A diagnostic of the Table III claims below the DGPS floor: on 2 s segments against the testbed truth (at the
    DGPS instants), on how many validation paths the asymmetric model's mean squared Delta x / Delta y (Mandow's
    axes) is lower than the better other model's by more than two standard errors (batch means of 2 segments,
    :func:`methods.mandow2007.repro.paired_margin`), and on how many its mean is lower at all."""
    from methods.mandow2007 import repro as R

    models = ("asymmetric", "p3at", "symmetric")
    segs = [{m: R._segments(run, ests[m][i], "truth", 2.0) for m in models} for i, run in enumerate(runs)]
    out: dict[str, float] = {}
    for axis, attr in (("dx", "dy"), ("dy", "dx")):  # Mandow's X lateral = suite y, Y forward = suite x
        resolved = lower = 0
        for seg in segs:
            sq = {m: getattr(s, attr) ** 2 for m, s in seg.items()}
            best = min(("p3at", "symmetric"), key=lambda m: float(sq[m].mean()))
            d = float(sq["asymmetric"].mean() - sq[best].mean())
            lower += int(d < 0)
            resolved += int(d + R.paired_margin(sq["asymmetric"], sq[best], batch=2) < 0)
        out[f"{k}_truth2s_asymmetric_lower_{axis}"] = float(lower)
        out[f"{k}_truth2s_asymmetric_resolved_{axis}"] = float(resolved)
    return out


def validation(ctx: Any) -> dict[str, float]:
    """Fig. 6 over the validation seeds: whole-path dead-reckoning position RMS against the DGPS per model,
    the paired 95 % half-width of asymmetric minus the better other model, per validated condition."""
    from methods.mandow2007 import repro as R

    ev = R._evaluate(ctx)
    out: dict[str, float] = {}
    best_count = 0
    path_rms: dict[str, np.ndarray] = {}  # the Table III condition's, per path, for the claim's note
    per_cond = _validation_runs(ctx)
    for c, runs in per_cond.items():
        cond = ev.conditions[c]
        models: Mapping[str, Any] = {"asymmetric": cond.ga, "asymmetric_de": cond.de, "symmetric": cond.symmetric,
                                     "p3at": registry.calibrate(R.M.DefaultP3at(), [])}
        ests = {m: [registry.estimate(method, r) for r in runs] for m, method in models.items()}
        rms = {m: np.array([position_rms(Trajectory.from_run(r, "ref"), Trajectory.from_estimate(e))
                            for r, e in zip(runs, es)]) for m, es in ests.items()}
        k = f"{c[0]}_{R.SHORT[c[1]]}"
        if c == R.SETTINGS.table3_condition:
            path_rms = rms
            out.update(_truth_segments(k, runs, ests))
        for m, v in rms.items():
            out[f"{k}_{m}_path_rms_mean"] = float(v.mean())
        best = min(("p3at", "symmetric"), key=lambda m: rms[m].mean())
        a, b, h = paired_statistics(rms["asymmetric"], rms[best])
        out[f"{k}_others_min_path_rms_mean"], out[f"{k}_path_rms_half95"] = b, h
        out[f"{k}_asymmetric_best"] = float(a + h < b)
        best_count += int(a + h < b)
    out["n_validated"], out["n_asymmetric_best"] = float(len(per_cond)), float(best_count)
    seeds = ctx.info["validation_seeds"]
    ctx.note("validation", (
        f"Joystick paths of seeds {seeds} ({'30 s, quick' if ctx.quick else '60 s'}), none a calibration seed; models "
        "calibrated as for Table III; dead reckoning from the first DGPS pose, position RMS against the DGPS. "
        "*_path_rms_half95: 95 % half-width of the mean paired difference asymmetric minus the better other model; "
        "*_asymmetric_best = 1 when the asymmetric mean is lower by more than it."))
    k = "{}_{}".format(R.SETTINGS.table3_condition[0], R.SHORT[R.SETTINGS.table3_condition[1]])
    if f"{k}_path_rms_half95" in out:
        ctx.note("asym_best_path", ", ".join(f"{m} {out[f'{k}_{m}_path_rms_mean']:.3f} m" for m in
                                             ("asymmetric", "p3at", "symmetric", "asymmetric_de"))
                 + f" (mean over {len(seeds)} paths); 95 % half-width of the paired difference "
                 f"{out[f'{k}_path_rms_half95']:.3f} m; per path (seed: asymmetric / symmetric) " + ", ".join(
                     f"{sd}: {a:.2f} / {b:.2f}" for sd, a, b in zip(seeds, path_rms["asymmetric"],
                                                                     path_rms["symmetric"])) + " m")
    ctx.note("asym_best_path_all_conditions", "asymmetric lowest by more than the 95 % half-width in: " + (", ".join(
        key[:-len("_asymmetric_best")] for key, v in out.items()
        if key.endswith("_asymmetric_best") and key != "n_asymmetric_best" and v) or "none") + f" (of {int(out['n_validated'])} validated)")
    return out
