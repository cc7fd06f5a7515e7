"""Baseline: ideal differential-drive dead reckoning, and the run helpers every kinematic plugin shares.

``baseline.ideal_dd`` integrates the encoder wheel speeds with the no-slip differential-drive model
(tread ICRs on the wheel centre lines, ``y_l = B/2``, ``y_r = -B/2``, ``x_icr = 0``): the yardstick
every skid-steer model of the suite must beat.  On real DRIVE windows it is the row ``ideal_dd`` of the
real-data benchmark (:meth:`IdealDD.window_models`, :class:`IdealDDWindowModel`).

Shared helpers (public, reused by :mod:`methods.mandow2007` and :mod:`methods.wang2015`):

- :func:`platform_geometry`  track ``B`` and nominal wheel radius ``r`` from ``run.meta["platform"]``
- :func:`encoder_speeds`     encoder samples ``(t, wl, wr)`` [s, rad/s], rows with a NaN dropped
- :func:`reference_poses`    reference-sensor samples ``(t, x, y, yaw)`` (rows where all three exist)
- :func:`initial_pose`       first reference pose if the run has one, else ``(0, 0, 0)``
- :func:`held_integral`      exact integral of a zero-order-held signal between two instants
- :func:`dead_reckon`        body velocities at the encoder instants -> world poses (SE(2), ZOH)

Conventions (DESIGN.md): body x forward, y left, yaw CCW; tread speeds ``v = r * w``.  An encoder reading is
the count difference over the period that ENDS at its stamp (:func:`bench.sim.sensors.encoders`, and what encoder
drivers publish), so :func:`encoder_speeds` returns at index ``k`` the reading stamped ``t_{k+1}``: the speed over
``[t_k, t_{k+1}]``, which the zero-order hold of :func:`bench.kinematics.integrate_se2` and :func:`held_integral`
applies there (as :func:`methods.liu2020.inputs._interval_speed`).  Holding the reading of ``t_k`` over the next
period instead integrated every wheel one sample late (a wheel ramping to 4 rad/s in 2 s through the testbed's
encoder: 3.960 rad for the true 4.000).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np
from numpy.typing import ArrayLike

from bench.kinematics import ideal_dd, integrate_se2
from bench.real.drive import DriveWindows
from bench.real.windows import Pose, VelocityWindowModel, tread_speeds
from bench.registry import Estimate, make_estimate
from bench.run import Run, RunError

__all__ = [
    "IdealDD",
    "IdealDDWindowModel",
    "dead_reckon",
    "encoder_speeds",
    "has_reference",
    "held_integral",
    "initial_pose",
    "platform_geometry",
    "reference_poses",
]

REFERENCE_CHANNELS = ("ref_x", "ref_y", "ref_yaw")


# ------------------------------------------------------------------------------------------------
# Run helpers
# ------------------------------------------------------------------------------------------------
def _platform_field(run: Run, name: str) -> float:
    plat = run.meta.get("platform")
    if plat is None:
        raise RunError(run.where, "meta.platform", None, "the run's metadata has no platform (track, wheel_radius)")
    value = plat.get(name) if isinstance(plat, Mapping) else getattr(plat, name, None)
    try:
        out = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise RunError(run.where, f"meta.platform.{name}", value, "expected a number") from None
    if not (np.isfinite(out) and out > 0):
        raise RunError(run.where, f"meta.platform.{name}", value, "expected a finite value > 0")
    return out


def platform_geometry(run: Run) -> tuple[float, float]:
    """``(track B [m], wheel_radius r [m])`` of the run's platform (geometry a user knows)."""
    return _platform_field(run, "track"), _platform_field(run, "wheel_radius")


def _check_time(run: Run, t: np.ndarray, channel: str) -> None:
    d = np.diff(t)
    if np.any(d <= 0):
        i = int(np.flatnonzero(d <= 0)[0])
        raise RunError(run.where, "t", f"{channel} sample {i + 1}: {t[i + 1]!r} after {t[i]!r}",
                       "time must increase strictly")


