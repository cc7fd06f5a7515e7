"""Plausibility of imported magnitudes given the platform: wheel speeds beyond the motor's no-load
speed (typically rpm given as rad/s), gyro rates beyond the fastest possible turn (deg/s as rad/s),
an accelerometer reading ~1 at rest (g as m/s^2), a heading in rad beyond +-pi (degrees).
"""
from __future__ import annotations

import math
from typing import Any, Mapping

import numpy as np

from bench.formats.mapping import PoseMap
from bench.run import Run, RunError
from bench.spec import Platform, build

__all__ = ["max_wheel_speed", "max_yaw_rate", "check_plausible"]


def _platform_obj(platform: Platform | Mapping[str, Any] | None) -> Platform | None:
    if platform is None or isinstance(platform, Platform):
        return platform
    return build(Platform, platform, "<run meta>")


def max_wheel_speed(platform: Platform) -> float:
    """No-load wheel speed [rad/s] at the supply voltage: omega_n / g_r * V_cc / V_nom."""
    m = platform.motor
    return m.no_load_speed / m.gear_ratio * m.supply_voltage / m.nominal_voltage


def max_yaw_rate(platform: Platform, w_max: float | None = None) -> float:
    """Fastest turn of an ideal differential drive with both sides at +-w_max: 2 r w_max / B
    (skid-steering only slows the turn down)."""
    w = max_wheel_speed(platform) if w_max is None else w_max
    return 2.0 * platform.wheel_radius * w / platform.track


def check_plausible(run: Run, platform: Platform | Mapping[str, Any] | None = None,
                    hints: Mapping[str, str] | None = None, max_wheel: float = 0.0) -> Run:
    """Reject magnitudes the platform cannot produce, with a unit suggestion.

    ``platform`` defaults to ``run.meta["platform"]``; ``hints`` maps a channel to where it came
    from (e.g. ``"CSV column 'wl', mapping wheels.unit = 'rad/s'"``).  Checks: wheel speeds
    (enc_*, cmd_*) against 1.5 x :func:`max_wheel_speed`; |imu_gz| against 1.5 x
    :func:`max_yaw_rate`; the median accelerometer norm (0.5..2 looks like g).
    """
    plat = _platform_obj(platform if platform is not None else run.meta.get("platform"))
    hints = dict(hints or {})
    where = run.where
    if plat is None:
        return run

    def src(c: str) -> str:
        return f"{c} ({hints[c]})" if c in hints else c

    w_max = max_wheel or max_wheel_speed(plat)
    lim = 1.5 * w_max
    for c in ("enc_wl", "enc_wr", "cmd_wl", "cmd_wr"):
        if c not in run.channels:
            continue
        v = run[c]
        a = np.abs(v[np.isfinite(v)])
        if a.size and a.max() > lim:
            vmax = float(a.max())
            as_rpm = vmax * 2.0 * math.pi / 60.0
            as_deg = vmax * math.pi / 180.0
            if as_rpm <= lim:
                hint = (f"looks like rpm ({vmax:.4g} rpm = {as_rpm:.3g} rad/s); set unit = \"rpm\" "
                        "in the mapping")
            elif as_deg <= lim:
                hint = (f"looks like deg/s ({vmax:.4g} deg/s = {as_deg:.3g} rad/s); set unit = "
                        "\"deg/s\" in the mapping")
            else:
                hint = "check the unit and the platform"
            raise RunError(where, src(c), vmax,
                           f"wheel speed exceeds 1.5 x the maximum {w_max:.3g} rad/s of platform "
                           f"'{plat.name}': {hint}")
    if "imu_gz" in run.channels:
        g = run["imu_gz"]
        a = np.abs(g[np.isfinite(g)])
        r_max = max_yaw_rate(plat, w_max)
        if a.size and a.max() > 1.5 * r_max:
            vmax = float(a.max())
            as_rad = vmax * math.pi / 180.0
            hint = (f"looks like deg/s ({vmax:.4g} deg/s = {as_rad:.3g} rad/s); set gyro_unit = "
                    "\"deg/s\" in the mapping" if as_rad <= 1.5 * r_max else "check the unit")
            raise RunError(where, src("imu_gz"), vmax,
                           f"yaw rate exceeds 1.5 x the fastest turn {r_max:.3g} rad/s of platform "
                           f"'{plat.name}': {hint}")
    acc = [c for c in ("imu_ax", "imu_ay", "imu_az") if c in run.channels]
    if len(acc) == 3:
        a = np.column_stack([run[c] for c in acc])
        m = np.all(np.isfinite(a), axis=1)
        if m.any():
            med = float(np.median(np.linalg.norm(a[m], axis=1)))
            if 0.5 < med < 2.0:
                raise RunError(where, src("imu_az"), med,
                               "median specific-force norm should be about 9.81 m/s^2 (gravity); "
                               "it looks like g: set accel_unit = \"g\" in the mapping")
    return run


def _check_yaw_unit(where: str, col: str, yaw: np.ndarray, pm: PoseMap, section: str) -> None:
    if pm.yaw_unwrapped or pm.yaw_unit != "rad":
        return
    a = np.abs(yaw[np.isfinite(yaw)])
    if a.size and a.max() > 2 * math.pi + 0.5:
        raise RunError(where, col, float(a.max()),
                       f"a heading in rad stays within +-pi; this looks like degrees: set "
                       f"{section}.yaw_unit = \"deg\" (or {section}.yaw_unwrapped = true)")
