"""The robot's steady turn response, identified from the steady windows of the calibration half.

The second steady stage of the real-data gap workflow (:mod:`bench.real.gap`), after the steady command response
(:mod:`bench.real.command_response`).  Once a step's wheels have settled, the robot turns at a yaw rate set by the
wheel-speed difference and by how the treads resist the turn: ``w_z = r (w_r - w_l) / (chi B)`` (Wang 2015 eq.
(25); ``chi`` the ICR spread over the track, 1 for ideal differential drive).  The steady windows measure ``chi``
without any model (:func:`chi_fit`, a regression through the origin of the gyro on the ideal yaw rate over the
turning steady commands), and the testbed's ``chi`` follows the tire-ground friction across the wheel: the gap
catalogue's ``lateral_friction`` (``terrain.mu_lat_ratio``).  Turning against that friction takes torque, and the
steady windows also show the wheel speeds the drive reached in each turn: the catalogue's ``motor_torque`` must be
strong enough to reach them.  So, on ``K_SIM`` of the calibration half's steady turning commands, each simulated
to its steady state with the model the simulation stage starts from:

1. ``chi``: if the measured ``chi`` differs from the testbed's by more than :data:`Z_ADOPT` of its standard error
   (p = 0.001, two-sided; the heteroscedasticity-robust standard error of the regression over steady commands, the
   statistical unit of :mod:`bench.real.command_response`), ``mu_lat_ratio`` is solved
   (:func:`scipy.optimize.brentq`) so that the testbed's ``chi`` is the measured one.  The testbed's ``chi`` is taken
   with the strongest drive of :data:`TORQUE_GRID` (it is a ratio of the testbed's own wheel and yaw rates, which the
   drive barely moves while it reaches them; a weak drive stalls in the turns) on at most :data:`K_SIM` of the
   commands, over which it varies by less than 0.03 on the Husky (the measured one uses them all);
2. drive: the ``torque_scale`` of :data:`TORQUE_GRID` whose simulated steady wheel speeds are nearest the measured
   ones (RMS; drives within :data:`TIE` of the best are tied, since every drive that reaches the speeds gives the
   same steady speeds, and the weakest of them is taken), adopted when its drop in squared error against the
   platform's own drive exceeds :data:`bench.real.command_response.CHI2_ADOPT` times the residual variance it
   leaves (p = 0.001, one degree of freedom).  Steady windows tell a drive only where it
   limits the steady speeds: a stronger one than taken may reach them as well; the transient fit of the simulation
   stage is offered no second ``motor_torque`` (it is not refitted there).

Both are adopted only with at least :data:`MIN_TURNS` steady turning commands.  A robot whose testbed model turns
as it does gets the nominal model back.  ``chi`` is measured with the encoders and the gyro as they read: a scale
error of either moves it (encoders reading 8 % high: mu_lat_ratio 1.98 where 1.78 is true, review of this stage),
and the fit has no intercept (a gyro bias matters when the turns all go one way; the Husky's go 50 / 47).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, Callable, Sequence

import numpy as np
from scipy.optimize import brentq

from bench.gap.catalogue import get
from bench.gap.model import apply_overrides
from bench.real.command_response import CHI2_ADOPT, per_command, steady_window_means
from bench.real.drive import DriveWindows
from bench.sim import simulate
from bench.spec import Scenario, Segment

__all__ = ["TurnResponse", "SteadyTurns", "chi_fit", "steady_turns", "identify_turn_response", "TURN_EFFECTS",
           "X_MIN", "MIN_TURNS", "Z_ADOPT", "TORQUE_GRID", "TIE", "K_SIM"]

X_MIN = 0.2        # [rad/s] a steady command turns when its ideal yaw rate r (w_r - w_l) / B is at least this
MIN_TURNS = 8      # fewer steady turning commands: nothing identified
Z_ADOPT = 3.29     # two-sided p = 0.001 on the measured chi against the testbed's
TORQUE_GRID = (1.0, 1.1, 1.25, 1.5, 1.75, 2.0, 2.5, 3.0, 3.5, 4.0)  # drive strengths, weakest first (torque_scale)
TIE = 0.002  # [rad/s] drives whose steady wheel-speed RMS is within this of the best are tied: the weakest is taken
K_SIM = 24         # steady turning commands simulated (evenly spread over the measured ideal yaw rates)
SIM_DURATION, SETTLE = 4.0, 2.5  # [s] each simulated turn, and the start of its steady part
# the catalogue's effects this stage sets: the simulation stage does not refit what it adopted
TURN_EFFECTS = {"mu_lat_ratio": "lateral_friction", "torque_scale": "motor_torque"}


@dataclass(frozen=True)
class SteadyTurns:
    """Per steady turning command (one point per step and command): commanded and measured steady wheel speeds
    [rad/s] and yaw rate [rad/s]."""

    u_l: np.ndarray
    u_r: np.ndarray
    w_l: np.ndarray
    w_r: np.ndarray
    w_z: np.ndarray


@dataclass(frozen=True)
class TurnResponse:
    """What the stage measured and adopted (module docstring); ``adopted`` maps ``mu_lat_ratio`` /
    ``torque_scale`` to their values, ``{}`` when the testbed turns as the robot does."""

    n_turns: int
    chi: float = math.nan
    chi_se: float = math.nan
    chi_nominal: float = math.nan  # the testbed's before the stage (strongest drive, as tested)
    chi_final: float = math.nan  # the testbed's with what was adopted
    wheel_rms_nominal: float = math.nan  # [rad/s] simulated - measured steady wheel speeds, before
    wheel_rms_final: float = math.nan  # and after
    wheel_tolerance: float = math.nan  # [rad/s] best RMS of the drive grid + TIE
    adopted: dict[str, float] = dataclasses.field(default_factory=dict)
    note: str = ""

    @property
    def catalogue_without(self) -> list[str]:
        """The catalogue effects the simulation stage is not offered: those whose value this stage adopted."""
        return [TURN_EFFECTS[k] for k in self.adopted]

    def overrides(self, scn: Scenario) -> dict[str, Any]:
        """Scenario overrides of what was adopted (the catalogue effects' own fields)."""
        out: dict[str, Any] = {}
        for k, v in self.adopted.items():
            out.update(get(TURN_EFFECTS[k]).spec_overrides(scn, (v,)))
        return out

    def to_json(self) -> dict[str, Any]:
        fin = (lambda x: float(x) if math.isfinite(x) else None)
        return {"n_turns": self.n_turns, "chi": fin(self.chi), "chi_se": fin(self.chi_se),
                "chi_nominal": fin(self.chi_nominal), "chi_final": fin(self.chi_final),
                "wheel_rms_nominal": fin(self.wheel_rms_nominal), "wheel_rms_final": fin(self.wheel_rms_final),
                "wheel_tolerance": fin(self.wheel_tolerance), "adopted": dict(self.adopted),
                "catalogue_without": self.catalogue_without, "note": self.note}


def chi_fit(x: np.ndarray, w_z: np.ndarray) -> tuple[float, float]:
    """``chi`` and its standard error from ideal yaw rates ``x = r (w_r - w_l) / B`` and measured ones: the
    least-squares slope ``1/chi`` of ``w_z`` on ``x`` through the origin (Wang 2015 eq. (25)); its standard error is
    heteroscedasticity-robust (HC3: the real residuals grow with the turn rate, 0.04 -> 0.14 rad/s on the Husky,
    where the equal-variance one is 0.8 x the spread over resamples), propagated (``se_chi = se_slope chi^2``).
    ``(nan, nan)`` with fewer than two points or a slope <= 0 (the yaw rate against the turn: a gyro sign?)."""
    x, w_z = np.asarray(x, float), np.asarray(w_z, float)
    sxx = float(np.sum(x * x))
    if x.size < 2 or sxx <= 0.0:
        return math.nan, math.nan
    slope = float(np.sum(x * w_z)) / sxx
    if slope <= 0.0:
        return math.nan, math.nan
    e = w_z - slope * x
    h = x * x / sxx  # leverages
    var = float(np.sum((x * e / (1.0 - h)) ** 2)) / sxx ** 2
    return 1.0 / slope, math.sqrt(var) / slope ** 2


def steady_turns(w: DriveWindows, steps: Sequence[int] | None, wheel_radius: float, track: float) -> SteadyTurns:
    """The steady turning commands of ``steps`` (:data:`X_MIN`), one point per step and command."""
    step, *means = steady_window_means(w, steps, ("cmd_wl", "cmd_wr", "enc_wl", "enc_wr", "imu_gz"))
    u_l, u_r, w_l, w_r, w_z = per_command(step, *means)
    turn = np.abs(wheel_radius * (w_r - w_l) / track) >= X_MIN
    return SteadyTurns(u_l[turn], u_r[turn], w_l[turn], w_r[turn], w_z[turn])


def _simulated(scn: Scenario, turns: SteadyTurns, overrides: dict[str, Any]) -> tuple[np.ndarray, ...]:
    """Steady wheel speeds and yaw rate of the testbed (truth, t >= SETTLE) at each command of ``turns``."""
    base = apply_overrides(scn, overrides)
    out = np.zeros((3, turns.u_l.size))
    for i, (ul, ur) in enumerate(zip(turns.u_l, turns.u_r)):
        cmd = dataclasses.replace(base.command, segments=(Segment(SIM_DURATION, float(ul), float(ur)),))
        run = simulate(dataclasses.replace(base, command=cmd, duration=SIM_DURATION), 0)
        k = run.t >= SETTLE
        out[:, i] = [np.mean(run[c][k]) for c in ("truth_wl", "truth_wr", "truth_wz")]
    return tuple(out)


def _spread(turns: SteadyTurns, r: float, track: float, k: int) -> SteadyTurns:
    """At most ``k`` of the turns, evenly spread over their sorted ideal yaw rates."""
    order = np.argsort(r * (turns.w_r - turns.w_l) / track, kind="stable")
    pick = order[np.unique(np.linspace(0, order.size - 1, min(k, order.size)).round().astype(int))]
    return SteadyTurns(*(a[pick] for a in dataclasses.astuple(turns)))


def identify_turn_response(turns: SteadyTurns, scn: Scenario,
                           simulated: Callable[..., tuple[np.ndarray, ...]] = _simulated) -> TurnResponse:
    """Measured ``chi`` and the drive strength the steady turns need, against the testbed model ``scn`` (the
    platform's wheel radius and track; module docstring).  ``simulated(scn, turns, overrides)``: the testbed's
    steady wheel speeds and yaw rate per command."""
    r, track = scn.platform.wheel_radius, scn.platform.track
    n = int(turns.u_l.size)
    if n < MIN_TURNS:
        return TurnResponse(n, note=f"{n} steady turning commands (fewer than {MIN_TURNS}): nothing identified")
    chi, se = chi_fit(r * (turns.w_r - turns.w_l) / track, turns.w_z)
    sub = _spread(turns, r, track, K_SIM)
    lat, drive = get(TURN_EFFECTS["mu_lat_ratio"]), get(TURN_EFFECTS["torque_scale"])

    cache: dict[tuple[float, float], tuple[np.ndarray, ...]] = {}

    def sims(mu: float, torque: float) -> tuple[np.ndarray, ...]:
        if (mu, torque) not in cache:
            ov = {**lat.spec_overrides(scn, (mu,)), **drive.spec_overrides(scn, (torque,))}
            cache[(mu, torque)] = simulated(scn, sub, ov)
        return cache[(mu, torque)]

    def _wheel_errors(mu: float, torque: float) -> np.ndarray:
        """Per simulated command: the squared steady wheel-speed error summed over the two sides."""
        wl, wr, _ = sims(mu, torque)
        return (wl - sub.w_l) ** 2 + (wr - sub.w_r) ** 2

    def model(mu: float, torque: float) -> tuple[float, float]:
        wl, wr, wz = sims(mu, torque)
        return chi_fit(r * (wr - wl) / track, wz)[0], float(np.sqrt(np.mean(_wheel_errors(mu, torque)) / 2.0))

    if not math.isfinite(chi):
        return TurnResponse(n, note="the yaw rate does not rise with the wheel-speed difference (slope <= 0: a gyro "
                                    "sign?): nothing identified")
    mu0 = float(scn.terrain.mu_lat_ratio)
    chi0, _ = model(mu0, TORQUE_GRID[-1])  # as every chi here: the strongest drive (the weak one stalls in turns)
    adopted: dict[str, float] = {}
    mu, note = mu0, ""
    if math.isfinite(chi0) and abs(chi - chi0) > Z_ADOPT * se:
        lo, hi = lat.params[0].lower, lat.params[0].upper
        f = lambda m: model(m, TORQUE_GRID[-1])[0] - chi  # noqa: E731
        try:
            if f(lo) * f(hi) < 0:
                mu = float(brentq(f, lo, hi, xtol=0.005))
                adopted["mu_lat_ratio"] = mu
            else:
                note = f"the measured chi {chi:.3f} is outside the testbed's range over mu_lat_ratio {lo:g}-{hi:g}"
        except ValueError:  # a NaN chi of the testbed (its slope <= 0) inside the bracket
            note = "the testbed's chi is undefined somewhere over mu_lat_ratio: not solved"
    grid = {s: model(mu, s) for s in TORQUE_GRID}
    best = min(q for _, q in grid.values())
    tol = best + TIE
    torque = next(s for s in TORQUE_GRID if grid[s][1] <= tol)
    if torque != 1.0:  # adopted when the drop in squared error is significant against the best drive's residual
        sse1, ssek = float(np.sum(_wheel_errors(mu, 1.0))), float(np.sum(_wheel_errors(mu, torque)))
        s2 = max(ssek / (2 * sub.u_l.size - 1), 1e-12)  # the measured speeds' noise and the map's misfit: the floor
        if (sse1 - ssek) / s2 > CHI2_ADOPT:
            adopted["torque_scale"] = torque
        else:
            torque = 1.0
    chi1, rms1 = grid[torque]
    return TurnResponse(n, chi, se, chi0, chi1, grid[1.0][1], rms1, tol, adopted, note)
