"""skidbench method plugins of Yu 2010: closed-loop (Fig. 3) and open-loop (Fig. 16) prediction.

``estimate(run)`` predicts from the commands (and, for the open loop, the measured torques) and
the initial state only: wheel speeds from the first encoder sample after the first time stamp
within 50 ms (0 when absent or within one count of 0: :func:`initial_wheel_speeds`), initial pose
from the first reference (else GNSS) sample (0 when absent).  The pose follows from the simulated
wheel speeds through the kinematic model eq. (1) with alpha (body frame x forward:
vx = r (w_l + w_r)/2, vy = 0, wz = r (w_r - w_l)/(alpha B)), integrated exactly on SE(2).

Geometry, motor and PID come from ``run.meta["platform"]`` when present (a user knows them);
terrain parameters (K, mu_sa, mu_op, mu_roll, alpha; slope/ramp if the user sets them) from the
plugin's :class:`YuParams` (Table II until calibrated).  The terrain metadata of a run is truth
and never read.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import numpy as np

from bench.kinematics import integrate_se2
from bench.registry import Estimate, make_estimate
from bench.run import Run, RunError, encoder_count_speed
from methods.yu2010.identification import alpha_from_yaw_rate, identify_from_speeds, rolling_from_straight
from methods.yu2010.params import YuParams
from methods.yu2010.resistance import ResistanceTable
from methods.yu2010.simulate import SimResult, simulate_closed_loop, simulate_open_loop, zoh

PAPER = "Yu et al. 2010"


@dataclass(frozen=True)
class SteadySummary:
    """Steady part of one calibration run (the last constant command, after settling)."""

    run: str
    cmd_wl: float
    cmd_wr: float
    wl: float  # mean encoder speed in the window (the command when no encoder)
    wr: float
    tau_l: float
    tau_r: float
    yaw_rate: float  # from the reference heading, NaN when absent
    t0: float
    t1: float

    @property
    def straight(self) -> bool:
        return abs(self.cmd_wl - self.cmd_wr) <= 1e-9 * max(abs(self.cmd_wl), abs(self.cmd_wr), 1e-12)


def _window_mean(run: Run, name: str, t0: float, t1: float) -> float:
    if name not in run.data.columns:
        return float("nan")
    t, v = run.samples(name)
    m = (t >= t0) & (t <= t1)
    return float(v[m].mean()) if m.any() else float("nan")


def steady_summary(run: Run, settle: float = 1.0, settle_fraction: float = 0.3) -> SteadySummary:
    """The steady part of ``run``: the last segment of constant (cmd_wl, cmd_wr), without its first
    max(``settle`` s, ``settle_fraction`` of the segment).  Raises :class:`RunError` naming the run
    and channel when there is no such part or no torque sample in it."""
    run.require(("cmd_wl", "cmd_wr", "tau_l", "tau_r"), "yu2010 calibration")
    t = run.t
    cl, cr = run["cmd_wl"], run["cmd_wr"]
    ok = np.isfinite(cl) & np.isfinite(cr)
    tc, cl, cr = t[ok], cl[ok], cr[ok]
    scale = max(float(np.max(np.abs(cl))), float(np.max(np.abs(cr))), 1e-12)
    change = np.flatnonzero((np.abs(np.diff(cl)) > 1e-9 * scale) | (np.abs(np.diff(cr)) > 1e-9 * scale))
    start = tc[change[-1] + 1] if change.size else tc[0]
    end = t[-1]
    t0 = start + max(settle, settle_fraction * (end - start))
    if t0 >= end:
        raise RunError(run.where, "cmd_wl", f"last constant command {start:.3f}-{end:.3f} s",
                       f"no steady part left after settling {max(settle, settle_fraction * (end - start)):.2f} s")
    tl, tr = _window_mean(run, "tau_l", t0, end), _window_mean(run, "tau_r", t0, end)
    for name, val in (("tau_l", tl), ("tau_r", tr)):
        if not np.isfinite(val):
            raise RunError(run.where, name, f"window {t0:.3f}-{end:.3f} s",
                           "no finite torque sample in the steady part")
    wl, wr = _window_mean(run, "enc_wl", t0, end), _window_mean(run, "enc_wr", t0, end)
    if not (np.isfinite(wl) and np.isfinite(wr)):
        wl, wr = float(cl[-1]), float(cr[-1])
    yaw_rate = float("nan")
    if "ref_yaw" in run.data.columns:
        ty, yv = run.samples("ref_yaw")
        m = (ty >= t0) & (ty <= end)
        if m.sum() >= 3:
            yaw_rate = float(np.polyfit(ty[m] - ty[m][0], np.unwrap(yv[m]), 1)[0])
    return SteadySummary(run.id, float(cl[-1]), float(cr[-1]), wl, wr, tl, tr, yaw_rate, float(t0), float(end))


def initial_wheel_speeds(run: Run, window: float = 0.05) -> tuple[float, float]:
    """Wheel speeds [rad/s] at the run's first time stamp: the first encoder sample strictly after it within
    ``window`` s (an encoder speed is a count difference: a sample at the very first time stamp has no earlier count
    and reads 0 even when the vehicle already moves; Yu's ramps start at speed); (0, 0) when either side has none.
    A reading within one count per sample of zero (``meta.platform.sensors.encoder``: 2 pi / counts_per_rev x
    rate_hz) is taken as rest: a wheel that starts from rest under a ramp already reads one count in its first
    sample (0.077 rad/s on the P3-AT, 10 ms in), and starting the model's wheels at that speed with the vehicle
    at rest made its start-up torque chatter (closed-loop torque RMS 0.37 N m against 0.11 from rest on the
    0.2 m/s straight)."""
    t0 = float(run.t[0])
    wl = _first_sample(run, "enc_wl", t0 + window, after=t0)
    wr = _first_sample(run, "enc_wr", t0 + window, after=t0)
    if wl is None or wr is None:
        return 0.0, 0.0
    one_count = encoder_count_speed(run)
    if one_count is not None:
        wl, wr = (0.0 if abs(w) <= one_count * (1.0 + 1e-9) else w for w in (wl, wr))
    return float(wl), float(wr)


def _first_sample(run: Run, name: str, t_max: float, after: float | None = None) -> float | None:
    """First finite sample of ``name`` up to ``t_max``; with ``after``, the first one strictly
    later than ``after`` if there is one (else the first)."""
    if name not in run.data.columns:
        return None
    t, v = run.samples(name)
    if after is not None:
        later = np.flatnonzero((t > after) & (t <= t_max))
        if later.size:
            return float(v[later[0]])
    if t.size == 0 or t[0] > t_max:
        return None
    return float(v[0])


@dataclass(eq=False)
class Yu2010:
    """Yu 2010 closed-loop dynamic model (Fig. 3): commands -> PID -> motor -> dynamics (25) ->
    wheel speeds, torques, body velocities and pose."""

    params: YuParams = field(default_factory=YuParams)
    use_run_platform: bool = True
    dt: float = 1e-3
    settle: float = 1.0
    calibration: Mapping[str, Any] = field(default_factory=dict)
    _tables: dict = field(default_factory=dict, repr=False, compare=False)

    name = "yu2010.closed_loop"
    paper = PAPER
    requires = frozenset({"cmd_wl", "cmd_wr"})
    calibration_requires = frozenset({"tau_l", "tau_r"})

    # ------------------------------------------------------------------ helpers
    def params_for(self, run: Run) -> YuParams:
        """The parameters used on ``run``: platform fields from its metadata when present."""
        plat = run.meta.get("platform") if self.use_run_platform else None
        return self.params.with_platform(plat) if plat else self.params

    def table(self, params: YuParams) -> ResistanceTable:
        key = dataclasses.replace(params, Kp=0.0, Ki=0.0, Kd=0.0)  # the table ignores the PID
        if key not in self._tables:
            self._tables.clear()
            self._tables[key] = ResistanceTable.build(params)
        return self._tables[key]

    def _initial_state(self, run: Run) -> tuple[tuple[float, float], tuple[float, float, float]]:
        t0 = float(run.t[0])
        w0 = initial_wheel_speeds(run)
        for px, py, pyaw in (("ref_x", "ref_y", "ref_yaw"), ("gnss_x", "gnss_y", "gnss_yaw")):
            x, y, yaw = (_first_sample(run, c, t0 + 1.0) for c in (px, py, pyaw))
            if x is not None and y is not None:
                return w0, (x, y, yaw or 0.0)
        return w0, (0.0, 0.0, 0.0)

    def _simulate(self, run: Run, params: YuParams, w0: tuple[float, float]) -> SimResult:
        t = run.t
        tl_, cl = run.samples("cmd_wl")
        tr_, cr = run.samples("cmd_wr")
        if tl_.size == 0 or tr_.size == 0:
            raise RunError(run.where, "cmd_wl" if tl_.size == 0 else "cmd_wr", "all NaN", "no command sample")
        tt = np.union1d(np.union1d(tl_, tr_), t[:1])  # start at the run's first time stamp
        return simulate_closed_loop(tt, zoh(tl_, cl, tt), zoh(tr_, cr, tt), params, dt=self.dt,
                                    t_end=float(t[-1]), w0=w0, table=self.table(params))

    # ------------------------------------------------------------------ protocol
    def estimate(self, run: Run) -> Estimate:
        run.require(self.requires, self.name)
        if run.t.size < 2:
            raise RunError(run.where, "t", run.t.size, "a prediction needs at least two time stamps")
        params = self.params_for(run)
        w0, pose0 = self._initial_state(run)
        sim = self._simulate(run, params, w0)
        vx = params.r * (sim.wl + sim.wr) / 2.0  # eq. (1)
        wz = params.r * (sim.wr - sim.wl) / (params.alpha * params.B)
        x, y, yaw = integrate_se2(sim.t, vx, np.zeros_like(vx), wz, *pose0)
        t = run.t

        def at(a: np.ndarray) -> np.ndarray:
            return np.interp(t, sim.t, a)

        info = {"params": dataclasses.asdict(params), "initial_wheel_speeds": w0, "initial_pose": pose0,
                "dt": self.dt, "calibration": dict(self.calibration)}
        return make_estimate(self.name, info, t=t, x=at(x), y=at(y), yaw=at(yaw), vx=at(vx), vy=np.zeros_like(t),
                             wz=at(wz), wl=at(sim.wl), wr=at(sim.wr), tau_l=at(sim.tau_l), tau_r=at(sim.tau_r),
                             chi=np.full_like(t, params.alpha))

    def calibrate(self, runs: Sequence[Run]) -> "Yu2010":
        """Identify mu_roll (straight runs), alpha (turning runs with a reference heading) and
        (K, mu_sa, mu_op) by eq. (28) (turning runs), each from the steady part of the runs
        (:func:`steady_summary`).  Parameters without suitable runs keep their current values."""
        if not runs:
            raise ValueError(f"{self.name}: calibrate needs at least one run")
        params = self.params_for(runs[0])
        rows = [steady_summary(r, self.settle) for r in runs]
        straight = [s for s in rows if s.straight and (s.cmd_wl != 0.0)]
        turning = [s for s in rows if not s.straight]
        info: dict[str, Any] = {"runs": [s.run for s in rows]}
        if straight:
            mu_roll = float(np.mean([rolling_from_straight(s.tau_l, s.tau_r, params) for s in straight]))
            params = params.replace(mu_roll=mu_roll)
            info["mu_roll"] = mu_roll
        with_yaw = [s for s in turning if np.isfinite(s.yaw_rate)]
        if with_yaw:
            alpha = alpha_from_yaw_rate([s.wl for s in with_yaw], [s.wr for s in with_yaw],
                                        [s.yaw_rate for s in with_yaw], params)
            params = params.replace(alpha=alpha)
            info["alpha"] = alpha
        if turning:
            res = identify_from_speeds([s.cmd_wl for s in turning], [s.cmd_wr for s in turning],
                                       [s.tau_l for s in turning], [s.tau_r for s in turning], params)
            params = res.apply(params)
            info.update(K=res.K, mu_sa=res.mu_sa, mu_op=res.mu_op, rms_torque=res.rms, success=res.success)
        return dataclasses.replace(self, params=params, calibration=info, _tables={})


@dataclass(eq=False)
class Yu2010OpenLoop(Yu2010):
    """Yu 2010 open-loop model (Fig. 3 without the PID; Fig. 16): the measured side torques
    (tau = K_tau V) drive the dynamics (25), clipped to the motor limits."""

    name = "yu2010.open_loop"
    requires = frozenset({"cmd_wl", "cmd_wr", "tau_l", "tau_r"})

    def _simulate(self, run: Run, params: YuParams, w0: tuple[float, float]) -> SimResult:
        tl_, vl = run.samples("tau_l")
        tr_, vr = run.samples("tau_r")
        if tl_.size == 0 or tr_.size == 0:
            raise RunError(run.where, "tau_l" if tl_.size == 0 else "tau_r", "all NaN", "no torque sample")
        tt = np.union1d(tl_, tr_)
        vl_, vr_ = np.interp(tt, tl_, vl), np.interp(tt, tr_, vr)
        t = run.t
        t0 = float(t[0])
        if tt[0] > t0:  # hold the first torque sample back to the start
            tt, vl_, vr_ = np.concatenate(([t0], tt)), np.concatenate(([vl_[0]], vl_)), np.concatenate(([vr_[0]], vr_))
        return simulate_open_loop(tt, vl_, vr_, params, dt=self.dt, t_end=float(t[-1]), w0=w0,
                                  table=self.table(params))
