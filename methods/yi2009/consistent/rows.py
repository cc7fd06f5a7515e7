"""Known parts of the pseudo-measurement rows' errors, subtracted before their Gauss-Markov states (not Yi's).

The traction slip of the v_x row (13) (:class:`TractionSlip`, :func:`fit_traction_slip` on
:func:`traction_features`) and the S correction of the v_y row (15) (:class:`IcrCorrection`,
:func:`fit_icr_correction` on :func:`icr_features`), both fitted by least squares on moving means
(:func:`fit_row_offset`), and the offsets they give the rows of :func:`methods.yi2009.consistent.filter.run_filter_gm`.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np

from methods.yi2009.consistent.gauss_markov import _window_means
from methods.yi2009.consistent.sensors import _moving, _no_slip_speed
from methods.yi2009.ekf import EkfParams

def _require_finite(obj: Any, names: Sequence[str]) -> None:
    """ValueError naming the class and field when one of the ``names`` fields of ``obj`` is not a finite number."""
    for k in names:
        v = getattr(obj, k)
        if not (isinstance(v, (int, float)) and math.isfinite(v)):
            raise ValueError(f"{type(obj).__name__}.{k} = {v!r}: must be finite")


@dataclass(frozen=True)
class TractionSlip:
    """Traction slip of the v_x row (13) (not Yi's): the net slip velocity r (w_L + w_R)/2 - v_Bx predicted from the
    IMU as ``c_f`` f_x + ``c_w`` |w_z| while the wheels turn (0 at rest), with f_x the specific force along the
    body x axis [m/s^2] and w_z the body yaw rate [rad/s].  Linear region of the slip-traction curve: the
    longitudinal force the treads transmit is m f_x plus the resistances (f_x = a_x + g sin(pitch) is the
    accelerometer's reading, so a slope is included), and the slip velocity is proportional to it (Wong, Theory of
    Ground Vehicles, 4th ed. 2008, Sec. 2.1 / Yu 2010's shear-displacement law at small shear); turning needs
    opposite longitudinal forces on the two sides, whose slip and skid do not cancel in the mean (the |w_z| term,
    identified, not derived).  ``c_f`` [s], ``c_w`` [m]; identified by :func:`fit_traction_slip`."""

    c_f: float
    c_w: float

    def __post_init__(self) -> None:
        _require_finite(self, ("c_f", "c_w"))

    def offset(self, acc: np.ndarray, gyr: np.ndarray, moving: np.ndarray) -> np.ndarray:
        """Predicted net slip velocity [m/s] per step (IMU rows on the filter grid; 0 where not ``moving``)."""
        return np.where(moving, self.c_f * acc[:, 0] + self.c_w * np.abs(gyr[:, 2]), 0.0)


def traction_features(acc: np.ndarray, gyr: np.ndarray) -> np.ndarray:
    """(n, 2) features of :class:`TractionSlip`: specific force along body x, |yaw rate|."""
    return np.column_stack((acc[:, 0], np.abs(gyr[:, 2])))


def _longest_finite_run(e: np.ndarray) -> int:
    """The length of the longest run of consecutive finite samples of ``e``."""
    edges = np.diff(np.concatenate(([0], np.isfinite(e).astype(np.int8), [0])))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    return int((ends - starts).max()) if starts.size else 0


def fit_row_offset(res: Sequence[np.ndarray], feats: Sequence[np.ndarray], dt: float, window: float = 2.0,
                   who: str = "fit_row_offset") -> tuple[np.ndarray, dict[str, float]]:
    """Least-squares coefficients c of a pseudo-measurement row's error modelled as feats @ c, from row residuals
    (row minus reference, NaN = masked) on their ``window``-s moving means (full windows of finite samples, all
    overlapping windows pooled): the residual's own noise (encoder quantisation, the reference derivative's noise)
    averages out in the means and sits on the left-hand side only, so the fit is unbiased (numpy.linalg.lstsq).
    Returns c and the RMS of the moving means before / after (the share of the row's low-frequency error the
    model explains)."""
    w = max(2, int(round(window / dt)))
    feats = [np.asarray(f, float) for f in feats]
    masked = [np.where(np.isfinite(f).all(axis=1), np.asarray(e, float), np.nan) for e, f in zip(res, feats)]
    try:  # full windows (min_fraction 1) of the residual and, over the same windows, of each feature
        y = _window_means(masked, w)
        x = np.column_stack([_window_means(masked, w, over=[f[:, j] for f in feats]) for j in range(feats[0].shape[1])])
    except ValueError:
        y = np.empty(0)
    if y.size < 3:
        longest = max((_longest_finite_run(e) for e in masked), default=0)
        raise ValueError(f"{who}: no full {window} s window of finite residuals and features (the longest run of "
                         f"finite steps is {longest} = {longest * dt:.3f} s; a step is masked at rest, when gated, or "
                         "when it has no new wheel-encoder sample, e.g. encoders slower than the IMU)")
    c, *_ = np.linalg.lstsq(x, y, rcond=None)
    return c, {"window": w * dt, "rms_before": float(np.sqrt(np.mean(y**2))),
               "rms_after": float(np.sqrt(np.mean((y - x @ c) ** 2))), "windows": int(y.size)}


def fit_traction_slip(res: Sequence[np.ndarray], feats: Sequence[np.ndarray], dt: float, window: float = 2.0
                      ) -> tuple[TractionSlip, dict[str, float]]:
    """:class:`TractionSlip` fitted to v_x row residuals (no-slip row minus reference v_x) by :func:`fit_row_offset`
    on :func:`traction_features`."""
    c, info = fit_row_offset(res, feats, dt, window, "fit_traction_slip")
    return TractionSlip(float(c[0]), float(c[1])), info


@dataclass(frozen=True)
class IcrCorrection:
    """Correction of S in the v_y row (15) (not Yi's): S(gamma) (41) + ``c_0`` + ``c_1`` v |w_z| while the wheels
    turn, so that the row is y_y = -S(gamma) psi_dot - (c_0 + c_1 v |w_z|) w_z, with psi_dot the Euler yaw rate
    (10e) of (15), v = r (w_L + w_R)/2 the encoders' no-slip speed [m/s] and w_z the gyro's yaw rate [rad/s] (the
    correction is computed from the sensors before the filter runs; on level ground psi_dot = w_z).  Eq. (41)
    makes S a function of gamma alone; the lateral force balance of a skid-steered turn shifts the ICR line by a
    distance proportional to the centripetal acceleration v |w_z| over the friction (the longitudinal shift of the
    turning centre of a tracked vehicle, Wong, Theory of Ground Vehicles, 4th ed. 2008, Ch. 7, steering of tracked
    vehicles), which (41) cannot hold at other speeds than the identification runs' (the testbed's true S at one
    gamma rises with speed in proportion to v |w_z|, see :class:`Yi2009EkfConsistent`); ``c_0`` takes the
    constant part of the error of the S(gamma) used.  ``c_0`` [m], ``c_1`` [s^2]; identified by
    :func:`fit_icr_correction` on the calibration runs."""

    c_0: float
    c_1: float

    def __post_init__(self) -> None:
        _require_finite(self, ("c_0", "c_1"))

    def delta_s(self, gyr: np.ndarray, enc: np.ndarray, r: float) -> np.ndarray:
        """The correction c_0 + c_1 v |w_z| of S [m] per step (NaN where an encoder sample is NaN)."""
        return self.c_0 + self.c_1 * _no_slip_speed(enc, r) * np.abs(gyr[:, 2])

    def gyro_gain(self, gyr: np.ndarray, enc: np.ndarray, r: float) -> np.ndarray:
        """d(offset)/d w_z = c_0 + 2 c_1 v |w_z| [m] per step: the correction's share of the gain from the gyro's
        noise to the row (the row's total gain is S(gamma) + this)."""
        return self.c_0 + 2.0 * self.c_1 * _no_slip_speed(enc, r) * np.abs(gyr[:, 2])

    def offset(self, gyr: np.ndarray, enc: np.ndarray, r: float, moving: np.ndarray) -> np.ndarray:
        """The v_y row's predicted error [m/s] per step, (c_0 + c_1 v |w_z|) w_z (0 where not ``moving`` or where an
        encoder sample is NaN)."""
        d = self.delta_s(gyr, enc, r)
        return np.where(moving & np.isfinite(d), np.nan_to_num(d) * gyr[:, 2], 0.0)


def icr_features(gyr: np.ndarray, enc: np.ndarray, r: float) -> np.ndarray:
    """(n, 2) features of :class:`IcrCorrection`: yaw rate, no-slip speed x yaw rate x |yaw rate| (NaN where an
    encoder sample is NaN)."""
    wz = gyr[:, 2]
    return np.column_stack((wz, _no_slip_speed(enc, r) * wz * np.abs(wz)))


def fit_icr_correction(res: Sequence[np.ndarray], feats: Sequence[np.ndarray], dt: float, window: float = 2.0
                       ) -> tuple[IcrCorrection, dict[str, float]]:
    """:class:`IcrCorrection` fitted to v_y row residuals ((15) minus reference v_y) by :func:`fit_row_offset` on
    :func:`icr_features`: the row's error is (S_true - S) w_z (eq. (15) with (7))."""
    c, info = fit_row_offset(res, feats, dt, window, "fit_icr_correction")
    return IcrCorrection(float(c[0]), float(c[1])), info


def _gamma_wheel_speeds(opts: Mapping[str, Any], enc: np.ndarray) -> np.ndarray:
    """The wheel speeds of gamma (40) and the S correction: the filter options' ``enc_gamma``, else ``enc``."""
    g = opts.get("enc_gamma")
    return enc if g is None else g


def _row_offsets(traction: TractionSlip | None, icr: IcrCorrection | None, acc: np.ndarray, gyr: np.ndarray,
                 enc: np.ndarray, r: float, params: EkfParams, enc_gamma: np.ndarray | None = None
                 ) -> tuple[np.ndarray | None, np.ndarray | None]:
    """``vx_offset`` and ``vy_offset`` of :func:`run_filter_gm` for ``traction`` and ``icr`` (None without one); the
    S correction's speed from ``enc_gamma`` (the wheel speeds of gamma, :meth:`Yi2009EkfConsistent.gamma_speeds`;
    None: ``enc``)."""
    moving = _moving(enc, r, params.min_wheel_speed)
    return (None if traction is None else traction.offset(acc, gyr, moving),
            None if icr is None else icr.offset(gyr, enc if enc_gamma is None else enc_gamma, r, moving))
