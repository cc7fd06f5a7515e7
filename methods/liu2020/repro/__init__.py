"""Reproduction of Liu et al. 2020 on the skidbench testbed: Table 2, Figs. 6-20 and the claims.

Citation
    F. Liu, X. Li, S. Yuan and W. Lan, "Slip-Aware Motion Estimation for Off-Road Mobile Robots via
    Multi-Innovation Unscented Kalman Filter", IEEE Access, vol. 8, 2020,
    doi:10.1109/ACCESS.2020.2977889.

Declared in ``scenarios/papers/liu2020.toml``; run with ``skidbench reproduce liu2020 [--quick]``.
The four estimators are the plugins of :mod:`methods.liu2020` (En-DR, ICR, UKF+ICR, MI-UKF), called
through :func:`bench.registry.calibrate` / :func:`bench.registry.estimate` (truth withheld; a method
is never scored on a run it was calibrated on).

Paper item -> compute function (each returns ``dict[str, float]``; ids ``<table>.<metric>``)
    Table 2 (position RMS, truth reference)         :func:`table2` (tables)
    Table 2 (position RMS, GNSS reference, as Liu)  :func:`table2_gnss` (tables)
    Figs. 7-8, 12-13, 17-18 as numbers (heading / velocity RMS)  :func:`motion` (tables)
    Figs. 9, 14, 19 and Secs. V-C-3, V-D (ICR means, smoothness, yaw-rate sweep)  :func:`icr` (tables)
    Figs. 16-17 (-pi/pi chattering check)           :func:`heading` (tables)
    filter consistency (NEES vs chi-square band)    :func:`nees` (consistency; beyond the paper)
    Secs. III-B-3, III-C (20 s GNSS outage)         :func:`outage` (tables)
    Figs. 6-20 (XY, heading, velocities, ICR, slip per scenario)  ``liu2020_scenario{1,2,3}.png``
    plus ``liu2020_nees.png``, ``liu2020_outage.png``, ``liu2020_icr_smoothness.png``,
    ``liu2020_heading.png`` (figures), ``table2_intervals.md``, ``nees_consistency.md``.
Modules: ``evaluation`` (settings, the one batch of runs, calibration, estimates and per-run scores
shared by all tables), ``tables``, ``consistency``, ``figures``.

Choices (each one stated where the paper is silent or the testbed differs)
* Scenarios: ``liu_straight`` (s1), ``liu_large_radius`` (s2), ``liu_small_radius`` (s3) at the published
  commands.  Quick mode: 2 seeds; the scored scenarios, the sweep and the heading variant cut to 12 s (the
  outage variant stays 30 s, the calibration run 64 s).
* Seeds: 0..4 (full), 0..1 (quick).  The testbed physics is deterministic and seed independent: a seed
  changes only the sensor noise (GNSS drift direction, IMU noise and bias walk), so the intervals measure
  the estimators' sensitivity to sensor noise, not to terrain.
* Reference: Table 2 is scored against the testbed truth (geometric centre, every log row) in ``table2``
  and against the GNSS fixes (Liu's reference, which carries its 0.3 m initial drift) in ``table2_gnss``.
* Intervals: mean and two-sided 95% Student-t interval over the seeds (``scipy.stats.t``; a bootstrap of
  2-5 values is not meaningful).
* Calibration: the ICR method's constant (y_l, y_r, x) is fitted (``methods.liu2020.fit_icr``) on the
  dedicated calibration run ``scenarios/liu_calib.toml`` (seed 100: other path, speeds and radii, same
  platform and terrain).  As a sensitivity check, ``*.icr_samepath`` reports the ICR method calibrated
  on seed 100 of the *same* scenario (identical physics, other sensor noise).  The UKFs estimate the ICR
  online and have nothing to calibrate; En-DR uses the nominal geometry.  No parameter of any method is
  set from a scored run.
* Steady window: t >= 5 s for every steady-state statistic (ICR means/std, yaw rate, GNSS speed).
* ICR smoothness: std over the steady window of the MI-UKF's y_l and y_r (mean of the two stds), mean
  over seeds, at the samples where the ICR exists (truth |yaw rate| >= 1e-3 rad/s, the testbed's own
  definition); n/a when fewer than half of the window has one.  Liu's "more stable in s2 than in s1"
  compares s2 with the scored straight, whose class C bumps turn it both ways (it has an ICR at most of
  its steady samples); scenario 1 as Liu drove it (``s1_liu``: 4 m/s with the heading change 1.18 -> 0.67 rad
  of Sec. V-B-1 over the ~8 s of motion of Figs. 8, 10, a 63 m radius) is reported beside it.  The paper
  compares scenarios whose yaw rates differ (s2: 0.5, s3: -1 rad/s measured); but s2 and s3 differ in
  more than the yaw rate (speed, direction), so a yaw-rate sweep of scenario 2 (3 m/s at radii 17, 8, 4,
  2 m) tests the stated cause on its own: a check beyond the paper (Liu ran no sweep).
* Ordering claims hold only beyond the seeds' 95 % interval: their margin is the Student-t half-width of
  the per-seed paired difference (``*.margin.*``; the seeds share the physics, so the pair differs by the
  sensor noise only).
* ICR model against the traditional slip model (abstract): constant slip rates and sideslip angle
  (``methods.liu2020.SlipDr``) fitted on the same calibration run as the ICR method, both dead-reckoned
  on the turning scenarios (``slip_dr`` rows of Table 2, beside the paper's four).  Within one steady
  turn the two are functions of the same state estimate, and their relative spreads (std/|mean|,
  ``cv_icr``, ``cv_slip``) differ by the B/2 offset of y_l alone, so that comparison is reported, not scored.
* GNSS zero drift (Sec. IV-C, Figs. 3-4: removed by Liu before the robot moves): the scored runs keep the
  testbed's 0.3 m initial drift; ``nodrift.*`` repeats the two filters on the scored scenarios with it
  set to 0 (claim ``mi_vs_ukf_nodrift``).
* Heading check: scenario 3 started at yaw -2.8 rad (``initial_yaw`` override) so that the heading crosses
  -pi within ~3 s even in quick mode; excess = |wrap(yaw_k - yaw_k-1)| - (|truth yaw rate| dt + 0.02 rad).
* NEES (beyond the paper; :mod:`methods.liu2020.repro.consistency`): error against truth (X, Y, wrapped
  phi, v_x, v_y, yaw rate) with the filters' posterior P at every log row after the first, averaged over
  the N seeds per step; 95% band of the seed average ``[chi2_0.025(N n) / N, chi2_0.975(N n) / N]``
  (Bar-Shalom, Li, Kirubarajan 2001, Sec. 5.4).  Both configurations side by side: the paper's filters
  and their consistent configuration (``methods.liu2020.UkfIcrConsistent`` / ``MiUkfConsistent``, keys
  ``ukf_icr_c`` / ``mi_ukf_c``), whose noise is identified on the same calibration run as the ICR method
  (``liu_calib`` seed 100; GNSS vs the reference sensor, no truth; the process noise of heading, velocity
  and yaw rate from the innovations: whiteness for UKF+ICR, level for the MI-UKF,
  ``methods.liu2020.match_process_noise``).  They appear in the NEES and outage tables only; Table 2,
  the motion and ICR tables are the paper's four methods.  Claims ``nees_consistent`` / ``nees_paper``:
  every scenario's seed-averaged 6-state and pose NEES of both filters inside the band at >= 90 % of the
  steps (``bench.estimation.ukf.NEES_MIN_STEP_FRACTION``; Bar-Shalom's per-step test).
* Outage: scenario 2 cut to 30 s, GNSS blanked in [8, 28) s on the recorded runs
  (:func:`bench.robustness.faults.gnss_outage`) in two ways: Liu's 9x1 mode (Sec. IV-C after (32): positions
  deleted, and so the heading row, :func:`methods.liu2020.model._gnss_block`; GNSS velocity kept; metrics
  ``mode9x1.*``, claim ``outage_error_end``) and every GNSS channel (our harder check,
  ``outage_error_end_no_gnss``).  The filters' error at 28 s is compared with En-DR and ICR dead reckoning
  restarted from the true pose at 8 s (``*.drift_window``, :func:`methods.liu2020.repro.tables._window_drift`).
"""
from methods.liu2020.repro.consistency import nees, nees_band
from methods.liu2020.repro.evaluation import (
    ALL_FILTERS,
    CONSISTENT,
    FILTERS,
    LABELS,
    METHODS,
    SCENARIOS,
    SETTINGS,
    Settings,
    mean_ci,
    published_values,
)
from methods.liu2020.repro.tables import heading, icr, motion, outage, table2, table2_gnss

__all__ = ["table2", "table2_gnss", "motion", "icr", "heading", "nees", "outage", "Settings", "mean_ci", "nees_band",
           "published_values", "SETTINGS", "SCENARIOS", "METHODS", "FILTERS", "CONSISTENT", "ALL_FILTERS", "LABELS"]
