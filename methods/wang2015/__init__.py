"""Wang et al. 2015: symmetric skid-steer kinematics with an ICR coefficient chi(curvature ratio).

Citation
    T. Wang, Y. Wu, J. Liang, C. Han, J. Chen and Q. Zhao, "Analysis and experimental kinematics of a
    skid-steering wheeled robot based on a laser scanner sensor", Sensors, vol. 15, no. 5,
    pp. 9681-9702, 2015, doi:10.3390/s150509681.

Axes: Wang's body frame is x forward, y left (Fig. 1), the suite's own; no conversion.

Paper equation -> code
  (1)        body to world velocities ................ methods.baselines.dead_reckon (bench.kinematics.integrate_se2)
  (4)-(9)    tread-ICR kinematics .................... bench.kinematics.icr_forward (shared)
  (10)-(11)  symmetric model ......................... kinematics.symmetric_velocities
  (13)       path curvature variable lambda .......... bench.kinematics.curvature_ratio
             (called ``curvature_ratio`` in code, never ``lambda``)
  (15)       chi = (y_l - y_r)/B = 2 y0 / B .......... kinematics.symmetric_velocities (y0 = B chi / 2)
  (16)-(23), Fig. 5 dynamic simulation ............... methods.yu2010.steady.wang_steady_state,
                                                       chi_vs_curvature_ratio (Yu's model, Wang Sec. 2.2)
  (25), (36), (42) y0 = (S_r - S_l)/(2 phi) per run .. chi.chi_per_run, chi.RunChi
  (26)-(27)  the 40 identification runs .............. chi.identification_plan
  (28)-(41)  laser localization, error analysis ...... not implemented (the testbed's reference sensor)
  (44)       chi(lambda) = 1 + a / (1 + b |lambda|^1/2)  chi.chi_of_curvature_ratio, chi.ChiCurve
  (44) fit   nonlinear least squares for (a, b) ...... chi.fit_chi_curve (scipy curve_fit),
                                                       chi.identify_chi_curve (Section 3 on runs)
  (45)       published fit a = 0.4728, b = 0.0538 .... chi.PUBLISHED_CURVE
  (46)       default P3-AT model, chi = 1.5 .......... plugins.ConstantChi (``wang2015.constant_chi``),
                                                       kinematics.CHI_P3AT_DEFAULT
  (47)       proposed model, chi(lambda) ............. plugins.ChiLambda (``wang2015.chi_lambda``)
  (48)       validation inputs ....................... kinematics.VALIDATION_PROFILE
  Table 3    chi per lambda (published means) ........ chi.TABLE_3
  Tables 3-4, Figs. 12-16 on the testbed ............. repro (table3, fit, table3_corrected, table4)
  (11), (15) on real DRIVE windows, constant chi ..... windows.SymmetricChi (end-pose least squares)
  (44), (47) on real DRIVE windows, (25) measured .... windows.WangChiCurve, windows.wang_chi, windows.WANG_P3AT

Inconsistency in the paper (reported, not silently fixed): eqs. (46)-(47) print
``omega_z = (v_r - v_l) / (2 B chi)``; eqs. (11) and (15) give ``(v_r - v_l) / (B chi)``, the default here;
``literal_eq46=True`` reproduces the printed equations (:mod:`methods.wang2015.kinematics`).

Implementation choices (documented, configurable; :mod:`methods.wang2015.chi`): chi(lambda) is held at
chi(10) beyond the stated domain lambda in [0, 10]; chi per run uses the run from ``skip_start`` on and
skips runs turning less than ``min_rotation`` (0.25 rad).

Plugins (:mod:`methods.wang2015.plugins`): ``wang2015.chi_lambda`` (:class:`ChiLambda`) offers the real-data
window model ``wang2015_chi_curve``, ``wang2015.constant_chi`` (:class:`ConstantChi`) offers ``icr_sym_chi``
(``window_models``, :mod:`methods.wang2015.windows`).
"""
from methods.wang2015.chi import (
    CURVATURE_RATIO_MAX,
    PUBLISHED_CURVE,
    TABLE_3,
    CalibrationDataError,
    ChiCurve,
    ChiIdentification,
    PlanEntry,
    RunChi,
    chi_of_curvature_ratio,
    chi_per_run,
    fit_chi_curve,
    identification_plan,
    identify_chi_curve,
)
from methods.wang2015.kinematics import CHI_P3AT_DEFAULT, VALIDATION_PROFILE, symmetric_velocities
from methods.wang2015.plugins import PAPER, ChiLambda, ConstantChi, NotCalibratedError

__all__ = [
    "CURVATURE_RATIO_MAX", "PUBLISHED_CURVE", "TABLE_3", "CalibrationDataError", "ChiCurve", "ChiIdentification",
    "PlanEntry", "RunChi", "chi_of_curvature_ratio", "chi_per_run", "fit_chi_curve", "identification_plan",
    "identify_chi_curve", "CHI_P3AT_DEFAULT", "VALIDATION_PROFILE", "symmetric_velocities", "PAPER", "ChiLambda",
    "ConstantChi", "NotCalibratedError",
]
