"""Yu 2010: dynamic model of a skid-steered wheeled vehicle with its closed speed loop.

W. Yu, O. Y. Chuy Jr., E. G. Collins Jr., P. Hollis, "Analysis and Experimental Verification for
Dynamic Modeling of a Skid-Steered Wheeled Vehicle," IEEE Transactions on Robotics, vol. 26,
no. 2, pp. 340-353, April 2010, doi:10.1109/TRO.2010.2042540.
Also used by T. Wang, Y. Wu, J. Liang, C. Han, J. Chen, Q. Zhao, "Analysis and Experimental
Kinematics of a Skid-Steering Wheeled Robot Based on a Laser Scanner Sensor," Sensors 15(5),
pp. 9681-9702, 2015, doi:10.3390/s150509681 (Sec. 2.2).

Frames: Yu's local frame has x lateral (right) and y longitudinal (forward); it is used only
inside :mod:`methods.yu2010.resistance` and :mod:`methods.yu2010.steady`.  Everything public takes
and returns skidbench quantities (body x forward, y left, yaw CCW; wheel speeds in rad/s; side
torques in N m at the wheel).

Paper equation -> code
  (1)  kinematic model with alpha ........ resistance.yu_twist, plugin.Yu2010.estimate (pose),
                                           commands.inverse_kinematics (its inverse, Fig. 8)
  (2)  no-slip model, commanded radius ... commands.inverse_kinematics(alpha=1), steady.steady_torques
  (4)/(23)/(25) dynamics ................. simulate._integrate (M q_ddot + C + G = tau)
  (5)  mass matrix ....................... params.YuParams.mass_matrix
  (7)  shear stress vs displacement ...... resistance.side_unit_forces
  (8)-(10) contact time, sliding velocity  resistance.shear_displacement, side_unit_forces
  (11)-(16) shear displacements .......... resistance.shear_displacement
  (17)/(20) sliding friction F_f ......... resistance.side_unit_forces, unit_long_forces
  (18)/(21)/(22) C(q, q_dot) ............. resistance.side_torque, resistance.resistance,
                                           resistance.ResistanceTable (lookup used at 1 kHz)
  (24) gravity G(q) ...................... params.YuParams.gravity, simulate._integrate
  (26) DC motor torque-speed line ........ simulate._integrate (closed loop), params.R_a/K_B
  (27) controller voltage limit .......... params.YuParams.V_max
  motor power limit (abstract, V-B) ...... params.YuParams.P_max, simulate._integrate
  Fig. 4 modified PID .................... simulate._integrate
  Fig. 16 open loop (tau = K_tau V) ...... simulate.simulate_open_loop, plugin.Yu2010OpenLoop
  (28) identification, Table I ........... identification.identify, identify_from_speeds
  Sec. V-A mu_roll, 31 radii ............. identification.rolling_from_straight, commands.commanded_radii
  (29)-(30) lemniscate, Figs. 22-23 ...... commands.lemniscate_xy, lemniscate_v_radius, lemniscate_command
  Wang 2015 (16)-(23), Fig. 5 ............ steady.wang_steady_state, steady.chi_vs_curvature_ratio
"""
from methods.yu2010.commands import (
    LEMNISCATE_TAU0,
    commanded_radii,
    inverse_kinematics,
    lemniscate_command,
    lemniscate_v_radius,
    lemniscate_xy,
)
from methods.yu2010.identification import (
    IdentificationResult,
    alpha_from_yaw_rate,
    evenly_spaced,
    identify,
    identify_from_speeds,
    rolling_from_straight,
)
from methods.yu2010.params import YuParams
from methods.yu2010.plugin import SteadySummary, Yu2010, Yu2010OpenLoop, steady_summary
from methods.yu2010.resistance import (
    PatchNodes,
    ResistanceTable,
    patch_nodes,
    resistance,
    shear_displacement,
    side_unit_forces,
    unit_long_forces,
)
from methods.yu2010.simulate import SimResult, simulate_closed_loop, simulate_open_loop
from methods.yu2010.steady import (
    WangSteadyState,
    chi_vs_curvature_ratio,
    steady_torques,
    wang2015_table1_params,
    wang_steady_state,
)

__all__ = [
    "LEMNISCATE_TAU0", "commanded_radii", "inverse_kinematics", "lemniscate_command", "lemniscate_v_radius",
    "lemniscate_xy", "IdentificationResult", "alpha_from_yaw_rate", "evenly_spaced", "identify",
    "identify_from_speeds", "rolling_from_straight", "YuParams", "SteadySummary", "Yu2010", "Yu2010OpenLoop",
    "steady_summary", "PatchNodes", "ResistanceTable", "patch_nodes", "resistance", "shear_displacement",
    "side_unit_forces", "unit_long_forces", "SimResult", "simulate_closed_loop", "simulate_open_loop",
    "WangSteadyState", "chi_vs_curvature_ratio", "steady_torques", "wang2015_table1_params", "wang_steady_state",
]
