"""Log import/export: TUM trajectories, CSV logs and ROS 1/ROS 2 bags -> :class:`bench.run.Run`.

* TUM (``timestamp tx ty tz qx qy qz qw``, one pose a line, ``#`` comments; the format of the
  TUM RGB-D benchmark, read by evo): :func:`write_tum`, :func:`read_tum`, :func:`run_to_tum`.
  Numbers are written as Python's repr (shortest exact text), so a float64 round-trips exactly.
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
      name = "p3at_pneumatic_20psi"   # scenarios/platforms/<name>.toml: geometry + plausibility
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
      [commands]
      topic = "/cmd_vel"                            # geometry_msgs/Twist or TwistStamped -> cmd_wl, cmd_wr
      [gnss]
      topic = "/navsat/fix"                         # sensor_msgs/NavSatFix -> local ENU metres (pymap3d)
      datum_lat = 46.78                             # optional ENU origin [deg, deg, m]; default the first fix
      datum_lon = -71.27
      datum_alt = 60.0

  (``wheel_radius`` / ``track`` in a ``[wheels]`` or ``[commands]`` section override the platform's;
  :mod:`bench.formats.bag` says how each message type is read.)

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
:mod:`~bench.formats.csv`, :mod:`~bench.formats.bag`, :mod:`~bench.formats.channels` (samples -> Run,
shared by both imports), :mod:`~bench.formats.plausible`; every public name is importable from
``bench.formats``.
"""
from __future__ import annotations

from bench.formats.bag import import_bag
from bench.formats.csv import import_csv
from bench.formats.mapping import (G0, ImportMapping, ImuMap, PlatformMap, PoseMap, TimeMap,  # noqa: F401
                                   WheelMap, load_mapping)
from bench.formats.plausible import check_plausible, max_wheel_speed, max_yaw_rate
from bench.formats.tum import TUM_HEADER, read_tum, run_to_tum, write_tum  # noqa: F401

__all__ = [
    "write_tum", "read_tum", "run_to_tum", "TimeMap", "WheelMap", "ImuMap", "PoseMap",
    "PlatformMap", "ImportMapping", "load_mapping", "import_csv", "import_bag", "check_plausible",
    "max_wheel_speed", "max_yaw_rate",
]
