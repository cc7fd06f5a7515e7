"""Screening the effect catalogue: a cheap estimate of every candidate on top of the current model, which
decides what :mod:`bench.gap.select` refines with :func:`bench.gap.fit.refine`.

Screening (cheap, one simulation per parameter and one more): the residual's sensitivity to each
parameter at the effect's neutral value (forward difference with the parameter's probe step),
then a bounded *linear* least-squares step (``scipy.optimize.lsq_linear``) predicts the fitted
value and cost, and the estimate is simulated (:func:`simulate_estimates`): the selection refines the
best candidates by either cost (the linear prediction misranked an effect whose response bends, a
friction change on Coulomb ground predicted at 10 x its simulated cost).  Effects without a neutral
value (Coulomb -> shear displacement) are screened on a grid of simulations; motor saturation is
screened at the ceiling seen in the measured currents; the actuator delay on a time-shift surrogate
of the nominal signals (bounded scalar minimisation, ``minimize_scalar``); sensor effects are fitted
exactly (no simulation).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Mapping, Sequence

import numpy as np
from scipy.optimize import lsq_linear, minimize_scalar

from bench.gap.catalogue import Effect, ModelConfig
from bench.gap.fit import Evaluator, Layout, _clip, refine
from bench.gap.residuals import ResidualSpace
from bench.spec import Scenario


@dataclass(frozen=True)
class Screen:
    effect: str
    theta: tuple[float, ...]  # estimate of the candidate's parameters
    predicted_cost: float
    evaluated: bool  # predicted_cost is an actual evaluation (not a linear prediction)
    note: str = ""
    # d z / d u at the effect's neutral value (rows of ResidualSpace.zvec, columns the parameters in the
    # fit's variables u: log10 for scale parameters); None where the effect has no neutral value (grid
    # screening) or no response there (a current ceiling that never binds).  For detection limits.
    sensitivity: np.ndarray | None = field(default=None, repr=False, compare=False)
    # a linearised screen's cost simulated at its estimate (simulate_estimates); None for the other screens,
    # whose predicted_cost is an evaluation already
    simulated_cost: float | None = None

    @property
    def best_cost(self) -> float:
        """The lower of the screen's cost and its simulated one (the second ranking of the refinement)."""
        return self.predicted_cost if self.simulated_cost is None else min(self.predicted_cost, self.simulated_cost)


def _probe_thetas(effect: Effect, lay: Layout, neutral: Sequence[float], scn: Scenario) -> list[np.ndarray]:
    """The linearised screening's probe points: each parameter moved by its probe step from the neutral value."""
    out = []
    for j, p in enumerate(effect.params):
        th = np.array(neutral, float)
        th[j] = th[j] * 10 ** p.step if p.log else th[j] + p.step
        out.append(_clip(th, lay, scn))
    return out


def screen_configs(ev: Evaluator, effect: Effect, base: ModelConfig, measured_i_max: float | None
                   ) -> list[ModelConfig]:
    """The simulations screening ``effect`` will need (for batching)."""
    scn = ev.scn
    lay = Layout((effect,), base)
    if effect.kind == "physics":
        neutral = effect.neutral(scn)
        if neutral is None:
            return [lay.config(scn, g) for g in effect.probe_grid]
        if effect.name == "motor_saturation":
            if measured_i_max is None:
                return []
            return [lay.config(scn, (measured_i_max,))]
        return [lay.config(scn, th) for th in _probe_thetas(effect, lay, neutral, scn)]
    return []


