"""ROS 1 ``.bag`` file and ROS 2 bag directory import with ``rosbags`` (``rosbags.highlevel.AnyReader``,
no ROS install); rows are the union of all sample timestamps.  What each mapping section reads:

* ``wheels`` (-> enc_wl, enc_wr): sensor_msgs/JointState (joint velocities, averaged per side), or nav_msgs/Odometry
  (the wheel odometry a Husky or Jackal driver publishes, ``/husky_velocity_controller/odom``): its twist
  (v = twist.linear.x, omega = twist.angular.z; linear.y is ignored) becomes wheel speeds by the ideal
  differential-drive inverse ``w_l = (v - omega B / 2) / r``, ``w_r = (v + omega B / 2) / r`` with ``track`` (B) and
  ``wheel_radius`` (r) from the section, else the platform.  The driver computed that twist from the encoders with
  the same model (ros_controllers' diff_drive_controller), so this gives its encoder speeds back *if B is the
  driver's*: the controller uses ``wheel_separation * wheel_separation_multiplier``, 1.875 on a Husky
  (husky_control/config/control.yaml) and 1.5 on a Jackal, i.e. ~1.04-1.07 m on a Husky, not the 0.55 m wheel
  track of ``platform.name = "husky"``.  With the platform's track the wheel speeds' difference is 1/1.875 of the
  encoders'; give the section's ``track`` to undo what the driver did.
* ``commands`` (-> cmd_wl, cmd_wr, the commanded wheel speeds of the simulated runs): sensor_msgs/JointState, or
  geometry_msgs/Twist / TwistStamped (``cmd_vel``): the commanded v, omega by the same inverse (the driver turns
  cmd_vel into wheel speeds with the same B).  A Twist has no header: its time is the bag's receive time whatever
  ``time.source`` says (listed in ``meta["receive_time_topics"]``; with ``source = "header"`` the other topics'
  times are their header stamps, so a Twist lags them by the transport delay).
* ``imu``: sensor_msgs/Imu.
* ``gnss`` / ``reference`` / ``truth``: nav_msgs/Odometry, geometry_msgs/PoseStamped(WithCovarianceStamped), or
  sensor_msgs/NavSatFix: latitude, longitude and altitude as local ENU metres (x east, y north; WGS-84,
  :mod:`bench.formats.geodesy`) about the ``[datum]``, by default the first fix.  Fixes with a status below
  STATUS_FIX (STATUS_NO_FIX, -1) are dropped, counted in ``meta["navsat"][section]["no_fix_dropped"]`` and
  warned of.  A fix has no heading and no velocity: the yaw and velocity channels stay empty unless the section says
  ``heading = "course"`` / ``velocity = "fix_difference"`` (from the ENU track of the fixes).  The Run has no channel
  for ``position_covariance``: the median east/north standard deviation it gives goes into
  ``meta["navsat"][section]["position_std_median"]`` [m] (None when the covariance type is unknown).
"""
from __future__ import annotations

import math
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from bench.formats import geodesy
from bench.formats.channels import _check_time, _finish, _pose_channels
from bench.formats.mapping import (_ACCEL_UNITS, _GYRO_UNITS, _POS_UNITS, _POSE_PREFIX, _WHEEL_PREFIX,
                                   ImportMapping, PoseMap, WheelMap, _as_mapping, _platform, _wheel_factor)
from bench.run import Run, RunError
from bench.spec import Platform, SpecError

__all__ = ["import_bag"]


