"""Command profiles -> wheel-speed references (rad/s), vectorised over time.

Every scenario's command is a :class:`bench.spec.CommandSpec`; :func:`wheel_reference` turns it
into the per-side wheel-speed references ``(w_l, w_r)`` at arbitrary times.  Units of the papers
(rpm for Yi 2009, tread m/s for Wang 2015, (v, radius) for Yu 2010) are converted here.
"""
from __future__ import annotations

import math

import numpy as np

from bench.kinematics import inverse_v_radius
from bench.spec import CommandSpec, Platform, SpecError

RPM_TO_RAD_S = 2.0 * math.pi / 60.0


def _piecewise(t: np.ndarray, cmd: CommandSpec, fill_b: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Values (a, b) of the segment active at each t (segment i holds through t_end[i]); after
    the last segment (0, fill_b)."""
    if not cmd.segments:
        raise SpecError("<command>", "command.segments", (), "at least one segment is required")
    t_end = np.array([s.t_end for s in cmd.segments])
    if np.any(np.diff(t_end) <= 0):
        raise SpecError("<command>", "command.segments", t_end.tolist(), "t_end must increase")
    a = np.array([s.a for s in cmd.segments])
    b = np.array([s.b for s in cmd.segments])
    idx = np.searchsorted(t_end, t, side="left")
    inside = idx < len(t_end)
    idx = np.minimum(idx, len(t_end) - 1)
    return np.where(inside, a[idx], 0.0), np.where(inside, b[idx], fill_b)


def lemniscate_v_radius(t: np.ndarray, t0: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Desired speed and signed turning radius along Yu 2010 eqs. (29)-(30):
    X = 9 cos(s)/(1 + sin^2 s), Y = 27 sin(s) cos(s)/(1 + sin^2 s), s = (t + t0)/50."""
    s = (np.asarray(t, float) + t0) / 50.0
    ds = 1.0 / 50.0
    sn, cs = np.sin(s), np.cos(s)
    den = 1.0 + sn**2
    # analytic derivatives of X(s), Y(s) w.r.t. s
    dX = (-9 * sn * den - 9 * cs * 2 * sn * cs) / den**2
    num_y = 27 * sn * cs
    dnum_y = 27 * (cs**2 - sn**2)
    dY = (dnum_y * den - num_y * 2 * sn * cs) / den**2
    # second derivatives numerically (smooth closed curve; central difference in s)
    h = 1e-5

    def first(sv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        a, c = np.sin(sv), np.cos(sv)
        d = 1.0 + a**2
        return (-9 * a * d - 9 * c * 2 * a * c) / d**2, (27 * (c**2 - a**2) * d - 27 * a * c * 2 * a * c) / d**2

    xp, yp = first(s + h)
    xm, ym = first(s - h)
    ddX, ddY = (xp - xm) / (2 * h), (yp - ym) / (2 * h)
    speed_s = np.hypot(dX, dY)
    v = speed_s * ds
    curvature = (dX * ddY - dY * ddX) / np.maximum(speed_s**3, 1e-12)  # signed, per metre
    with np.errstate(divide="ignore"):
        radius = np.where(np.abs(curvature) < 1e-9, np.inf, 1.0 / curvature)
    return v, radius


def _random_profile(t: np.ndarray, cmd: CommandSpec, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Joystick-like path: every ``cmd.step`` s a new (v, yaw-rate) pair, uniform in the box."""
    n = int(math.ceil((float(t.max()) if t.size else 0.0) / cmd.step)) + 1
    rng = np.random.default_rng(np.random.SeedSequence([seed, 0xC0FFEE]))
    v = rng.uniform(0.2 * cmd.v_max, cmd.v_max, n) * rng.choice([1.0, 1.0, 1.0, -1.0], n)
    w = rng.uniform(-cmd.w_max, cmd.w_max, n)
    k = np.minimum((t / cmd.step).astype(int), n - 1)
    return v[k], w[k]


SEEDED_COMMANDS = frozenset({"random"})  # command kinds whose wheel references depend on the seed (_random_profile)


def wheel_reference(t: np.ndarray, cmd: CommandSpec, platform: Platform, seed: int = 0
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Per-side wheel-speed references (rad/s) at times ``t`` (before any acceleration limit)."""
    t = np.asarray(t, float)
    r, B = platform.wheel_radius, platform.track
    if cmd.kind == "wheel_speeds":
        a, b = _piecewise(t, cmd)
        if cmd.units == "rpm":
            return a * RPM_TO_RAD_S, b * RPM_TO_RAD_S
        if cmd.units == "m/s":
            return a / r, b / r
        return a, b
    if cmd.kind == "v_radius":
        v, radius = _piecewise(t, cmd, fill_b=np.inf)
        vl, vr = inverse_v_radius(v, radius, B)
        return vl / r, vr / r
    if cmd.kind == "v_curvature_ratio":
        # v is the outer (faster) tread speed, so that curvature ratio 0 (pure rotation) is defined
        v, lam = _piecewise(t, cmd, fill_b=np.inf)
        # (v_l + v_r)/(v_r - v_l) = lam, max(|v_l|, |v_r|) = v, CCW turn (v_r >= v_l)
        vr = v
        with np.errstate(invalid="ignore"):
            vl = np.where(np.isinf(lam), v, v * (lam - 1.0) / (lam + 1.0))
        return vl / r, vr / r
    if cmd.kind == "rotation":
        v = np.full_like(t, cmd.v)
        return -v / r, v / r
    if cmd.kind == "lemniscate":
        v, radius = lemniscate_v_radius(t, cmd.t0)
        if cmd.accel > 0:  # Yu: ramp at accel to the initial speed, then follow the curve
            v0, r0 = lemniscate_v_radius(np.array([0.0]), cmd.t0)
            t_ramp = v0[0] / cmd.accel
            shifted = np.maximum(t - t_ramp, 0.0)
            v, radius = lemniscate_v_radius(shifted, cmd.t0)
            ramp = t < t_ramp
            v = np.where(ramp, cmd.accel * t, v)
            radius = np.where(ramp, np.inf, radius)
        vl, vr = inverse_v_radius(v, radius, B)
        return vl / r, vr / r
    if cmd.kind == "random":
        v, w = _random_profile(t, cmd, seed)
        return (v - w * B / 2) / r, (v + w * B / 2) / r
    raise SpecError("<command>", "command.kind", cmd.kind, "unknown command kind")


def first_order_lag(ref: np.ndarray, dt: float, tau: float, initial: float = 0.0) -> np.ndarray:
    """A side's powertrain as DRIVE models it (Baril et al. 2024; methods/baril2024/powertrain.py): the wheel-speed
    reference follows the command through ``tau dw/dt = u - w``, discretised exactly under a zero-order hold,
    ``w_k = w_{k-1} + (1 - exp(-dt/tau)) (u_k - w_{k-1})`` from ``w_{-1} = initial``; ``tau = 0`` returns ``ref``
    itself (the command passes bit for bit)."""
    if tau <= 0.0:
        return ref
    from scipy.signal import lfilter

    alpha = 1.0 - math.exp(-dt / tau)
    u = np.asarray(ref, float)
    y, _ = lfilter([alpha], [1.0, alpha - 1.0], u, zi=[(1.0 - alpha) * initial])
    return y


def rate_limit(ref: np.ndarray, dt: float, accel: float, initial: float = 0.0) -> np.ndarray:
    """``ref`` followed at a rate of at most ``accel`` [unit/s] per physics step ``dt``, from ``initial``: the
    velocity controller's acceleration limit (ROS diff_drive_controller's ``SpeedLimiter.limit_acceleration``:
    ``y_k = y_{k-1} + clip(u_k - y_{k-1}, -accel dt, accel dt)``).  ``accel = inf`` returns ``ref`` itself."""
    if not math.isfinite(accel):
        return ref
    u = np.asarray(ref, float).tolist()
    step = accel * dt
    y, prev = [0.0] * len(u), float(initial)
    for k, uk in enumerate(u):
        d = uk - prev
        prev = prev + (d if -step <= d <= step else math.copysign(step, d))
        y[k] = prev
    return np.array(y)


def wheel_speed_scale(ref_l: np.ndarray, ref_r: np.ndarray, limit: float) -> tuple[np.ndarray, np.ndarray]:
    """Both sides scaled by one factor so that the faster one is at most ``limit`` [rad/s]: the ratio of the two
    wheel speeds, hence the path's curvature, is kept (Clearpath husky_base ``limitDifferentialSpeed``).
    ``limit = inf`` returns the references themselves."""
    if not math.isfinite(limit):
        return ref_l, ref_r
    big = np.maximum(np.abs(ref_l), np.abs(ref_r))
    k = np.where(big > limit, limit / np.maximum(big, 1e-300), 1.0)
    return ref_l * k, ref_r * k