def screen(ev: Evaluator, effect: Effect, base: ModelConfig, cost0: float, z0: np.ndarray,
           nominal_signals: Mapping[str, np.ndarray], measured_i_max: float | None) -> Screen:
    """Screening estimate of ``effect`` on top of the model ``base`` (residual ``z0``)."""
    scn = ev.scn
    lay = Layout((effect,), base)
    neutral = effect.neutral(scn)
    if effect.kind == "sensor":  # from the best of neutral and the grid (cheap: no simulation)
        start = min([tuple(neutral)] + list(effect.probe_grid), key=lambda g: ev.cost(lay.config(scn, g)))
        res = refine(ev, lay, np.array(start, float), max_nfev=20)
        return Screen(effect.name, res.theta, res.cost, True, "exact (sensor effect, no simulation)",
                      sensitivity=res.jac)
    if effect.kind == "delay":
        d0 = neutral[0]
        p = effect.params[0]

        def f(s: float) -> float:
            return ev.cost(base.replace(shift=base.shift + s))

        r = minimize_scalar(f, bounds=(0.0, p.upper - d0), method="bounded", options={"xatol": 1e-4})
        h = 0.25 * scn.dt
        sens = ((ev.z(base.replace(shift=base.shift + h)) - z0) / h)[:, None]
        return Screen(effect.name, (d0 + float(r.x),), float(r.fun), True, "time-shift surrogate", sensitivity=sens)
    if neutral is None:
        best = None
        for g in effect.probe_grid:
            c = ev.cost(lay.config(scn, g))
            if best is None or c < best[1]:
                best = (g, c)
        return Screen(effect.name, tuple(best[0]), best[1], True, "grid")
    if effect.name == "motor_saturation":
        if measured_i_max is None:
            return Screen(effect.name, tuple(neutral), cost0, True, "no current ceiling below the model's")
        th = (measured_i_max,)
        return Screen(effect.name, th, ev.cost(lay.config(scn, th)), True, "measured current ceiling")
    th0 = np.array(neutral, float)
    u0 = lay.to_u(th0)
    cols = []
    for j, th in enumerate(_probe_thetas(effect, lay, neutral, scn)):
        du = lay.to_u(th)[j] - u0[j]
        cols.append((ev.z(lay.config(scn, th)) - z0) / du)
    S = np.column_stack(cols)
    lo, hi = lay.bounds_u(scn)
    r = lsq_linear(S, -z0, bounds=(lo - u0, hi - u0))
    u = u0 + r.x
    pred = float(np.sum((z0 + S @ r.x) ** 2))
    return Screen(effect.name, tuple(lay.to_theta(u)), pred, False, "linearised", sensitivity=S)


def simulate_estimates(ev: Evaluator, effects: Sequence[Effect], screens: Sequence[Screen], base: ModelConfig
                       ) -> list[Screen]:
    """The linearised screens with their estimate simulated (in parallel): ``simulated_cost``, an upper bound of what
    the refinement, started at the estimate, reaches.  The selection refines the best candidates by the linear
    prediction and by ``best_cost`` (:func:`bench.gap.select.run_selection`): each ranking has its blind spot.  The
    linear prediction misranks an effect whose response bends: a friction scale of 0.8 hidden on Coulomb ground was
    predicted to cost 363 from its probe at 1.15, behind a wrong effect's 129 (speed_slip), so it was never refined;
    simulated at its estimate (0.835) it costs 36 (tests/test_gap_blind_speed_slip.py).  The simulated cost misranks
    an effect whose response is even in a parameter (a CoM offset x): its linear estimate is no fit at all, but the
    refinement, started from both signs, finds it; ranked by the simulated costs alone it fell out of the top three
    (tests/test_gap_hidden.py, two hidden effects).  Other screens (evaluated already) are returned unchanged."""
    scn = ev.scn
    todo = [(i, Layout((e,), base)) for i, (e, s) in enumerate(zip(effects, screens)) if not s.evaluated]
    ev.prefetch([lay.config(scn, screens[i].theta) for i, lay in todo])
    out = list(screens)
    for i, lay in todo:
        out[i] = dataclasses.replace(screens[i], simulated_cost=ev.cost(lay.config(scn, screens[i].theta)))
    return out


def measured_current_ceiling(space: ResidualSpace, nominal: Mapping[str, np.ndarray], rel: float = 0.97
                             ) -> float | None:
    """Max |measured current| when the nominal model draws clearly more (a saturation hint)."""
    meas = [np.max(np.abs(space.meas[c])) for c in ("i_l", "i_r") if c in space.meas]
    model = [np.nanmax(np.abs(nominal[c])) for c in ("i_l", "i_r") if c in nominal]
    if not meas or not model:
        return None
    m, n = max(meas), max(model)
    return float(m) if m < rel * n else None


__all__ = ["Screen", "screen", "screen_configs", "simulate_estimates", "measured_current_ceiling"]