# ------------------------------------------------------------------------------------------
# Bags
# ------------------------------------------------------------------------------------------
_NAVSAT = "sensor_msgs/msg/NavSatFix"
_JOINTS = "sensor_msgs/msg/JointState"
_ODOM = "nav_msgs/msg/Odometry"
_TWIST = "geometry_msgs/msg/Twist"
_TWIST_STAMPED = "geometry_msgs/msg/TwistStamped"
_POSE_TYPES = (_ODOM, "geometry_msgs/msg/PoseStamped", "geometry_msgs/msg/PoseWithCovarianceStamped", _NAVSAT)
_WHEEL_TYPES = {"wheels": (_JOINTS, _ODOM), "commands": (_JOINTS, _TWIST, _TWIST_STAMPED)}
_NO_HEADER = (_TWIST,)
# labels of the (v, omega) of a twist topic, for error messages
_TWIST_FIELDS = {_ODOM: ("twist.twist.linear.x", "twist.twist.angular.z"), _TWIST: ("linear.x", "angular.z"),
                 _TWIST_STAMPED: ("twist.linear.x", "twist.angular.z")}
_NAVSAT_FIELDS = ("latitude", "longitude", "altitude")


def _yaw_from_quat(x: np.ndarray, y: np.ndarray, z: np.ndarray, w: np.ndarray) -> np.ndarray:
    return np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def _extract(msgtype: str, msg: Any) -> tuple[float, ...] | list[Any]:
    """Numeric payload of one message (kept lean: this runs once per message)."""
    if msgtype == "sensor_msgs/msg/Imu":
        a, g = msg.linear_acceleration, msg.angular_velocity
        return (a.x, a.y, a.z, g.x, g.y, g.z)
    if msgtype == _JOINTS:
        return [list(msg.name), np.asarray(msg.velocity, float)]
    if msgtype == _ODOM:
        p, q, v, w = msg.pose.pose.position, msg.pose.pose.orientation, msg.twist.twist.linear, msg.twist.twist.angular
        return (p.x, p.y, q.x, q.y, q.z, q.w, v.x, v.y, w.z)
    if msgtype == _TWIST:
        return (msg.linear.x, msg.angular.z)
    if msgtype == _TWIST_STAMPED:
        return (msg.twist.linear.x, msg.twist.angular.z)
    if msgtype == _NAVSAT:  # degrees as published; converted to radians with the other columns
        c = msg.position_covariance
        return (msg.latitude, msg.longitude, msg.altitude, float(msg.status.status), float(c[0]), float(c[4]),
                float(msg.position_covariance_type))
    if msgtype == "geometry_msgs/msg/PoseWithCovarianceStamped":
        p, q = msg.pose.pose.position, msg.pose.pose.orientation
        return (p.x, p.y, q.x, q.y, q.z, q.w)
    p, q = msg.pose.position, msg.pose.orientation  # PoseStamped
    return (p.x, p.y, q.x, q.y, q.z, q.w)


def _check_section_keys(mp: ImportMapping, section: str, msgtype: str, topic: str) -> None:
    """SpecError for a key the topic's message type does not use (one that would otherwise be silently ignored)."""
    file = mp.source_file or "<mapping>"
    if section in _WHEEL_PREFIX:
        wm: WheelMap = getattr(mp, section)
        if msgtype == _JOINTS:
            if not (wm.left_joints and wm.right_joints):
                raise SpecError(file, f"{section}.left_joints", list(wm.left_joints),
                                "a JointState topic needs left_joints and right_joints")
            if wm.track:
                raise SpecError(file, f"{section}.track", wm.track, f"track is for a twist topic; {topic} is a "
                                                                    "JointState (its joint velocities are the speeds)")
            return
        for key in ("left_joints", "right_joints"):
            if getattr(wm, key):
                raise SpecError(file, f"{section}.{key}", list(getattr(wm, key)),
                                f"joints are for a JointState; {topic} is a {msgtype} (its twist gives the speeds)")
        if wm.unit != "rad/s":
            raise SpecError(file, f"{section}.unit", wm.unit, f"{topic} is a {msgtype}: its twist is in m/s and "
                                                              "rad/s (REP 103); leave unit out")
        return
    if section in _POSE_PREFIX and msgtype != _NAVSAT:
        pm: PoseMap = getattr(mp, section)
        for key in ("heading", "velocity"):
            if getattr(pm, key) != "none":
                raise SpecError(file, f"{section}.{key}", getattr(pm, key),
                                f"for a sensor_msgs/NavSatFix topic; {topic} is a {msgtype}")


