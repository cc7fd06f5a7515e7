"""Greedy selection of missing effects by held-out (cross-validated) cost with a complexity penalty.

Score of a model with ``p`` fitted parameters: ``S = J_cv + KAPPA * J_noise * p`` (``J_cv`` the
linearised two-fold held-out cost of :mod:`bench.gap.fit`, ``J_noise`` the cost sensor noise alone
would leave, :mod:`bench.gap.residuals`).  Greedy: start from the nominal model; screen every
catalogue effect on top of the current model, refine the most promising ones, and keep the best
if its score gain ``G = S_current - S_candidate`` passes all three tests

* ``G >= MIN_GAIN * J_noise`` (absolute: clearly more than fitting sensor noise can give),
* ``G >= MIN_GAIN_FRACTION * E`` (it explains a real part of the current excess
  ``E = J_cv,current - J_noise``),
* ``G >= MIN_GAIN_INITIAL * E_0`` (it is material next to the gap the workflow started from:
  the testbed's cost has small jumps, so a near-perfect model can leave a few units that a
  fudge parameter "explains" by flipping a bistable state).

A second effect is added only if it still pays by the same tests (at most ``max_effects``).
Models with several effects are polished jointly at the end.  Verdict:

* nothing selected and ``E_0 < SIGNIFICANT_EXCESS * J_noise``: "no significant missing effect";
* nothing selected although the excess is significant, or the selected effects leave more than
  ``UNEXPLAINED_FRACTION`` of ``E_0`` (and more than ``SIGNIFICANT_EXCESS * J_noise``):
  "unexplained residual: ..., largest in regime ..."; the effects that helped are reported as
  partial candidates, never named;
* otherwise the selected effects are named with fitted values and standard errors.

Thresholds and how they were chosen
-----------------------------------
Development data only, never the test data of ``tests/test_gap_hidden.py`` (other scenarios,
seeds >= 100, other magnitudes): ``python -m bench.gap.dev --seeds 0 1 --null-seeds 0 1 2 3 4``
on the scenarios ``gap_dev_coulomb`` and ``gap_dev_janosi``: 10 null runs, each of the 11
catalogue effects at its development magnitude (``bench.gap.dev.DEV_HIDDEN``) with 2 seeds in
both scenarios (44 runs), wheel radius + payload (4 runs) and a time-varying friction patch
(4 runs); later also the worked example (``gap_example``, seed 7, 20 s).  Final table (62 runs,
all verdicts as hidden; costs in units of ``J_noise`` ~ 5):

* null runs: nominal excess ``E_0 / J_noise`` <= -0.09 (the replay is exact; the encoder noise
  scale is overestimated, so sensor noise alone costs ~0.9 J_noise);
* smallest gain of a true effect: 0.58 (encoder scale error 3 %), then 4.9 (gyro bias
  0.01 rad/s); all others > 100.  Second true effects (wheel radius + payload): 30-73 % of
  ``E_0``;
* best candidate of a second round that was not a hidden effect (friction patch runs): gains of
  3.4-3.5 % of the current excess (coulomb: cg offset) and 0.5 % (janosi: gyro bias, 0.3 % of
  ``E_0``); worked example before ``MIN_GAIN_INITIAL`` existed: a spurious friction scale with
  gain 0.18 % of ``E_0`` (0.9 J_noise; it flipped a bistable drive torque);
* excess left after the selected true effect(s): <= 0.1 % of ``E_0`` (at the noise level);
  after the friction patch: 53-67 %.

The thresholds sit inside those gaps, on a log scale roughly half-way:

* ``MIN_GAIN = 0.10`` (between the null excess <= -0.09, i.e. no screening, and the smallest true
  gain 0.58; it sets the detection limit: an encoder scale error of about 1.2 %);
* ``MIN_GAIN_FRACTION = 0.10`` (a true effect explained >= 26 % of the current excess, the first
  of two hidden ones included; the wrong second candidate of a patch run <= 3.5 %);
* ``MIN_GAIN_INITIAL = 0.005`` (true second effects >= 30 % of ``E_0``; spurious <= 0.3 %);
* ``SIGNIFICANT_EXCESS = 0.15`` (null <= -0.09);
* ``UNEXPLAINED_FRACTION = 0.15`` (true effects leave <= 0.1 %, the patch >= 53 %);
* ``KAPPA = 0.02``: penalty per parameter (in J_noise); a tie-breaker between candidates of
  equal held-out cost with one or two parameters; it never decided a development case.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from bench.gap.catalogue import CATALOGUE, Effect, nominal_config
from bench.gap.fit import Evaluator, FitResult, Layout, Screen, measured_current_ceiling, refine, refine_many, screen, screen_configs

KAPPA = 0.02
MIN_GAIN = 0.10
MIN_GAIN_FRACTION = 0.10
MIN_GAIN_INITIAL = 0.005
SIGNIFICANT_EXCESS = 0.15
UNEXPLAINED_FRACTION = 0.15
POLISH_MAX_NFEV = 4  # the joint polish starts next to the optimum


@dataclass(frozen=True)
class Thresholds:
    kappa: float = KAPPA
    min_gain: float = MIN_GAIN
    min_gain_fraction: float = MIN_GAIN_FRACTION
    min_gain_initial: float = MIN_GAIN_INITIAL
    significant_excess: float = SIGNIFICANT_EXCESS
    unexplained_fraction: float = UNEXPLAINED_FRACTION
    max_effects: int = 2
    refine_top: int = 3
    refine_rel: float = 0.2
    early_stop: float = 0.01  # stop refining once a fit leaves < 1% of the excess


@dataclass
class Round:
    screens: list[Screen]
    fits: list[FitResult]
    best: FitResult | None
    gain: float
    accepted: bool
    reason: str


@dataclass
class Selection:
    nominal: FitResult
    final: FitResult
    selected: list[str]
    rounds: list[Round]
    j_noise: float
    verdict: str
    named: bool
    explained_fraction: float
    thresholds: Thresholds
    not_applicable: list[str] = field(default_factory=list)


def total_params(fit: FitResult) -> int:
    return sum(len(v) for v in fit.values.values())


def score(fit: FitResult, j_noise: float, thr: Thresholds) -> float:
    return fit.cost_cv + thr.kappa * j_noise * total_params(fit)


def applicable(effect: Effect, physics_model: bool) -> bool:
    return physics_model or effect.kind in ("sensor",)


def mirror_start(effect: Effect, scn, theta) -> tuple[float, ...] | None:
    """The screening estimate reflected about the neutral value in the parameters whose response
    is partly even (``Param.mirror``): a second start for the refinement."""
    neutral = effect.neutral(scn)
    if neutral is None or not any(p.mirror for p in effect.params):
        return None
    out = []
    for p, n, v in zip(effect.params, neutral, theta):
        d = v - n
        if p.mirror:
            d = d if abs(d) >= p.step else math.copysign(p.step, d)
            out.append(n - d)
        else:
            out.append(v)
    return tuple(out)


def run_selection(ev: Evaluator, catalogue: Sequence[Effect] = CATALOGUE, thr: Thresholds = Thresholds(),
                  physics_model: bool = True, progress=None) -> Selection:
    scn, space = ev.scn, ev.space
    jn = max(space.j_noise, 1e-9)
    nominal = refine(ev, Layout((), nominal_config(scn)), [])
    current = nominal
    e0 = nominal.cost - jn
    selected: list[tuple[Effect, tuple[float, ...]]] = []
    rounds: list[Round] = []
    na = [e.name for e in catalogue if not applicable(e, physics_model)]
    for _ in range(thr.max_effects):
        excess = current.cost_cv - jn
        # a further effect could gain at most the excess: stop when that cannot pass the tests
        if excess < thr.min_gain * jn or (selected and excess < thr.min_gain_initial * e0):
            break
        base = current.config
        z0 = ev.z(base)
        cost0 = float(z0 @ z0)
        sig0 = ev.signals(base)
        ceiling = measured_current_ceiling(space, sig0)
        cands = [e for e in catalogue if applicable(e, physics_model) and e.name not in {s.name for s, _ in selected}]
        ev.prefetch([c for e in cands for c in screen_configs(ev, e, base, ceiling)])
        screens = [screen(ev, e, base, cost0, z0, sig0, ceiling) for e in cands]
        if progress:
            progress(f"screened {len(screens)} effects ({ev.n_sims} simulations so far)")
        gains = np.array([cost0 - s.predicted_cost for s in screens])
        order = np.argsort(-gains, kind="stable")
        best_gain = gains[order[0]] if gains.size else 0.0
        pick = [i for i in order[: thr.refine_top] if gains[i] > 0 and gains[i] >= thr.refine_rel * best_gain]
        fixed = tuple(selected)
        prior = current.jac if fixed else None
        jobs = []
        for i in pick:
            lay = Layout((cands[i],), nominal_config(scn), fixed)
            jobs.append((lay, screens[i].theta, prior))
            mirrored = mirror_start(cands[i], scn, screens[i].theta)
            if mirrored is not None:
                jobs.append((lay, mirrored, prior))
        # refine in batches of `workers`; stop once a fit leaves (almost) nothing to explain
        fits: list[FitResult] = []
        batch = max(1, ev.workers)
        for k in range(0, len(jobs), batch):
            fits += refine_many(ev, jobs[k:k + batch])
            best_left = min(f.cost_cv for f in fits) - jn
            if best_left <= max(thr.early_stop * excess, thr.min_gain * jn):
                break
        if progress:
            progress(f"refined {[f.effects[-1] for f in fits]} ({ev.n_sims} simulations so far)")
        if not fits:
            rounds.append(Round(screens, [], None, 0.0, False, "no candidate reduces the cost"))
            break
        cur_score = score(current, jn, thr)
        scores = [score(f, jn, thr) for f in fits]
        b = int(np.argmin(scores))
        best = fits[b]
        gain = cur_score - scores[b]
        need = {"absolute": thr.min_gain * jn, "current excess": thr.min_gain_fraction * max(excess, 0.0),
                "initial excess": thr.min_gain_initial * max(e0, 0.0)}
        accepted = bool(all(gain >= v for v in need.values()))
        reason = (f"gain {gain:.3g} vs needed " + ", ".join(f"{v:.3g} ({k})" for k, v in need.items()))
        rounds.append(Round(screens, fits, best, float(gain), accepted, reason))
        if not accepted:
            break
        eff = next(e for e in catalogue if e.name == best.effects[-1])
        vals = tuple(best.values[eff.name][p.name] for p in eff.params)
        selected.append((eff, vals))
        current = best
    if len(selected) > 1:  # joint polish: the first effect was fitted without the later ones
        lay = Layout(tuple(e for e, _ in selected), nominal_config(scn))
        theta0 = [v for _, vals in selected for v in vals]
        joint = refine(ev, lay, theta0, max_nfev=POLISH_MAX_NFEV)
        if joint.cost <= current.cost:
            current = joint
    ef = current.cost_cv - jn
    frac = float((e0 - max(ef, 0.0)) / e0) if e0 > 0 else 0.0
    sel_names = [e.name for e, _ in selected]
    if not selected:
        if e0 < thr.significant_excess * jn:
            verdict, named = "no significant missing effect", False
        else:
            verdict, named = "unexplained residual", False
    elif ef > thr.unexplained_fraction * e0 and ef > thr.significant_excess * jn:
        verdict, named = "unexplained residual", False
    else:
        verdict, named = "missing effect", True
    return Selection(nominal, current, sel_names, rounds, jn, verdict, named, frac, thr, na)


__all__ = ["Thresholds", "Selection", "Round", "run_selection", "score", "KAPPA", "MIN_GAIN", "MIN_GAIN_FRACTION",
           "SIGNIFICANT_EXCESS", "UNEXPLAINED_FRACTION"]
