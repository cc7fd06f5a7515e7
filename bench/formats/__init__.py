"""Log import/export: TUM trajectories, CSV logs and ROS 1/ROS 2 bags -> :class:`bench.run.Run`.

* TUM (``timestamp tx ty tz qx qy qz qw``, one pose a line, ``#`` comments; the format of the
  TUM RGB-D benchmark, read by evo): :func:`write_tum`, :func:`read_tum`, :func:`run_to_tum`.
  Numbers are written as Python's repr (shortest exact text), so a float64 round-trips exactly.
* Estimates (``skidbench estimate``'s CSV: t, x, y, yaw, ...): :func:`read_estimate_csv`, checked.
* CSV and bags: :func:`import_csv`, :func:`import_bag`.  A *mapping* TOML file
  (:class:`ImportMapping`, see :func:`load_mapping`) names, per Run channel group, the CSV
  columns or the bag topic and the units the log uses; values are converted to SI at this
  boundary (rpm -> rad/s, m/s tread speed -> rad/s with the wheel radius, deg -> rad, g ->
  m/s^2, ms -> s, ...).  Example::

      run_id = "field_test_3"
      [time]
      column = "stamp"            # CSV; bags use header stamps (source = "header" | "receive")
      unit = "ms"
      [platform]
      name = "p3at_pneumatic_20psi"   # scenarios/platforms/<name>.toml, or a .toml path beside this mapping
      [wheels]                    # -> enc_wl, enc_wr   ([commands] -> cmd_wl, cmd_wr)
      left = "wl"                 # CSV columns
      right = "wr"
      topic = "/joint_states"     # bags: sensor_msgs/JointState velocities, averaged per side
      left_joints = ["front_left_wheel", "rear_left_wheel"]
      right_joints = ["front_right_wheel", "rear_right_wheel"]
      unit = "rpm"                # rad/s | rpm | deg/s | m/s (tread speed; needs wheel_radius)
      [imu]                       # -> imu_ax..az, imu_gx..gz (sensor_msgs/Imu on bags)
      topic = "/imu/data"
      gyro_unit = "rad/s"         # or deg/s ; accel_unit = "m/s^2" or "g"
      [gnss]                      # -> gnss_x, gnss_y, gnss_yaw, gnss_vx, gnss_vy (world frame)
      topic = "/gnss/odom"        # nav_msgs/Odometry | geometry_msgs/PoseStamped | sensor_msgs/NavSatFix
      [reference]                 # -> ref_x, ref_y, ref_yaw
      [truth]                     # -> truth_x, truth_y, truth_yaw (+ truth_vx, vy, wz: body frame)

  What a Husky or Jackal bag carries (no JointState)::

      [platform]
      name = "husky"                                # the wheel radius and track of the twists below
      [wheels]
      topic = "/husky_velocity_controller/odom"     # nav_msgs/Odometry: twist -> wheel speeds (DD inverse)
      track = 1.0702                                # [m] the driver's effective B (see below); 0 = platform's
      [commands]
      topic = "/cmd_vel"                            # geometry_msgs/Twist | TwistStamped -> cmd_wl, cmd_wr
      track = 1.0702                                #   (a Twist has no header: timed at receive)
      [gnss]
      topic = "/navsat/fix"                         # sensor_msgs/NavSatFix -> local ENU metres (pymap3d, WGS-84)
      velocity = "fix_difference"                   # optional: gnss_vx, gnss_vy from the fixes' track
      heading = "course"                            # optional: gnss_yaw = course over ground where moving
      course_min_speed = 0.2                        #   [m/s] below it no yaw sample
      [datum]                                       # optional ENU origin of every NavSatFix topic (WGS-84);
      latitude_deg = 46.78                          #   default the first fix with status >= STATUS_FIX
      longitude_deg = -71.27
      altitude = 60.0                               # [m] ellipsoidal; default the first fix's

  ``wheel_radius`` / ``track`` in a ``[wheels]`` or ``[commands]`` section override the platform's for a twist
  topic.  v, omega become wheel speeds by the ideal differential-drive inverse (v -+ omega B / 2) / r, the model the
  ROS diff_drive_controller used to make that twist from the encoders (and to turn cmd_vel into wheel speeds) --
  with its own B, ``wheel_separation x wheel_separation_multiplier``: on a Husky 1.875 x 0.5708 m = 1.07 m (ROS 1
  husky_control control.yaml, the separation from the URDF; 1.875 x 0.555 = 1.04 m in Clearpath's ROS 2 A200
  config), on a Jackal 1.5 x its wheel separation.  The platform's geometric 0.55 m
  track gives wheel speeds whose difference is 1/1.875 of the encoders'.  NavSatFix fixes with STATUS_NO_FIX are
  dropped (a warning; counts in ``meta["navsat"]``), a fix with NaN altitude is placed at the datum's; the datum goes
  into ``meta["enu_datum"]``.  ``velocity`` / ``heading`` are for NavSatFix topics (``velocity`` for [gnss] only);
  without them a fix gives x, y only, and Liu 2020's estimators, which read gnss_yaw, gnss_vx and gnss_vy, need
  them.  :mod:`bench.formats.bag` says how each message type is read, :mod:`bench.formats.geodesy` how fixes
  become metres.

  Bags are read with ``rosbags`` (``rosbags.highlevel.AnyReader``: ROS 1 ``.bag`` files and
  ROS 2 bag directories, no ROS install).  Rows of the Run are the union of all sample
  timestamps (no resampling: a channel is NaN where its sensor has no sample), starting at
  t = 0; the absolute time of the first row is ``meta["time_origin_ns"]``.

Every problem raises :class:`bench.run.RunError` (data) or :class:`bench.spec.SpecError`
(mapping) naming the file, the column/topic/field, the value and what was expected.

:func:`check_plausible` rejects implausible magnitudes given the platform (wheel speeds beyond
the motor's no-load speed -- typically rpm given as rad/s --, gyro rates beyond the fastest
possible turn -- deg/s as rad/s --, an accelerometer reading ~1 at rest -- g as m/s^2).

Modules: :mod:`~bench.formats.tum`, :mod:`~bench.formats.mapping` (the mapping TOML and its units),
:mod:`~bench.formats.csv`, :mod:`~bench.formats.bag`, :mod:`~bench.formats.geodesy` (NavSatFix fixes -> local ENU
metres), :mod:`~bench.formats.channels` (samples -> Run, shared by both imports), :mod:`~bench.formats.plausible`;
every public name is importable from ``bench.formats`` (the geodesy helpers from ``bench.formats.geodesy``).
"""
from __future__ import annotations

from bench.formats.bag import import_bag
from bench.formats.csv import import_csv, read_estimate_csv
from bench.formats.mapping import (G0, DatumMap, ImportMapping, ImuMap, PlatformMap, PoseMap,  # noqa: F401
                                   TimeMap, WheelMap, load_mapping)
from bench.formats.plausible import check_plausible, max_wheel_speed, max_yaw_rate
from bench.formats.tum import TUM_HEADER, read_tum, run_to_tum, write_tum  # noqa: F401

__all__ = [
    "write_tum", "read_tum", "run_to_tum", "TimeMap", "WheelMap", "ImuMap", "PoseMap",
    "DatumMap", "PlatformMap", "ImportMapping", "load_mapping", "import_csv", "read_estimate_csv", "import_bag",
    "check_plausible", "max_wheel_speed", "max_yaw_rate",
]
