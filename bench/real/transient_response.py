"""The robot's transient response to a command step, identified from the transitory windows of the calibration half.

The third stage of the real-data gap workflow (:mod:`bench.real.gap`), after the steady command response
(:mod:`bench.real.command_response`) and the steady turn response (:mod:`bench.real.turn_response`).  Those fix where
the wheels settle; this one fixes how they get there.  In the first seconds of each command step (DRIVE's
``transitory_state_mask``: the first 2 s of each 6 s step) the wheels leave their previous speeds late and at a
bounded rate, as a velocity controller with a dead time and acceleration limits on the mean speed and the turn
(ROS ``diff_drive_controller``'s ``SpeedLimiter``) drives them.  The stage fits that chain, in the testbed's own
order (:func:`bench.sim.testbed._references`), in closed form and without simulation (:func:`predict`):

    the mapped command (the steady map: ``m1``, ``h1``, its half-sum and half-difference) reached from the step's
    initial wheel speeds (``m0``, ``h0``) after a dead time ``d``, at most at ``a_m`` and ``a_h`` [rad/s^2]:
        m(t) = m0 + clip(m1 - m0, -a_m tau, a_m tau),  h likewise,  tau = max(t - t_c - d, 0)
    both sides scaled to the wheel-speed limit; the encoders read the wheels ``L`` late (their latency and
    counting period); the gyro reads ``g0 + r ((w_r - w_l) - (w0_r - w0_l)) / (chi B)`` (Wang 2015 eq. (25),
    ``chi`` from the turn stage)

with ``t_c`` the time the logged command changes.  DRIVE (Baril et al. 2024) models a per-side first-order lag
instead; on the Husky's calibration half that fits the encoders at twice the RMS of the rate limits (1.12 against
0.56 rad/s, 85 transitions, encoders only, a dead time fitted with either: an exploration before this stage was
written, not code of the repository), because the two sides do not respond on their own: a wheel whose speed barely
changes dips while the mean moves faster than the turn.  The initial state is read the same way on the robot and on
the testbed (:func:`_start`).  The gyro carries the
drive's dead time free of the encoders' latency, which is how ``d`` and ``L`` separate.

Each parameter is the catalogue's own (:data:`TRANSIENT_EFFECTS`: ``actuator_delay``, ``encoder_latency``,
``command_accel``).  The testbed has a transient response of its own (its wheel PIDs, its motors, its chassis: a
chassis that must break its tires' lateral grip before it yaws reads as a dead time on the gyro), which the same fit
reads as a chain too; so the values are solved so that the testbed, simulated on :data:`K_SIM` of the same
transitions (each step's replay) and fitted the same way, shows the robot's chain (:data:`ITERATIONS` fixed-point
steps ``p <- p + (p_robot - p_testbed(p))``, within the catalogue's bounds), and each is kept only if the robot's
transients tell the testbed with it from the testbed without it (backward elimination): the robot's weighted residual
sum of squares under the testbed's chain without the parameter (the others solved again without it) against with
it.  The transition is the unit, since
its samples share its error: the rises per transition are tested by their mean over its standard error
(:func:`rise`) against :data:`Z_ADOPT` (one-sided p = 0.001).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, Callable, Sequence

import numpy as np
from scipy.optimize import least_squares

from bench.gap.catalogue import get
from bench.gap.model import apply_overrides, replay_scenario
from bench.gap.residuals import encoder_samples
from bench.run import Run
from bench.sim import simulate
from bench.sim.startup import initial_wheel_speeds
from bench.spec import Scenario

__all__ = ["Transition", "TransientResponse", "transitions", "predict", "fit_transient", "rise",
           "identify_transient_response", "TRANSIENT", "MIN_TRANSITIONS", "K_SIM", "ITERATIONS", "TOLERANCE",
           "Z_ADOPT", "TRANSIENT_EFFECTS", "NEUTRAL"]

TRANSIENT = 2.0      # [s] the transitory window of a step (DRIVE)
MIN_TRANSITIONS = 8  # fewer: nothing identified
K_SIM = 24           # transitions simulated per fixed-point step (evenly spread over the calibration steps)
ITERATIONS = 4       # fixed-point steps of the testbed correction, at most
TOLERANCE = {"delay": 0.01, "latency": 0.01, "accel_mean": 0.05, "accel_diff": 0.05}  # [s] / relative: converged
Z_ADOPT = 3.09       # one-sided p = 0.001 on the rise over transitions (:func:`rise`)
# parameter -> (catalogue effect, index of its parameter there); neutral values in NEUTRAL
TRANSIENT_EFFECTS = {"delay": ("actuator_delay", 0), "latency": ("encoder_latency", 0),
                     "accel_mean": ("command_accel", 0), "accel_diff": ("command_accel", 1)}
NEUTRAL = {"delay": 0.0, "latency": 0.0, "accel_mean": math.inf, "accel_diff": math.inf}
_START = {"delay": 0.2, "latency": 0.1, "accel_mean": 5.0, "accel_diff": 3.0}  # where each fit starts


def _overrides(values: dict[str, float], scn: Scenario) -> dict[str, Any]:
    """Scenario overrides of parameter ``values`` (the catalogue effects' own fields; a partly set effect keeps its
    other parameter at the scenario's value)."""
    out: dict[str, Any] = {}
    for name in sorted({TRANSIENT_EFFECTS[k][0] for k in values}):
        keys = sorted((i, k) for k, (n, i) in TRANSIENT_EFFECTS.items() if n == name)
        out.update(get(name).spec_overrides(scn, tuple(values.get(k, _current(scn, k)) for _, k in keys)))
    return out


def _tolerance(key: str, value: float) -> float:
    """When the testbed's chain is the robot's (:data:`TOLERANCE`: absolute for times, relative for the limits)."""
    return TOLERANCE[key] * (abs(value) if key.startswith("accel") else 1.0)


def _current(scn: Scenario, key: str) -> float:
    """The scenario's own value of a parameter (:data:`TRANSIENT_EFFECTS`)."""
    plat = scn.platform
    return {"delay": plat.actuator_delay, "latency": plat.sensors.encoder.latency,
            "accel_mean": plat.command_accel_mean, "accel_diff": plat.command_accel_diff}[key]



@dataclass(frozen=True)
class Transition:
    """One step's transitory window: sample times from the command change ``t_c`` [s], the encoders' own samples and
    the gyro's, the initial wheel speeds ``w0`` and yaw rate ``g0`` (the replay's measured initial state) and the
    mapped command's half-sum and half-difference ``m1``, ``h1`` [rad/s]."""

    t_enc: np.ndarray
    enc_l: np.ndarray
    enc_r: np.ndarray
    t_gz: np.ndarray
    gz: np.ndarray
    w0: tuple[float, float]
    g0: float
    m1: float
    h1: float
    t_c: float
    run: Run | None = None  # the step (the replay's source), kept for the testbed correction

    def with_samples(self, sim: Run, scn: Scenario) -> "Transition":
        """The same transition read from another Run of the same step (the testbed's), its initial state estimated
        from that Run's own samples as the robot's was from the robot's (:func:`_start`: the same estimator on both
        sides, so that its bias, e.g. samples taken after the command change, is the same)."""
        w0, g0 = _start(sim, scn)
        return dataclasses.replace(self, **_samples(sim, self.t_c), w0=w0, g0=g0)


def _start(run: Run, scn: Scenario) -> tuple[tuple[float, float], float]:
    """Initial wheel speeds and yaw rate of a step Run as its replay estimates them (:func:`bench.gap.model.
    replay_scenario`: the first encoder and gyro samples)."""
    rscn, init = replay_scenario(run, scn)
    w0 = initial_wheel_speeds(rscn)
    return (float(w0[0]), float(w0[1])), float(init.yaw_rate)


def _samples(run: Run, t_c: float) -> dict[str, np.ndarray]:
    """The encoders' own samples (the logger's repeats left out) and the gyro's in the first :data:`TRANSIENT` s of
    ``run``, their times from the command change ``t_c``."""
    te, el = encoder_samples(run, "enc_wl")
    _, er = encoder_samples(run, "enc_wr")
    k = te <= TRANSIENT
    tg = run.t[np.isfinite(run["imu_gz"])] if run.has("imu_gz") else np.zeros(0)
    gz = run["imu_gz"][np.isfinite(run["imu_gz"])] if run.has("imu_gz") else np.zeros(0)
    j = tg <= TRANSIENT
    return {"t_enc": te[k] - t_c, "enc_l": el[k], "enc_r": er[k], "t_gz": tg[j] - t_c, "gz": gz[j]}


def transitions(runs: Sequence[Run], scn: Scenario) -> list[Transition]:
    """The transitory window of each step Run (one step each, from its measured initial state), the command mapped by
    ``scn``'s platform (its steady map)."""
    plat, out = scn.platform, []
    for run in runs:
        k = run.t <= TRANSIENT
        cl, cr = run["cmd_wl"][k], run["cmd_wr"][k]
        if cl.size < 3 or not (np.isfinite(cl[-1]) and np.isfinite(cr[-1])):
            continue
        changed = np.flatnonzero((cl != cl[-1]) | (cr != cr[-1]))
        t_c = float(run.t[changed[-1] + 1]) if changed.size else 0.0
        samples = _samples(run, t_c)
        if not (samples["t_enc"].size or samples["t_gz"].size):
            continue
        w0, g0 = _start(run, scn)
        m1 = float(np.clip(plat.command_gain_sum * 0.5 * (cl[-1] + cr[-1]), -plat.command_limit_mean,
                           plat.command_limit_mean))
        h1 = float(np.clip(plat.command_gain_diff * 0.5 * (cr[-1] - cl[-1]), -plat.command_limit_diff,
                           plat.command_limit_diff))
        out.append(Transition(**samples, w0=w0, g0=g0, m1=m1, h1=h1, t_c=t_c, run=run))
    return out


def _wheels(tr: Transition, p: dict[str, float], t: np.ndarray, wheel_limit: float) -> tuple[np.ndarray, np.ndarray]:
    """Both sides' wheel speeds at times ``t`` (from the command change) under the chain ``p`` (module docstring)."""
    tau = np.maximum(t - p["delay"], 0.0)
    m0, h0 = 0.5 * (tr.w0[0] + tr.w0[1]), 0.5 * (tr.w0[1] - tr.w0[0])
    on = tau > 0.0
    step_m = np.where(on, p["accel_mean"] * np.where(on, tau, 1.0), 0.0)  # no limit (inf): the step itself
    step_h = np.where(on, p["accel_diff"] * np.where(on, tau, 1.0), 0.0)
    m = m0 + np.clip(tr.m1 - m0, -step_m, step_m)
    h = h0 + np.clip(tr.h1 - h0, -step_h, step_h)
    wl, wr = m - h, m + h
    big = np.maximum(np.abs(wl), np.abs(wr))
    s = np.where(big > wheel_limit, wheel_limit / np.maximum(big, 1e-300), 1.0)
    return wl * s, wr * s


def predict(tr: Transition, p: dict[str, float], chi: float, wheel_radius: float, track: float,
            wheel_limit: float = math.inf) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The chain of the module docstring at the transition's samples: encoder left, right, gyro."""
    el, er = _wheels(tr, p, tr.t_enc - p["latency"], wheel_limit)
    gl, gr = _wheels(tr, p, tr.t_gz, wheel_limit)
    gz = tr.g0 + wheel_radius * ((gr - gl) - (tr.w0[1] - tr.w0[0])) / (chi * track)
    return el, er, gz


def fit_transient(trs: Sequence[Transition], free: Sequence[str], chi: float, wheel_radius: float, track: float,
                  wheel_limit: float = math.inf, sigma: tuple[float, float] | None = None,
                  fixed: dict[str, float] | None = None) -> tuple[dict[str, float], np.ndarray, tuple[float, float]]:
    """Least-squares fit of the ``free`` parameters (others at ``fixed``, else neutral) over ``trs``: the parameters, each transition's
    weighted residual sum of squares, and the (encoder, gyro) residual scales used as weights (``sigma``, else each
    channel's RMS under a fit of each channel alone)."""
    free = list(free)
    lo, hi = [TRANSIENT_LOWER[k] for k in free], [TRANSIENT_UPPER[k] for k in free]
    sizes = np.array([2 * tr.t_enc.size + tr.t_gz.size for tr in trs])

    def params(x) -> dict[str, float]:
        return {**NEUTRAL, **(fixed or {}), **dict(zip(free, x))}

    def resid(x, w_enc: float, w_gz: float) -> np.ndarray:
        p, out = params(x), []
        for tr in trs:
            el, er, gz = predict(tr, p, chi, wheel_radius, track, wheel_limit)
            out += [w_enc * (el - tr.enc_l), w_enc * (er - tr.enc_r), w_gz * (gz - tr.gz)]
        return np.concatenate(out) if out else np.zeros(0)

    def per_transition(r: np.ndarray) -> np.ndarray:
        return np.bincount(np.repeat(np.arange(len(trs)), sizes), weights=r * r, minlength=len(trs))

    x0 = [_START[k] for k in free]
    if sigma is None:
        n_e, n_g = sum(2 * tr.t_enc.size for tr in trs), sum(tr.t_gz.size for tr in trs)
        if free:
            e = least_squares(resid, x0, args=(1.0, 0.0), bounds=(lo, hi))
            g = least_squares(resid, x0, args=(0.0, 1.0), bounds=(lo, hi))
            s_e, s_g = math.sqrt(2 * e.cost / max(n_e, 1)), math.sqrt(2 * g.cost / max(n_g, 1))
        else:
            s_e = s_g = math.sqrt(float(np.mean(resid(np.zeros(0), 1.0, 1.0) ** 2)))
        sigma = (max(s_e, 1e-9), max(s_g, 1e-9))
    if not free:
        return params(()), per_transition(resid(np.zeros(0), 1.0 / sigma[0], 1.0 / sigma[1])), sigma
    f = least_squares(resid, x0, args=(1.0 / sigma[0], 1.0 / sigma[1]), bounds=(lo, hi))
    return params(f.x), per_transition(f.fun), sigma


def _bounds() -> tuple[dict[str, float], dict[str, float]]:
    lower, upper = {}, {}
    for k, (name, i) in TRANSIENT_EFFECTS.items():
        par = get(name).params[i]
        lower[k], upper[k] = float(par.lower), float(par.upper)
    return lower, upper


TRANSIENT_LOWER, TRANSIENT_UPPER = _bounds()


@dataclass(frozen=True)
class TransientResponse:
    """What the stage measured and adopted (module docstring): the robot's chain (``measured``, all four
    parameters fitted), ``adopted`` the parameters kept by the elimination with the values the testbed needs to show
    them, ``{}`` when nothing was identified."""

    n_transitions: int
    measured: dict[str, float] = dataclasses.field(default_factory=dict)
    statistic: dict[str, float] = dataclasses.field(default_factory=dict)  # rise() when left neutral
    testbed_before: dict[str, float] = dataclasses.field(default_factory=dict)  # the testbed's own chain, nominal
    testbed_after: dict[str, float] = dataclasses.field(default_factory=dict)  # and with what was adopted
    adopted: dict[str, float] = dataclasses.field(default_factory=dict)
    sigma: tuple[float, float] = (math.nan, math.nan)  # [rad/s] encoder and gyro residual scales
    note: str = ""

    @property
    def catalogue_without(self) -> list[str]:
        """The catalogue effects the simulation stage is not offered: with enough transitions to identify anything,
        all of this stage's (its elimination judged each on every calibration transition, where the fit block
        has a few; an effect found not significant stays off, as the steady map's stages do); else none."""
        return sorted({n for n, _ in TRANSIENT_EFFECTS.values()}) if self.measured else []

    def overrides(self, scn: Scenario) -> dict[str, Any]:
        """Scenario overrides of what was adopted (:func:`_overrides`)."""
        return _overrides(self.adopted, scn)

    def to_json(self) -> dict[str, Any]:
        fin = (lambda d: {k: (float(v) if math.isfinite(v) else None) for k, v in d.items()})
        return {"n_transitions": self.n_transitions, "measured": fin(self.measured), "statistic": fin(self.statistic),
                "testbed_before": fin(self.testbed_before), "testbed_after": fin(self.testbed_after),
                "adopted": fin(self.adopted), "sigma": list(self.sigma), "catalogue_without": self.catalogue_without,
                "note": self.note}


def rise(reduced: np.ndarray, full: np.ndarray) -> float:
    """How significantly a model without a parameter fits worse: the per-transition rises of the weighted residual sum
    of squares ``reduced - full``, their mean over its standard error (a one-sample t statistic over transitions, the
    unit: the samples of a transition share its error, so they are not counted singly)."""
    d = np.asarray(reduced, float) - np.asarray(full, float)
    if d.size < 2:
        return 0.0
    sd = float(np.std(d, ddof=1))
    return float(np.mean(d)) / (sd / math.sqrt(d.size)) if sd > 0 else (math.inf if np.mean(d) > 0 else 0.0)


def _spread(trs: Sequence[Transition], k: int) -> list[Transition]:
    pick = np.unique(np.linspace(0, len(trs) - 1, min(k, len(trs))).round().astype(int))
    return [trs[i] for i in pick]


def _simulated(scn: Scenario, tr: Transition, overrides: dict[str, Any]) -> Run:
    """The testbed's run of the transition's step (its replay: command and initial state), its first
    :data:`TRANSIENT` s, with ``overrides``."""
    rscn, _ = replay_scenario(tr.run, scn)
    rscn = apply_overrides(rscn, overrides)
    return simulate(dataclasses.replace(rscn, duration=min(rscn.duration, TRANSIENT + 0.1)), 0)


def identify_transient_response(runs: Sequence[Run], scn: Scenario, chi: float, chi_testbed: float,
                                simulated: Callable[[Scenario, Transition, dict[str, Any]], Run] = _simulated
                                ) -> TransientResponse:
    """The transient response of the step Runs ``runs`` (calibration steps, one each) against the model ``scn`` the
    simulation stage starts from (its steady map and wheel-speed limit; module docstring).  ``chi``: the robot's
    (turn stage), ``chi_testbed``: the testbed's under ``scn``.  ``simulated(scn, transition, overrides)``: the
    testbed's Run of a transition's step."""
    plat = scn.platform
    r, track, limit = plat.wheel_radius, plat.track, plat.wheel_speed_limit
    trs = transitions(runs, scn)
    n = len(trs)
    if n < MIN_TRANSITIONS or not math.isfinite(chi):
        return TransientResponse(n, note=f"{n} transitions (fewer than {MIN_TRANSITIONS}) or no chi: nothing "
                                         "identified")
    everything = list(TRANSIENT_EFFECTS)
    measured, _, sigma = fit_transient(trs, everything, chi, r, track, limit)
    sub = _spread(trs, K_SIM)

    def testbed(values: dict[str, float]) -> dict[str, float]:
        """The testbed's chain on ``sub`` with ``values`` adopted, fitted as the robot's is."""
        ov = _overrides(values, scn)
        sims = [tr.with_samples(simulated(scn, tr, ov), scn) for tr in sub]
        return fit_transient(sims, everything, chi_testbed, r, track, limit, sigma)[0]

    def solve(values: dict[str, float]) -> tuple[dict[str, float], dict[str, float]]:
        """``p <- p + (p_robot - p_testbed(p))`` on the keys of ``values`` until the testbed shows the robot's chain
        within :data:`TOLERANCE` or held at a bound (at most :data:`ITERATIONS` steps); the values and the testbed's
        chain."""
        sig = testbed(values)
        for _ in range(ITERATIONS):
            new = {k: float(np.clip(v + measured[k] - sig[k], TRANSIENT_LOWER[k], TRANSIENT_UPPER[k]))
                   for k, v in values.items()}
            # converged: each key within its tolerance, or held at a bound that the step would cross
            if all(abs(measured[k] - sig[k]) <= _tolerance(k, measured[k]) or new[k] == values[k] for k in values):
                break
            values = new
            sig = testbed(values)
        return values, sig

    def robot_wss(sig: dict[str, float]) -> np.ndarray:
        """The robot's per-transition weighted sum of squares under a chain (no fit)."""
        return fit_transient(trs, [], chi, r, track, limit, sigma, sig)[1]

    before = testbed({})
    values, after = solve({k: measured[k] for k in everything})
    stat: dict[str, float] = {}
    while values:  # backward elimination against the testbed with the rest adopted (module docstring)
        base = robot_wss(after)
        without = {}  # each parameter back at the scenario's value, the others solved again without it
        for k in values:
            rest = {j: v for j, v in values.items() if j != k}
            without[k] = solve(rest) if rest else ({}, before)
        z = {k: rise(robot_wss(sig), base) for k, (_, sig) in without.items()}
        stat.update(z)
        drop = min(z, key=z.get)
        if z[drop] > Z_ADOPT:
            break
        values, after = without[drop]
    note = "" if values else "the robot's transients are the testbed's"
    return TransientResponse(n, measured, stat, before, after, values, sigma, note)
