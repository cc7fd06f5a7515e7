"""DRIVE's slip-based BLR model on the real-data benchmark's command windows (:mod:`bench.real.windows` protocol).

Two window models, vectorised over the windows of a DRIVE table, fitted on the calibration windows only:

* :class:`BlrSlipWindows` (row ``baril2024_blr_slip``): the IDD velocities of the measured wheel speeds plus the
  predictive-mean slip of the three BLRs (:class:`methods.baril2024.slip_blr.SlipBlr`).
* :class:`BlrSlipCmdWindows` (row ``baril2024_blr_slip_cmd``): DRIVE's use of the model, driven by the commanded
  wheel speeds through the per-side powertrain (:mod:`methods.baril2024.powertrain`), from each window's initial
  measured wheel speed (the initial state, as the initial ICP pose is the initial pose).  The powertrain is fitted
  first, on the transitory calibration windows (bounds: the measured range of all calibration windows), then the
  slip on the IDD velocities of the powertrain's wheel speeds, as the authors' pipeline learns it
  (``slip_dataset_parser.py``: IDD of the modelled wheel speeds).

Training data (:func:`slip_training_data`): for every sample interval k -> k+1 of a window, the body velocity that
carries the ICP pose of sample k to that of sample k + 1 (:func:`methods.baril2024.slip_blr.body_twist`, the SE(2)
logarithm; the authors difference a smoothing spline of the ICP poses and take the yaw rate from the IMU) and the IDD
velocity of the wheel speeds at sample k (the velocity the zero-order-hold prediction holds over that interval);
slip = body - IDD.  Windows: the steady ones, as the authors' trainer (``blr_slip_trainer.py``:
``steady_state_mask``); all windows with ``train="all"``, or when a calibration set has no steady window.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np

from bench.real.drive import DriveWindows
from bench.real.windows import Pose, VelocityWindowModel
from methods.baril2024.powertrain import Powertrain, fit_powertrain
from methods.baril2024.slip_blr import BayesianLinearRegression, SlipBlr, Velocities, body_twist, idd_velocities

TRAIN_WINDOWS = ("steady", "all")
WheelSpeeds = Callable[[DriveWindows], tuple[np.ndarray, np.ndarray]]


class NotFittedError(RuntimeError):
    """A DRIVE window model was asked to predict before ``fit``."""


def measured_wheel_speeds(w: DriveWindows) -> tuple[np.ndarray, np.ndarray]:
    return w["enc_wl"], w["enc_wr"]


def training_windows(calib: DriveWindows, train: str) -> DriveWindows:
    """The calibration windows the slip is learned on (module docstring)."""
    if train not in TRAIN_WINDOWS:
        raise ValueError(f"train must be one of {TRAIN_WINDOWS}, got {train!r}")
    return calib.subset(calib.steady) if train == "steady" and calib.steady.any() else calib


def slip_training_data(calib: DriveWindows, wheel_radius: float, track: float, train: str = "steady",
                       wheel_speeds: WheelSpeeds = measured_wheel_speeds) -> tuple[Velocities, Velocities]:
    """(IDD velocities, reference body velocities) per sample interval of the training windows, each
    (n_windows, n_samples - 1); an interval with a NaN stays NaN (the fit drops it)."""
    w = training_windows(calib, train)
    wl, wr = wheel_speeds(w)
    idd = idd_velocities(wl[:, :-1], wr[:, :-1], wheel_radius, track)
    return idd, body_twist(w["ref_x"], w["ref_y"], w["ref_yaw"], w.dt)


def _require(slip: SlipBlr | None, name: str) -> SlipBlr:
    if slip is None:
        raise NotFittedError(f"{name}: call fit(calibration windows) first")
    return slip


@dataclass(frozen=True)
class BlrSlipWindows(VelocityWindowModel):
    """IDD of the measured wheel speeds + BLR slip (predictive mean)."""

    wheel_radius: float
    track: float
    prior: BayesianLinearRegression = BayesianLinearRegression()
    train: str = "steady"
    slip: SlipBlr | None = field(default=None, compare=False, repr=False)
    name: str = "baril2024_blr_slip"
    label: str = "IDD + BLR slip (Baril 2024), measured wheel speeds"
    fit_cost: float = math.nan
    n_fit: int = 0

    def fit(self, calib: DriveWindows) -> "BlrSlipWindows":
        slip = SlipBlr.fit(*slip_training_data(calib, self.wheel_radius, self.track, self.train), prior=self.prior)
        return replace(self, slip=slip, n_fit=slip.posteriors["x"].n)

    def velocities(self, w: DriveWindows) -> Pose:
        idd = idd_velocities(w["enc_wl"], w["enc_wr"], self.wheel_radius, self.track)
        return _require(self.slip, self.name).body_velocity(idd)

    def params(self) -> dict[str, float]:
        return dict(self.slip.params()) if self.slip is not None else {}


@dataclass(frozen=True)
class BlrSlipCmdWindows(VelocityWindowModel):
    """Commands -> powertrain (per side) -> IDD + BLR slip (predictive mean)."""

    wheel_radius: float
    track: float
    prior: BayesianLinearRegression = BayesianLinearRegression()
    train: str = "steady"
    left: Powertrain = Powertrain()
    right: Powertrain = Powertrain()
    slip: SlipBlr | None = field(default=None, compare=False, repr=False)
    name: str = "baril2024_blr_slip_cmd"
    label: str = "IDD + BLR slip (Baril 2024), commands through the powertrain"
    fit_cost: float = math.nan
    n_fit: int = 0
    inputs: tuple[str, ...] = ("commands", "first wheel speed")  # what it reads of a window (the real league)

    def fit(self, calib: DriveWindows) -> "BlrSlipCmdWindows":
        trans = calib.subset(calib.transitory) if calib.transitory.any() else calib
        sides = {}
        for side, c, e in (("left", "cmd_wl", "enc_wl"), ("right", "cmd_wr", "enc_wr")):
            enc = calib[e][np.isfinite(calib[e])]
            bounds = (float(enc.min()), float(enc.max())) if enc.size else None
            sides[side] = fit_powertrain(trans[c], trans[e], calib.dt, bounds)
        model = replace(self, **sides)
        data = slip_training_data(calib, self.wheel_radius, self.track, self.train, model.wheel_speeds)
        slip = SlipBlr.fit(*data, prior=self.prior)
        return replace(model, slip=slip, n_fit=slip.posteriors["x"].n)

    def wheel_speeds(self, w: DriveWindows) -> tuple[np.ndarray, np.ndarray]:
        """The powertrain's wheel speeds (n_windows, n_samples) from the commands and the first measured speed."""
        return (self.left.simulate(w["cmd_wl"], w["enc_wl"][:, 0], w.dt),
                self.right.simulate(w["cmd_wr"], w["enc_wr"][:, 0], w.dt))

    def velocities(self, w: DriveWindows) -> Pose:
        slip = _require(self.slip, self.name)
        return slip.body_velocity(idd_velocities(*self.wheel_speeds(w), self.wheel_radius, self.track))

    def params(self) -> dict[str, float]:
        out = dict(self.slip.params()) if self.slip is not None else {}
        for side, p in (("l", self.left), ("r", self.right)):
            out.update({f"tau_{side}": p.tau, f"delay_{side}[samples]": float(p.delay), f"w_min_{side}": p.w_min,
                        f"w_max_{side}": p.w_max, f"powertrain_mae_{side}": p.fit_cost})
        return {k: (float(v) if math.isfinite(v) else math.nan) for k, v in out.items()}

