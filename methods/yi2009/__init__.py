"""Yi et al. 2009: IMU + encoder EKF with skid-steer velocity constraints and slip estimation.

Citation
    J. Yi, H. Wang, J. Zhang, D. Song, S. Jayasuriya, J. Liu, "Kinematic Modeling and Analysis of
    Skid-Steered Mobile Robots With Applications to Low-Cost Inertial-Measurement-Unit-Based Motion
    Estimation", IEEE Transactions on Robotics, vol. 25, no. 5, pp. 1087-1097, Oct. 2009,
    doi:10.1109/TRO.2009.2026506.

Frames and units
    The paper's body frame B is x forward, y left, z up, yaw counter-clockwise (its eqs. (3)-(4)
    put the left wheels at y = +W/2): the same as skidbench, so no axis conversion is needed.
    Euler angles Theta = (phi, theta, psi) are Z-Y-X (eq. (2)).  Everything is SI inside; the
    published S(gamma) coefficient a1 is in cm and is converted only in :meth:`s_gamma.SGamma.from_cm` /
    :attr:`s_gamma.SGamma.a1_cm`; the rpm wheel speeds of the experiments belong to the scenario files.
    The IMU is at the centre of mass (x_M = y_M = 0, Sec. V-A), so eqs. (5), (13) and (15) are
    used with x_M = y_M = 0 and the IMU state is the robot state.

Map: paper equation -> code (module.function of this package)
    (1)  one wheel speed per side, w_L, w_R ............. the channels enc_wl, enc_wr (ekf.align_inputs)
    (2)  C_B^I(phi, theta, psi) ......................... ekf.dcm; inline in the EKF loop
    (3)-(5)  wheel-centre and IMU velocities ............ the EKF loop (slip step); windows.YiSGamma
    (6)  slip lambda_i = (r w_i - v_ix)/(r w_i), clipped to [-1, 1] (Sec. III-A)
         ................................................ slip.slip_ratio; inline in the EKF loop
    (7)  S = -v_Gy / yaw_rate ........................... s_gamma.reference_s_gamma_point, windows.yi_s_points
    (8)-(9a)  tread slip velocities, tread ICRs y_lc, y_rc  windows.YiSGamma (constant y_lc, y_rc)
    (10a)-(10e)  IMU kinematics (strapdown, Euler rates)  the EKF loop (prediction)
    (11)  v_Bz = 0 ...................................... measurement row 3
    (12)-(14)  v_Bx from encoders, sign-constrained slip  measurement row 1; (14) also slip.constrained_slip
         (with the cases of Sec. III-C's sentence: w_L = w_R is the w_L <= w_R case for both wheels)
    (15)  v_By = (x_M - S) yaw_rate ..................... measurement row 2 (variant 3); windows.YiSGamma
    (16)-(17)  y = C^T V_I + w .......................... measurement model
    (18)-(19)  X(k) = X(k-1) + dT f(X(k-1), u(k-1)) ..... prediction
    (20)-(22)  F = I + dT df/dX, F_Theta, F_V ........... prediction Jacobian
    (23)-(25)  H = [0, C^T, H_Theta] .................... measurement Jacobian
    (26a)-(26f)  EKF recursion, Joseph form (26f) ....... ekf.run_filter
    (27)-(39)  velocity-error analysis (Sec. IV-B) ...... no code (an analysis, not part of the estimator)
    (40)  gamma = (v_Lx - v_Rx)/(v_Lx + v_Rx) ........... s_gamma.gamma_ratio
    (41)  S(gamma) = a1 / (a2 |gamma| + a3) ............. s_gamma.SGamma; windows.s_of_gamma (with its limits)
    Sec. V-B  nonlinear least-squares fit of (41) ....... s_gamma.fit_s_gamma, ekf.Yi2009Ekf.calibrate
    Fig. 5  variants 1/2/3 .............................. ekf.Yi2009Ekf(variant=...), ekf.ekf_v1, ekf_v2, ekf_v3
    Figs. 3-7  the reproduction ......................... repro (scenarios/papers/yi2009.toml)
    "The EKF loop" (prediction, measurement rows and model, Jacobians, correction) is one loop,
    consistent.filter.run_filter_gm: ekf.run_filter is that loop without error states and with its default
    options (Yi's rows), so that one implementation serves the paper and the consistent configuration.

Modules
    s_gamma      S(gamma) (40)-(41), its identification (Sec. V-B) and the (gamma, S) point of (7) from the reference
    slip         slip (6) and its sign constraint (14) on arrays
    ekf          the EKF of Sec. IV-A as the paper defines it and the plugin Yi2009Ekf (ekf_v1 .. ekf_v3)
    windows      Yi's kinematics as real-data window models (YiSGamma; Yi2009Ekf.window_models)
    consistent   the consistent configuration, beyond the paper (Yi2009EkfConsistent, ekf_v1_consistent ..)
    repro        the reproduction of Figs. 3-7 and the NEES study (scenarios/papers/yi2009.toml)
"""
from methods.yi2009.s_gamma import (PUBLISHED_S_GAMMA, REF_CHANNELS, SGamma, SGammaFit, fit_s_gamma, gamma_ratio,
                                    reference_s_gamma_point)
from methods.yi2009.slip import constrained_slip, slip_ratio
from methods.yi2009.ekf import (ENC_CHANNELS, IMU_CHANNELS, PAPER, EkfParams, FilterDivergence, FilterResult, Yi2009Ekf,
                                align_inputs, dcm, ekf_v1, ekf_v2, ekf_v3, initial_state, run_filter)
from methods.yi2009.consistent import (GaussMarkov, Yi2009EkfConsistent, ekf_v1_consistent, ekf_v2_consistent,
                                       ekf_v3_consistent, run_filter_gm, shared_initial_states)

__all__ = [
    "PUBLISHED_S_GAMMA", "REF_CHANNELS", "SGamma", "SGammaFit", "fit_s_gamma", "gamma_ratio", "reference_s_gamma_point",
    "constrained_slip", "slip_ratio",
    "ENC_CHANNELS", "IMU_CHANNELS", "PAPER", "EkfParams", "FilterDivergence", "FilterResult", "Yi2009Ekf",
    "align_inputs", "dcm", "ekf_v1", "ekf_v2", "ekf_v3", "initial_state", "run_filter",
    "GaussMarkov", "Yi2009EkfConsistent", "ekf_v1_consistent", "ekf_v2_consistent", "ekf_v3_consistent",
    "run_filter_gm", "shared_initial_states",
]

