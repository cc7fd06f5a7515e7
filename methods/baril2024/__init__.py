"""Baril et al. 2024 (DRIVE): the slip-based Bayesian-linear-regression motion model, the learned peer model.

Citation
    D. Baril, S.-P. Deschênes, L. Coupal, C. Goffin, J. Lépine, P. Giguère and F. Pomerleau, "DRIVE: Data-driven
    Robot Input Vector Exploration", IEEE International Conference on Robotics and Automation (ICRA), 2024,
    arXiv:2309.10718.  Code and data: github.com/norlab-ulaval/DRIVE.

Frame: body x forward, y left, yaw CCW (the suite's own); wheel speeds in rad/s.

Source of the equations.  Only the paper's abstract and the opening of its introduction were retrievable in this
session (the stored arXiv HTML v2 page, its beginning only), so its equation numbers are NOT quoted below; the
abstract states the protocol and "a novel learned slip approach outperforming similar acceleration learning
approaches".  The model's form, its regressors, the prior and the powertrain follow the authors' public code
(``model_training/models/learning/blr_slip.py``, ``models/powertrain/bounded_powertrain.py``,
``model_trainers/{blr_slip,powertrain}_trainer.py``), re-derived from the textbook closed forms; every choice the
code does not fix is labelled in the module that makes it.

Paper model -> code
  IDD velocity from wheel speeds ............... slip_blr.idd_velocities (bench.kinematics.ideal_dd)
  body velocity = IDD + slip ................... slip_blr.SlipBlr.body_velocity
  slip regressors (v; v w; v w, v, w) .......... slip_blr.slip_features, slip_blr.FEATURES
  BLR, conjugate normal-inverse-gamma prior .... slip_blr.posterior (w_N, Lambda_N, a_N, b_N),
                                                 slip_blr.BayesianLinearRegression.fit (the authors' prior),
                                                 slip_blr.BlrPosterior.covariance
  BLR predictive mean / variance (Student-t) ... slip_blr.BlrPosterior.predict
  slip targets: reference body velocity - IDD .. slip_blr.body_twist, windows.slip_training_data (DRIVE windows),
                                                 plugins.run_training_data (Runs)
  powertrain: bounded first order + dead time .. powertrain.Powertrain, powertrain.simulate
  powertrain identification per side ........... powertrain.fit_powertrain
  model driven by measured wheel speeds ........ windows.BlrSlipWindows (row ``baril2024_blr_slip``)
  model driven by commands (powertrain) ........ windows.BlrSlipCmdWindows (row ``baril2024_blr_slip_cmd``)
  training on steady-state windows ............. windows.slip_training_data(train="steady")
  uncertainty propagation (sigma points) ....... not implemented (the benchmark scores the mean pose)

Plugin (:mod:`methods.baril2024.plugins`): ``baril2024.blr_slip`` (:class:`BlrSlip`), Run-based calibrate/estimate
and the real-data window models.
"""
from methods.baril2024.plugins import PAPER, BlrSlip, NotCalibratedError, run_training_data
from methods.baril2024.powertrain import Powertrain, fit_powertrain, simulate
from methods.baril2024.slip_blr import (
    AXES,
    FEATURES,
    BayesianLinearRegression,
    BlrPosterior,
    SlipBlr,
    SlipBlrError,
    body_twist,
    idd_velocities,
    posterior,
    slip_features,
)

__all__ = [
    "AXES", "FEATURES", "PAPER", "BayesianLinearRegression", "BlrPosterior", "BlrSlip", "NotCalibratedError",
    "Powertrain", "SlipBlr", "SlipBlrError", "body_twist", "fit_powertrain", "idd_velocities", "run_training_data",
    "posterior", "simulate", "slip_features",
]
