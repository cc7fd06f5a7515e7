"""Liu et al. 2020: slip-aware motion estimation with an ICR kinematic model and a multi-innovation UKF.

Citation
    F. Liu, X. Li, S. Yuan and W. Lan, "Slip-Aware Motion Estimation for Off-Road Mobile Robots via
    Multi-Innovation Unscented Kalman Filter", IEEE Access, vol. 8, 2020,
    doi:10.1109/ACCESS.2020.2977889.

Frames: Liu's body frame is ours (x forward, y left, yaw CCW).  His world rotation (9)/(13d-e) is printed
as a reflection; the proper rotation is used everywhere (:mod:`methods.liu2020.model`).

Four plugins, the four estimators compared in Liu's Figs. 6-20 and Table 2:

    liu2020.en_dr    EnDr     encoder dead reckoning, no-slip model (eqs. (1), (8) with y_l = B/2,
                              y_r = -B/2, x = 0, then (9))                           dead_reckoning
    liu2020.icr      IcrDr    ICR dead reckoning: A_ICR of eq. (8) with constant ICR locations
                              calibrated on calibration runs against GNSS (eqs. (2), (3), (5)), then (9)
                                                                                     dead_reckoning
    liu2020.ukf_icr  UkfIcr   UKF with IMU input and encoder-ICR + GNSS measurements (eqs. (14)-(24),
                              (30)-(32), Appendix); MI-UKF with lambda_2 = 0         ukf
    liu2020.mi_ukf   MiUkf    the same with the multi-innovation update, p = 2, a = 0.5 (eqs. (25)-(29))
                                                                                     ukf

and, not in the paper, the two filters in a consistent configuration (NEES in the chi-square band;
issue 4), whose noise is identified on calibration runs with a reference sensor (consistent):

    liu2020.ukf_icr_consistent  UkfIcrConsistent   UKF+ICR without the encoder pose pseudo-measurement,
    liu2020.mi_ukf_consistent   MiUkfConsistent    GNSS error as Gauss-Markov bias states, identified R,
                                                   process noise identified from the innovations

Modules: the paper in ``inputs`` (what is read from a Run), ``icr`` (ICR kinematics), ``dead_reckoning``
(En-DR, ICR), ``model`` (state, process and measurement models), ``ukf`` (UKF+ICR, MI-UKF); beyond the
paper ``gnss_bias`` and ``consistent`` (the consistent configuration); ``repro`` (the reproduction:
Table 2, Figs. 6-20, the claims; its NEES study, beyond the paper, in ``repro.consistency``).  Each
module's docstring gives its readings of ambiguous or inconsistent printed equations.

Paper equation -> code (modules of methods.liu2020)
    (1)  one speed per side .................. the Run's enc_wl, enc_wr (inputs._interval_speed, inputs._ffill)
    (2), (3), (5) ICR from the velocities .... icr.icr_from_state (per step, UKFs); dead_reckoning.fit_icr
                                               (constant, least squares, ICR DR)
    (4)  slipping / skidding from y_l, y_r ... reading only (the outputs y_l, y_r)
    (6)-(8), (11) A_ICR: body velocity from
         the tread speeds .................... bench.kinematics.icr_forward (dead_reckoning._dr_estimate,
                                               dead_reckoning.fit_icr); ukf.run_liu_filter (encoder
                                               pseudo-measurement)
    (9)  body -> world rotation .............. bench.kinematics.integrate_se2 (dead_reckoning._dr_estimate),
                                               model.liu_fx (UKF)
    (10) wheel slip .......................... icr.slip_rates (repo definition, see icr)
    (12), (13a-f), (30) process model ........ model.liu_fx
    (14) f and h ............................. model.liu_fx, model.liu_hx
    (15) initial state and covariance ........ ukf.run_liu_filter (inputs._initial_pose, ukf.LiuUkfParams.p0_*)
    (16)-(24) UKF ............................ bench.estimation.ukf.Ukf (built by ukf.run_liu_filter)
    (25)-(28) multi-innovation update ........ bench.estimation.ukf.Ukf(mi_weights=bench.estimation.ukf.mi_weights(2, 0.5))
    (29) lambda_1 = 1, lambda_i = a/(p - 1) .. bench.estimation.ukf.mi_weights; ukf.LiuUkfParams.innovation_length, mi_a
    (31), (32), Appendix measurement model ... model.liu_hx, model._gnss_block (block 1), ukf.run_liu_filter
                                               (block 2: encoder-ICR pseudo-measurement),
                                               ukf.LiuUkfParams.r_gnss / r_encoder
    Table 1 (B, r) ........................... inputs.Geometry, inputs.geometry
    Fig. 6 start point (first GNSS fix) ...... inputs._initial_pose
    Sec. V-B-3 initial ICR (B/2, -B/2, 0) .... ukf.run_liu_filter
    Sec. V-B-3 [-20, 20] ICR clamp ........... ukf.LiuUkfParams.icr_clamp, icr.icr_from_state
    Sec. IV-A ICR carried through a GNSS
         outage .............................. ukf.LiuUkfParams.icr_hold_gnss_timeout / icr_hold_window,
                                               icr._icr_update_allowed, icr._icr_window_fit
    Table 2, Figs. 6-20, claims .............. repro (scenarios/papers/liu2020.toml)
    abstract: "the traditional wheel slip/skid
         model" (the ICR model's comparator) . dead_reckoning.SlipDr, fit_slip, slip_forward (repro only,
                                               not a registered plugin)
Not Liu's
    ICR held through an encoder dropout ...... inputs._encoder_fresh (ukf.run_liu_filter, dead_reckoning._dr_estimate)
    no interpolation across a sensor gap ..... inputs._within_sampling (dead_reckoning.fit_icr)
    MI covariance incl. (28) ................. bench.estimation.ukf.Ukf(mi_covariance=True), ukf.LiuUkfParams.mi_covariance
    consistent configuration ................. ukf.LiuUkfParams.encoder_pose / gnss_bias_* / icr_min_expansion,
                                               gnss_bias.liu_fx_gnss_bias, gnss_bias.liu_hx_gnss_bias,
                                               consistent.identify_noise, consistent.match_process_noise,
                                               consistent.UkfIcrConsistent, consistent.MiUkfConsistent
    filter consistency (NEES) ................ repro.consistency.nees
"""
from methods.liu2020.consistent import (
    MiUkfConsistent,
    UkfIcrConsistent,
    identify_noise,
    innovation_statistics,
    match_process_noise,
)
from methods.liu2020.dead_reckoning import EnDr, IcrDr, SlipDr, fit_icr, fit_slip, slip_forward
from methods.liu2020.gnss_bias import liu_fx_gnss_bias, liu_hx_gnss_bias
from methods.liu2020.icr import icr_from_state, slip_rates
from methods.liu2020.inputs import GAP_INTERVALS, PAPER, TIME_SLACK, Geometry, geometry
from methods.liu2020.model import STATE_NAMES, liu_fx, liu_hx
from methods.liu2020.ukf import LiuUkfParams, MiUkf, UkfIcr, run_liu_filter

__all__ = [
    "EnDr", "IcrDr", "SlipDr", "fit_slip", "slip_forward", "UkfIcr", "MiUkf", "LiuUkfParams", "Geometry", "geometry", "liu_fx", "liu_hx",
    "fit_icr", "slip_rates", "icr_from_state", "run_liu_filter", "PAPER", "UkfIcrConsistent", "MiUkfConsistent",
    "identify_noise", "liu_fx_gnss_bias", "liu_hx_gnss_bias", "match_process_noise", "innovation_statistics",
    "STATE_NAMES", "GAP_INTERVALS", "TIME_SLACK",
]
