"""NEES of an estimate's horizontal velocity against the testbed truth (Bar-Shalom's consistency test).

Used by a paper's NEES study and by the stress suite alike, so it lives in the harness: it reads the
Run's truth channels and an :class:`bench.registry.Estimate` carrying its covariance
(``est.info["P"]``, one (n, n) matrix per estimate step), nothing of a method.
"""
from __future__ import annotations

import numpy as np

from bench.estimation.ukf import nees as nees_values
from bench.registry import Estimate
from bench.run import Run

NEES_T_MIN = 5.0  # [s] default start of the NEES window (the first seconds hold the filter's transient)
VELOCITY_BLOCK = (3, 5)  # state indices [start, stop) of V_I (x, y) in est.info["P"]: Yi 2009's state (26a)


def horizontal_velocity_error(run: Run, est: Estimate) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(e (n, 2), cos yaw, sin yaw): the horizontal V_I error at the estimate's steps, the estimate's body velocity
    rotated by its yaw minus the truth's rotated by the true yaw, and the estimated heading's cos / sin."""
    t = est["t"]
    tv = {c: np.interp(t, run.t, run[f"truth_{c}"]) for c in ("vx", "vy")}
    tyaw = np.interp(t, run.t, np.unwrap(run["truth_yaw"]))
    c, s_ = np.cos(est["yaw"]), np.sin(est["yaw"])
    ct, st = np.cos(tyaw), np.sin(tyaw)
    e = np.column_stack((c * est["vx"] - s_ * est["vy"] - (ct * tv["vx"] - st * tv["vy"]),
                         s_ * est["vx"] + c * est["vy"] - (st * tv["vx"] + ct * tv["vy"])))
    return e, c, s_


def velocity_nees_series(run: Run, est: Estimate, t_min: float = NEES_T_MIN,
                         block: tuple[int, int] = VELOCITY_BLOCK) -> np.ndarray:
    """Per-step NEES of the horizontal velocity V_I (x, y) (state block ``block`` of ``est.info["P"]``, 2 dof)
    against the testbed truth after ``t_min`` s (:func:`horizontal_velocity_error`)."""
    e, _, _ = horizontal_velocity_error(run, est)
    m = est["t"] >= t_min
    a, b = block
    return np.asarray(nees_values(e[m], est.info["P"][m][:, a:b, a:b]), dtype=float)