def _dd_inverse(v: np.ndarray, omega: np.ndarray, track: float, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """Wheel speeds [rad/s] of the ideal differential drive for body speed v [m/s] and yaw rate omega [rad/s]:
    (v -+ omega B / 2) / r (the inverse of :func:`bench.kinematics.ideal_dd`)."""
    half = 0.5 * track * omega
    return (v - half) / radius, (v + half) / radius


def _twist_geometry(wm: WheelMap, section: str, platform: Platform | None, mp: ImportMapping) -> tuple[float, float]:
    """(wheel radius, track) [m] for a twist topic: the section's, else the platform's, else a SpecError naming it."""
    r = wm.wheel_radius or (platform.wheel_radius if platform else 0.0)
    b = wm.track or (platform.track if platform else 0.0)
    for key, val in (("wheel_radius", r), ("track", b)):
        if not val > 0:
            raise SpecError(mp.source_file or "<mapping>", f"{section}.{key}", getattr(wm, key),
                            "a twist topic (Odometry, Twist) needs the wheel radius and track to give wheel speeds "
                            "(here or via platform.name)")
    return float(r), float(b)


def import_bag(bag_path: str | Path, mapping: ImportMapping | str | Path, *, check: bool = True) -> Run:
    """Import a ROS 1 ``.bag`` file or a ROS 2 bag directory (see the module docstring)."""
    from rosbags.highlevel import AnyReader

    path = Path(bag_path)
    mp = _as_mapping(mapping)
    platform = _platform(mp)
    file = mp.source_file or "<mapping>"
    given_datum = geodesy.mapping_datum(mp.datum, file)
    if not path.exists():
        raise RunError(str(path), "<file>", str(path), "file not found")
    where = str(path)
    sections: dict[str, tuple[str, tuple[str, ...]]] = {}
    for s in ("wheels", "commands"):
        wm: WheelMap = getattr(mp, s)
        if wm.topic:
            sections[s] = (wm.topic, _WHEEL_TYPES[s])
    if mp.imu.topic:
        sections["imu"] = (mp.imu.topic, ("sensor_msgs/msg/Imu",))
    for s in _POSE_PREFIX:
        pm: PoseMap = getattr(mp, s)
        if pm.topic:
            sections[s] = (pm.topic, _POSE_TYPES)
        if pm.velocity != "none" and s != "gnss":
            raise SpecError(file, f"{s}.velocity", pm.velocity, "a velocity from the fixes is for [gnss] "
                                                                "(the world-frame gnss_vx, gnss_vy)")
    if not sections:
        raise RunError(where, "<mapping>", file, "the mapping names no topic to import")

    data: dict[str, tuple[list[int], list[Any]]] = {s: ([], []) for s in sections}
    kind: dict[str, str] = {}  # section -> the message type of its topic
    try:
        reader = AnyReader([path])
        reader.open()
    except Exception as exc:  # rosbags raises several reader/storage errors: one message for all
        raise RunError(where, "<file>", f"{type(exc).__name__}: {exc}", "not a readable ROS 1/ROS 2 bag") from None
    try:
        conns = {c.topic: c for c in reader.connections}
        topic_of: dict[str, list[str]] = {}
        for s, (topic, types) in sections.items():
            if topic not in conns:
                raise RunError(where, topic, None, f"topic named by mapping {s}.topic is not in the bag; "
                                                   f"topics: {sorted(conns)}")
            if conns[topic].msgtype not in types:
                raise RunError(where, topic, conns[topic].msgtype, f"mapping {s} expects a message of type "
                                                                   f"{' or '.join(types)}")
            topic_of.setdefault(topic, []).append(s)
            kind[s] = conns[topic].msgtype
            _check_section_keys(mp, s, kind[s], topic)
        use_header = mp.time.source == "header"
        wanted = [conns[t] for t in topic_of]
        try:
            for con, stamp, rawdata in reader.messages(connections=wanted):
                msg = reader.deserialize(rawdata, con.msgtype)
                if use_header and con.msgtype not in _NO_HEADER:
                    st = msg.header.stamp
                    stamp = int(st.sec) * 1_000_000_000 + int(st.nanosec)
                payload = _extract(con.msgtype, msg)
                for s in topic_of[con.topic]:
                    data[s][0].append(stamp)
                    data[s][1].append(payload)
        except RunError:
            raise
        except Exception as exc:
            raise RunError(where, "<file>", f"{type(exc).__name__}: {exc}",
                           "a readable bag (truncated or corrupt message data)") from None
    finally:
        reader.close()

    navsat: dict[str, dict[str, Any]] = {}
    for s in [s for s in data if kind[s] == _NAVSAT]:  # below STATUS_FIX (STATUS_NO_FIX, -1): no position
        n_all = len(data[s][1])
        keep = [i for i, p in enumerate(data[s][1]) if p[3] >= geodesy.STATUS_FIX]
        navsat[s] = {"topic": sections[s][0], "fixes": len(keep), "no_fix_dropped": n_all - len(keep)}
        if n_all and not keep:
            raise RunError(where, f"{sections[s][0]} status.status", f"{n_all} messages, all {geodesy.STATUS_NO_FIX}",
                           "every NavSatFix has status STATUS_NO_FIX (-1): the receiver never had a fix")
        if n_all > len(keep):
            warnings.warn(f"{where}: {sections[s][0]}: {n_all - len(keep)} of {n_all} NavSatFix messages with status "
                          "STATUS_NO_FIX (-1) dropped", RuntimeWarning, stacklevel=2)
        data[s] = ([data[s][0][i] for i in keep], [data[s][1][i] for i in keep])
    empty = [sections[s][0] for s, (st, _) in data.items() if not st]
    if empty:
        raise RunError(where, empty[0], "0 messages", "the topic named by the mapping has no message (empty run)")
    stamps = {s: np.asarray(st, np.int64) for s, (st, _) in data.items()}
    for s, st in stamps.items():
        _check_time(where, sections[s][0], st.astype(float) * 1e-9, label="message", base=0)
    t0 = min(int(st[0]) for st in stamps.values())
    grid = np.unique(np.concatenate(list(stamps.values())))
    tt = (grid - t0).astype(float) * 1e-9
    n = grid.size
    cols: dict[str, np.ndarray] = {"t": tt}
    hints: dict[str, str] = {}
    extra: dict[str, Any] = {}
    receive_timed = sorted({sections[s][0] for s in data if kind[s] in _NO_HEADER}) if mp.time.source == "header" \
        else []
    if receive_timed:
        extra["receive_time_topics"] = receive_timed

    def place(s: str, values: np.ndarray) -> np.ndarray:
        out = np.full(n, np.nan)
        out[np.searchsorted(grid, stamps[s])] = values
        return out

    def finite(s: str, labels: tuple[str, ...], v: np.ndarray) -> np.ndarray:
        bad = ~np.isfinite(v)
        if bad.any():
            if mp.nan_policy == "drop":
                return np.where(bad, np.nan, v)
            i, k = (int(a) for a in np.argwhere(bad)[0])
            raise RunError(where, f"{sections[s][0]} {labels[k]}", f"message {i}: {v[i, k]}",
                           "NaN/inf in a message field (set nan_policy = \"drop\" to treat it as no sample)")
        return v

    for s, prefix in _WHEEL_PREFIX.items():
        if s not in data:
            continue
        wm = getattr(mp, s)
        if kind[s] != _JOINTS:  # a twist (Odometry, Twist, TwistStamped): v, omega -> wheel speeds
            arr = np.asarray(data[s][1], float)
            v, w = (arr[:, 6], arr[:, 8]) if kind[s] == _ODOM else (arr[:, 0], arr[:, 1])
            vw = finite(s, _TWIST_FIELDS[kind[s]], np.column_stack([v, w]))
            r, b = _twist_geometry(wm, s, platform, mp)
            wl, wr = _dd_inverse(vw[:, 0], vw[:, 1], b, r)
            cols[f"{prefix}_wl"] = place(s, wl * (-1.0 if wm.invert_left else 1.0))
            cols[f"{prefix}_wr"] = place(s, wr * (-1.0 if wm.invert_right else 1.0))
            for ch in ("wl", "wr"):
                hints[f"{prefix}_{ch}"] = f"topic {wm.topic} ({kind[s]} twist, r = {r} m, B = {b} m)"
            extra[f"{s}_twist_geometry"] = {"wheel_radius": r, "track": b}
            continue
        names_seen = data[s][1][0][0]
        changed = [i for i, p in enumerate(data[s][1]) if p[0] != names_seen]
        if changed:
            raise RunError(where, f"{wm.topic} name", data[s][1][changed[0]][0],
                           f"message {changed[0]}: every JointState must list the joints {names_seen} in one order")
        vel = np.full((len(data[s][1]), 2), np.nan)
        for side, joints in ((0, wm.left_joints), (1, wm.right_joints)):
            missing = [j for j in joints if j not in names_seen]
            if missing:
                raise RunError(where, f"{wm.topic} name", names_seen, f"joints {missing} named by mapping {s} "
                                                                       "are missing from the JointState")
        idx_l = [names_seen.index(j) for j in wm.left_joints]
        idx_r = [names_seen.index(j) for j in wm.right_joints]
        try:
            arr = np.stack([p[1] for p in data[s][1]])
        except ValueError:
            raise RunError(where, f"{wm.topic} velocity", "ragged", "every JointState with the same joints") from None
        if arr.ndim != 2 or arr.shape[1] != len(names_seen):
            raise RunError(where, f"{wm.topic} velocity", f"{arr.shape[1] if arr.ndim == 2 else 0} values",
                           f"one velocity per joint ({len(names_seen)})")
        vel[:, 0], vel[:, 1] = arr[:, idx_l].mean(axis=1), arr[:, idx_r].mean(axis=1)
        vel = finite(s, ("velocity (left joints)", "velocity (right joints)"), vel)
        k = _wheel_factor(wm, s, platform, mp)
        cols[f"{prefix}_wl"] = place(s, vel[:, 0] * k * (-1.0 if wm.invert_left else 1.0))
        cols[f"{prefix}_wr"] = place(s, vel[:, 1] * k * (-1.0 if wm.invert_right else 1.0))
        for ch in ("wl", "wr"):
            hints[f"{prefix}_{ch}"] = f"topic {wm.topic}, mapping {s}.unit = '{wm.unit}'"
    if "imu" in data:
        arr = finite("imu", tuple(f"{a}.{c}" for a in ("linear_acceleration", "angular_velocity") for c in "xyz"),
                     np.asarray(data["imu"][1], float))
        ka, kg = _ACCEL_UNITS[mp.imu.accel_unit], _GYRO_UNITS[mp.imu.gyro_unit]
        for k, key in enumerate(("ax", "ay", "az", "gx", "gy", "gz")):
            cols[f"imu_{key}"] = place("imu", arr[:, k] * (ka if k < 3 else kg))
            hints[f"imu_{key}"] = (f"topic {mp.imu.topic}, mapping imu."
                                   f"{'accel_unit' if k < 3 else 'gyro_unit'} = "
                                   f"'{mp.imu.accel_unit if k < 3 else mp.imu.gyro_unit}'")

    fixes: dict[str, np.ndarray] = {}  # NavSatFix sections: (lat [rad], lon [rad], alt [m]) per fix
    for s in navsat:
        arr = np.asarray(data[s][1], float)
        latlon = finite(s, _NAVSAT_FIELDS[:2], arr[:, :2])
        alt = arr[:, 2].copy()  # NaN is allowed: the message's "no altitude" (the datum's is used)
        inf = np.flatnonzero(np.isinf(alt))
        if inf.size and mp.nan_policy != "drop":
            i = int(inf[0])
            raise RunError(where, f"{sections[s][0]} altitude", f"message {i}: {alt[i]}",
                           "a finite altitude, or NaN for none (set nan_policy = \"drop\" to treat it as none)")
        alt[inf] = np.nan
        fixes[s] = np.column_stack([np.radians(latlon[:, 0]), np.radians(latlon[:, 1]), alt])
        geodesy.check_fix_range(where, sections[s][0], fixes[s][:, 0], fixes[s][:, 1])
        var = arr[arr[:, 6] != geodesy.COVARIANCE_TYPE_UNKNOWN][:, 4:6]  # east, north variances [m^2]
        var = var[np.isfinite(var).all(axis=1) & (var >= 0).all(axis=1)]
        navsat[s]["position_std_median"] = [math.sqrt(float(v)) for v in np.median(var, axis=0)] if var.size else None
    if navsat:
        firsts = []
        for s, f in fixes.items():
            ok = np.flatnonzero(np.isfinite(f[:, 0]) & np.isfinite(f[:, 1]))
            if ok.size == 0:
                raise RunError(where, f"{sections[s][0]} latitude", "NaN in every fix",
                               "at least one fix with a latitude and longitude")
            i = int(ok[0])
            firsts.append((int(stamps[s][i]), sections[s][0], float(f[i, 0]), float(f[i, 1]), float(f[i, 2])))
        datum = geodesy.choose_datum(given_datum, firsts)
        extra["enu_datum"] = datum.as_meta()
        extra["navsat"] = navsat

    for s, prefix in _POSE_PREFIX.items():
        if s not in data:
            continue
        pm = getattr(mp, s)
        if kind[s] == _NAVSAT:
            f = fixes[s]
            east, north = geodesy.geodetic_to_enu(f[:, 0], f[:, 1], f[:, 2], datum)
            geodesy.check_near_datum(where, sections[s][0], east, north, datum)
            ve, vn = geodesy.track_velocity((stamps[s] - t0).astype(float) * 1e-9, east, north)
            yaw = geodesy.course(ve, vn, pm.course_min_speed) if pm.heading == "course" else None
            vel = (ve, vn) if pm.velocity == "fix_difference" else (None, None)
            ch = _pose_channels(prefix, east, north, yaw, *vel, None, "world")
            cols.update({k: place(s, v) for k, v in ch.items()})
            continue
        arr = np.asarray(data[s][1], float)
        arr = finite(s, ("pose.position.x", "pose.position.y", "pose.orientation.x", "pose.orientation.y",
                         "pose.orientation.z", "pose.orientation.w", "twist.linear.x", "twist.linear.y",
                         "twist.angular.z")[: arr.shape[1]], arr)
        yaw = _yaw_from_quat(arr[:, 2], arr[:, 3], arr[:, 4], arr[:, 5])
        vx = vy = wz = None
        if arr.shape[1] == 9:  # Odometry: twist in the child (body) frame
            vx, vy, wz = arr[:, 6], arr[:, 7], arr[:, 8]
        kp = _POS_UNITS[pm.position_unit]
        if vx is not None:
            vx, vy = vx * kp, vy * kp
        ch = _pose_channels(prefix, arr[:, 0] * kp, arr[:, 1] * kp, yaw, vx, vy, wz, "body")
        cols.update({k: place(s, v) for k, v in ch.items()})
    return _finish(cols, path, mp, platform, hints, check,
                   {"time_origin_ns": t0, "time_source": mp.time.source, **extra})
