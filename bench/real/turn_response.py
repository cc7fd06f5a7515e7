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
   (p = 0.001, two-sided; the standard error from the regression over steady commands, the statistical unit of
   :mod:`bench.real.command_response`), ``mu_lat_ratio`` is solved (:func:`scipy.optimize.brentq`) so that the
   testbed's ``chi`` on the same commands is the measured one, with the strongest drive of :data:`TORQUE_GRID`
   (the testbed's ``chi`` is a ratio of its own wheel and yaw rates: the drive barely moves it);
2. drive: the smallest ``torque_scale`` of :data:`TORQUE_GRID` (1 first) whose simulated steady wheel speeds are
   within twice the smallest misfit any drive of the grid leaves (the steady map's own misfit, when a drive reaches
   the speeds), at least :data:`WHEEL_FLOOR`, of the measured ones.  Steady windows bound the drive's torque from
   below only (the drive reached these speeds); the transient fit of the simulation stage is offered no second
   ``motor_torque`` (it is not refitted there).

Both are adopted only with at least :data:`MIN_TURNS` steady turning commands.  A robot whose testbed model turns
as it does gets the nominal model back.
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
from bench.real.command_response import per_command, steady_window_means
from bench.real.drive import DriveWindows
from bench.sim import simulate
from bench.spec import Scenario, Segment

__all__ = ["TurnResponse", "SteadyTurns", "chi_fit", "steady_turns", "identify_turn_response", "TURN_EFFECTS",
           "X_MIN", "MIN_TURNS", "Z_ADOPT", "TORQUE_GRID", "WHEEL_FLOOR", "K_SIM"]

X_MIN = 0.2        # [rad/s] a steady command turns when its ideal yaw rate r (w_r - w_l) / B is at least this
MIN_TURNS = 8      # fewer steady turning commands: nothing identified
Z_ADOPT = 3.29     # two-sided p = 0.001 on the measured chi against the testbed's
TORQUE_GRID = (1.0, 1.5, 2.0, 2.5, 3.0, 4.0)  # drive strengths tried, weakest first (motor_torque's torque_scale)
WHEEL_FLOOR = 0.05  # [rad/s] smallest steady wheel-speed tolerance of step 2 (module docstring)
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
    chi_nominal: float = math.nan  # the testbed's, on the same commands, before the stage
    chi_final: float = math.nan  # the testbed's with what was adopted
    wheel_rms_nominal: float = math.nan  # [rad/s] simulated - measured steady wheel speeds, before
    wheel_rms_final: float = math.nan  # and after
    wheel_tolerance: float = math.nan
    adopted: dict[str, float] = dataclasses.field(default_factory=dict)
    note: str = ""

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
                "catalogue_without": [TURN_EFFECTS[k] for k in self.adopted], "note": self.note}


def chi_fit(x: np.ndarray, w_z: np.ndarray) -> tuple[float, float]:
    """``chi`` and its standard error from ideal yaw rates ``x = r (w_r - w_l) / B`` and measured ones: the
    least-squares slope ``1/chi`` of ``w_z`` on ``x`` through the origin (Wang 2015 eq. (25)), its standard error
    from the residuals, propagated (``se_chi = se_slope chi^2``)."""
    x, w_z = np.asarray(x, float), np.asarray(w_z, float)
    sxx = float(np.sum(x * x))
    if x.size < 2 or sxx <= 0.0:
        return math.nan, math.nan
    slope = float(np.sum(x * w_z)) / sxx
    if slope <= 0.0:
        return math.nan, math.nan
    s2 = float(np.sum((w_z - slope * x) ** 2)) / (x.size - 1)
    return 1.0 / slope, math.sqrt(s2 / sxx) / slope ** 2


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

    def model(mu: float, torque: float) -> tuple[float, float]:
        ov = {**lat.spec_overrides(scn, (mu,)), **drive.spec_overrides(scn, (torque,))}
        wl, wr, wz = simulated(scn, sub, ov)
        rms = float(np.sqrt(np.mean(np.r_[wl - sub.w_l, wr - sub.w_r] ** 2)))
        return chi_fit(r * (wr - wl) / track, wz)[0], rms

    mu0 = float(scn.terrain.mu_lat_ratio)
    chi0, rms0 = model(mu0, 1.0)
    chi0_strong = model(mu0, TORQUE_GRID[-1])[0]
    adopted: dict[str, float] = {}
    mu, note = mu0, ""
    if math.isfinite(chi) and math.isfinite(chi0_strong) and abs(chi - chi0_strong) > Z_ADOPT * se:
        lo, hi = lat.params[0].lower, lat.params[0].upper
        f = lambda m: model(m, TORQUE_GRID[-1])[0] - chi  # noqa: E731
        f_lo, f_hi = f(lo), f(hi)
        if f_lo * f_hi < 0:
            mu = float(brentq(f, lo, hi, xtol=0.005))
            adopted["mu_lat_ratio"] = mu
        else:
            note = f"the measured chi {chi:.3f} is outside the testbed's range over mu_lat_ratio {lo:g}-{hi:g}"
    grid = {s: model(mu, s) for s in TORQUE_GRID}
    tol = max(2.0 * min(q for _, q in grid.values()), WHEEL_FLOOR)
    torque = next(s for s in TORQUE_GRID if grid[s][1] <= tol)
    if torque != 1.0:
        adopted["torque_scale"] = torque
    chi1, rms1 = grid[torque]
    return TurnResponse(n, chi, se, chi0, chi1, rms0, rms1, tol, adopted, note)