def encoder_speeds(run: Run) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Encoder instants and interval speeds ``(t, wl, wr)`` at the rows where both ``enc_wl`` and ``enc_wr`` are
    finite (a NaN reading is dropped, never integrated).  ``wl[k]``, ``wr[k]`` are the readings stamped ``t[k+1]``,
    the mean speeds over ``[t[k], t[k+1]]`` (a reading covers the period ending at its stamp; across a dropped
    reading the next one is held back over the gap, of which its own period is only the end).  The last is
    repeated (it holds after the log's end, where no pose is asked) and the first reading, of the period before
    the log, is not used.  Raises :class:`RunError` naming the run and the channel when fewer than two samples
    remain."""
    t = run.t
    wl, wr = run["enc_wl"], run["enc_wr"]
    ok = np.isfinite(t) & np.isfinite(wl) & np.isfinite(wr)
    if ok.sum() < 2:
        bad = "enc_wl" if np.isfinite(wl).sum() < 2 else "enc_wr"
        raise RunError(run.where, bad, f"{int(ok.sum())} usable samples",
                       "dead reckoning needs at least two samples with both encoders finite")
    t, wl, wr = t[ok], wl[ok], wr[ok]
    _check_time(run, t, "encoder")
    return t, np.concatenate((wl[1:], wl[-1:])), np.concatenate((wr[1:], wr[-1:]))


def reference_poses(run: Run) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Reference-sensor samples ``(t, x, y, yaw)`` at the rows where ``ref_x``, ``ref_y`` and
    ``ref_yaw`` are all finite; yaw is unwrapped.  Raises :class:`RunError` if a channel is missing."""
    for c in REFERENCE_CHANNELS:
        if c not in run.channels:
            raise RunError(run.where, c, None, "missing reference channel")
    x, y, yaw = run["ref_x"], run["ref_y"], run["ref_yaw"]
    ok = np.isfinite(run.t) & np.isfinite(x) & np.isfinite(y) & np.isfinite(yaw)
    t = run.t[ok]
    _check_time(run, t, "reference")
    return t, x[ok], y[ok], np.unwrap(yaw[ok])


def has_reference(run: Run) -> bool:
    """True when the run has at least two complete reference poses."""
    if not all(c in run.channels for c in REFERENCE_CHANNELS):
        return False
    m = np.isfinite(run["ref_x"]) & np.isfinite(run["ref_y"]) & np.isfinite(run["ref_yaw"])
    return int(m.sum()) >= 2


def initial_pose(run: Run) -> tuple[float, float, float]:
    """Initial pose ``(x0, y0, yaw0)`` for dead reckoning: the run's first complete reference sample
    (``ref_x``, ``ref_y``, ``ref_yaw`` finite on the same row) if there is one, else the origin.
    The pose is assigned to the first encoder instant (the reference and encoders start together in
    the suite's logs)."""
    if not all(c in run.channels for c in REFERENCE_CHANNELS):
        return 0.0, 0.0, 0.0
    x, y, yaw = run["ref_x"], run["ref_y"], run["ref_yaw"]
    ok = np.flatnonzero(np.isfinite(x) & np.isfinite(y) & np.isfinite(yaw))
    if ok.size == 0:
        return 0.0, 0.0, 0.0
    i = int(ok[0])
    return float(x[i]), float(y[i]), float(yaw[i])


def held_integral(t: ArrayLike, v: ArrayLike, t0: ArrayLike, t1: ArrayLike) -> np.ndarray:
    """Exact integral over ``[t0, t1]`` of the signal that holds ``v[k]`` on ``[t[k], t[k+1])``
    (zero-order hold; the last value is held after ``t[-1]``, zero before ``t[0]``).  Vectorised over
    ``t0``/``t1``.  Used for the wheel travel ``S = integral r w dt`` of Mandow eqs. (11)-(12) and
    Wang eq. (25)."""
    t, v = np.asarray(t, float), np.asarray(v, float)
    cum = np.concatenate(([0.0], np.cumsum(v[:-1] * np.diff(t))))

    def prim(tau: np.ndarray) -> np.ndarray:
        tau = np.maximum(np.asarray(tau, float), t[0])
        k = np.searchsorted(t, tau, side="right") - 1
        return cum[k] + v[k] * (tau - t[k])

    return prim(np.asarray(t1, float)) - prim(np.asarray(t0, float))


def dead_reckon(t: np.ndarray, vx: np.ndarray, vy: np.ndarray, wz: np.ndarray,
                pose0: tuple[float, float, float]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """World poses at ``t`` from body velocities held over each encoder interval (exact SE(2)
    exponential, :func:`bench.kinematics.integrate_se2`)."""
    return integrate_se2(t, vx, vy, wz, *pose0)


# ------------------------------------------------------------------------------------------------
# Plugin
# ------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class IdealDD:
    """``baseline.ideal_dd``: no-slip differential drive from the encoders.

    ``vx = r (wl + wr)/2``, ``vy = 0``, ``wz = r (wr - wl)/B`` (:func:`bench.kinematics.ideal_dd`),
    integrated from :func:`initial_pose`.  Nothing to calibrate.
    """

    name: str = "baseline.ideal_dd"
    paper: str = "ideal differential drive (no slip)"
    requires: frozenset[str] = frozenset({"enc_wl", "enc_wr"})

    def calibrate(self, runs: Sequence[Run]) -> "IdealDD":
        """Nothing to identify; returns a copy (so calibration bookkeeping lands on the copy)."""
        return dataclasses.replace(self)

    def estimate(self, run: Run) -> Estimate:
        track, radius = platform_geometry(run)
        t, wl, wr = encoder_speeds(run)
        vx, vy, wz = ideal_dd(radius * wl, radius * wr, track)
        pose0 = initial_pose(run)
        x, y, yaw = dead_reckon(t, vx, vy, wz, pose0)
        n = t.size
        return make_estimate(
            self.name, {"track": track, "wheel_radius": radius, "initial_pose": pose0},
            t=t, x=x, y=y, yaw=yaw, vx=vx, vy=vy, wz=wz,
            y_l=np.full(n, track / 2), y_r=np.full(n, -track / 2), x_icr=np.zeros(n), chi=np.ones(n),
        )

    def window_models(self, wheel_radius: float, track: float) -> list["IdealDDWindowModel"]:
        """The real-data benchmark's row ``ideal_dd`` (:mod:`bench.real.windows` protocol)."""
        return [IdealDDWindowModel(wheel_radius, track)]


@dataclass(frozen=True)
class IdealDDWindowModel(VelocityWindowModel):
    """Ideal differential drive with the nominal track and wheel radius (nothing to fit)."""

    wheel_radius: float
    track: float
    name: str = "ideal_dd"
    label: str = "ideal differential drive, nominal B"
    fit_cost: float = math.nan

    def fit(self, calib: DriveWindows) -> "IdealDDWindowModel":
        return self

    def velocities(self, w: DriveWindows) -> Pose:
        return ideal_dd(*tread_speeds(w, self.wheel_radius), self.track)

    def params(self) -> dict[str, float]:
        return {"B": self.track, "r": self.wheel_radius}
