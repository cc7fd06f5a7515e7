"""Reproduction of Yu 2010 on the skidbench testbed: Table I, Figs. 9-29 and Wang 2015 Fig. 5.

W. Yu, O. Y. Chuy Jr., E. G. Collins Jr., P. Hollis, "Analysis and Experimental Verification for
Dynamic Modeling of a Skid-Steered Wheeled Vehicle," IEEE Transactions on Robotics, vol. 26,
no. 2, pp. 340-353, April 2010, doi:10.1109/TRO.2010.2042540.
Wang 2015 Fig. 5: T. Wang, Y. Wu, J. Liang, C. Han, J. Chen, Q. Zhao, "Analysis and Experimental
Kinematics of a Skid-Steering Wheeled Robot Based on a Laser Scanner Sensor," Sensors 15(5),
pp. 9681-9702, 2015, doi:10.3390/s150509681 (Sec. 2.2, built on Yu's model).

Declared in ``scenarios/papers/yu2010.toml``; each function below is ``compute(ctx) -> metrics``
(:mod:`bench.reproduce`).  Paper item -> function:

  Table I, eq. (28), Sec. V-A (K, mu_sa, mu_op vs N; mu_roll, alpha) ... :func:`table1`     (sweep.py)
  Sec. V-A variations from the transcribed Table I ..................... :func:`table1_definition` (sweep.py)
  Fig. 9   steady torque vs commanded radius ............................ :func:`fig9`       (sweep.py)
  Figs. 10-13  circle 0.2 m/s, R = 4 m (wheel speed, torque, path) ..... :func:`fig10_13`   (circle.py)
  Figs. 14-16  straight 0.2 m/s, closed vs open loop ................... :func:`fig14_16`   (straight.py)
  Fig. 17  1.5 m/s command, saturation ................................. :func:`fig17`      (straight.py)
  Figs. 18-20  three ramps (holds / decelerates / fails) ............... :func:`fig18_20`   (ramps.py)
  Figs. 21-29  partial lemniscate, eqs. (29)-(30) ...................... :func:`fig22_29`   (lemniscate.py)
  Wang 2015 Fig. 5  chi vs curvature ratio from the steady state ....... :func:`wang_fig5`  (chi_curvature.py)

The runs, the calibrated model and the prediction of a scored run are in :mod:`methods.yu2010.repro.runs`,
the figure primitives in :mod:`methods.yu2010.repro.figures`; this package re-exports every compute function
(``module = "methods.yu2010.repro"`` in the declaration) and the public names of its modules.

Calibration runs and scored runs are different runs (DESIGN.md): the model is calibrated on the
31-radius sweep (``yu_radius_sweep``, one run per commanded radius of Sec. V-A) plus a straight
constant-speed run at 0.3 m/s for mu_roll (Sec. V-A), and on flat straight runs of each ramp's
surface for that surface's mu_roll; it is scored on the circle, the 0.2 and 1.5 m/s straight
runs, the ramps and the lemniscate, through :func:`bench.registry.calibrate` /
:func:`bench.registry.estimate` (truth withheld, scoring a calibration run refused).  The
lemniscate's surface is calibrated the same way on its own sweep (scenario ``yu_lemniscate_sweep``:
Yu identified that surface's K, mu_sa, mu_op by eq. (28) too); Yu's published Sec. V-C values are
scored beside it for comparison.
Metrics and figures may read the testbed's truth (velocities, pose, terrain spec); the model never
does.  Every simulation goes through ``ctx.simulate_many`` in one batch (run cache, process pool),
and the runs and the calibrated model are shared between the compute functions through
``ctx.scratch`` (key :data:`MEMO_KEY`; never persisted with the result).

Commands: a scenario's ``command.accel`` ramp (Yu: "commanded at an acceleration of 1 m/s^2")
is part of the command the model gets (:func:`ramped_command`); the testbed logs the commanded
step and ramps its PID reference at the same rate.
"""
from methods.yu2010.repro.chi_curvature import WANG_RATIOS, WANG_SPEEDS, wang_fig5
from methods.yu2010.repro.circle import ACCEL_PHASE, fig10_13
from methods.yu2010.repro.lemniscate import LEMNISCATE_PARAMS, RAMP_TIME, fig22_29, skill_ratio
from methods.yu2010.repro.ramps import OUTCOMES, TAIL, fig18_20, ramp_outcome
from methods.yu2010.repro.runs import (
    CAL_STRAIGHT_SPEED,
    LEMNISCATE_SWEEP,
    MEMO_KEY,
    RAMPS,
    SWEEP_SPEED,
    Calibrated,
    Experiments,
    calibrated,
    calibrated_lemniscate,
    experiments,
    monotone,
    ramped_command,
    sweep_scenarios,
    table_ii_params,
)
from methods.yu2010.repro.straight import fig14_16, fig17
from methods.yu2010.repro.sweep import (
    FIG9_SERIES,
    MULTISTART,
    TABLE1_N,
    TREND_TOL,
    fig9,
    published_table1,
    table1,
    table1_definition,
    variation,
)

__all__ = [
    "TABLE1_N", "Experiments", "Calibrated", "ramped_command", "ramp_outcome", "monotone", "variation",
    "published_table1", "sweep_scenarios", "experiments", "calibrated", "calibrated_lemniscate", "table1",
    "table1_definition", "fig9", "fig10_13", "fig14_16", "fig17", "fig18_20", "fig22_29", "wang_fig5",
    # the constants of the modules (attributes of methods.yu2010.repro before it became a package)
    "SWEEP_SPEED", "CAL_STRAIGHT_SPEED", "FIG9_SERIES", "TREND_TOL", "MULTISTART", "LEMNISCATE_SWEEP",
    "LEMNISCATE_PARAMS", "RAMP_TIME", "skill_ratio", "RAMPS", "OUTCOMES", "TAIL", "ACCEL_PHASE", "WANG_RATIOS",
    "WANG_SPEEDS", "MEMO_KEY",
    "table_ii_params",
]
