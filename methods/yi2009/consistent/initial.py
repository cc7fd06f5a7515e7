"""The consistent filter's initial state (not Yi's).

The paper's :func:`methods.yi2009.ekf.initial_state` with the identified levelling precision where the run starts
at rest (:func:`at_rest_start`) and the yaw's P0 of the configuration, and the initial errors that the seeds of a
scenario share (:func:`shared_initial_states`, for the NEES null test).
"""
from __future__ import annotations

import numpy as np

from methods.yi2009.ekf import EkfParams, initial_state

def at_rest_start(enc: np.ndarray, wheel_radius: float, params: EkfParams) -> bool:
    """True when :func:`initial_state` levels roll/pitch (the wheels at rest over the first ``level_samples``
    steps).  Evaluated by :func:`initial_state` itself (no second copy of its test): fed a specific force with
    roll pi/4, it returns that roll only when it levels."""
    n = enc.shape[0]
    if n == 0:
        return False
    acc = np.tile((0.0, 1.0, 1.0), (n, 1))
    x0, _ = initial_state(acc, enc, wheel_radius, params, (0.0, 0.0, 0.0))
    return bool(x0[6] != 0.0)


def shared_initial_states(enc: np.ndarray, r: float, params: EkfParams, x0: np.ndarray) -> tuple[int, ...]:
    """The navigation states (0-8) whose initial error :func:`initial_state` does not take from the run's sensors,
    so that on a scenario's seeds (one truth, other sensor noise) it is the same: all but roll and pitch when they
    are levelled from the accelerometer (:func:`at_rest_start`) and the velocity when x0 has the first encoder
    sample's nonzero speed (its quantisation).  ``run_filter_gm`` ``shared_init``."""
    per_run = ((6, 7) if at_rest_start(enc, r, params) else ()) + ((3, 4, 5) if np.any(x0[3:6] != 0.0) else ())
    return tuple(i for i in range(9) if i not in per_run)


def _initial_state_consistent(acc: np.ndarray, enc: np.ndarray, r: float, params: EkfParams,
                              pose: tuple[float, float, float], unlevelled_p0_rollpitch: float,
                              start_yaw_sd: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """:func:`initial_state` with ``params`` (roll/pitch variance ``params.p0_rollpitch``, the identified static
    levelling precision) when the run starts at rest; otherwise with ``unlevelled_p0_rollpitch`` (the model's own
    value before identification: the paper's 0.02 rad by default).  ``start_yaw_sd`` [rad]: the yaw's P0 sd
    instead of ``params.p0_yaw`` (None: that)."""
    x0, p0 = initial_state(acc, enc, r, params, pose)
    if not at_rest_start(enc, r, params):
        p0[6, 6] = p0[7, 7] = unlevelled_p0_rollpitch ** 2
    if start_yaw_sd is not None:
        p0[8, 8] = start_yaw_sd**2
    return x0, p0
