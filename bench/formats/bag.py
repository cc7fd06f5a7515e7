"""ROS 1 ``.bag`` file and ROS 2 bag directory import with ``rosbags`` (``rosbags.highlevel.AnyReader``,
no ROS install); rows are the union of all sample timestamps.  What each mapping section reads:

* ``wheels``: sensor_msgs/JointState (joint velocities), or nav_msgs/Odometry (the wheel odometry a Husky or Jackal
  driver publishes, ``/husky_velocity_controller/odom``): its twist (v = linear.x, omega = angular.z) becomes wheel
  speeds by the ideal differential-drive inverse ``w_l = (v - omega B / 2) / r``, ``w_r = (v + omega B / 2) / r`` (the
  driver computed that twist from the encoders with the same model, so this gives its encoder speeds back), with
  ``track`` / ``wheel_radius`` from the section or the platform.
* ``commands``: sensor_msgs/JointState, or geometry_msgs/Twist / TwistStamped (``cmd_vel``): the commanded v, omega
  as commanded wheel speeds by the same inverse.  A Twist has no header: its time is the bag's receive time whatever
  ``time.source`` says.
* ``imu``: sensor_msgs/Imu.
* ``gnss`` / ``reference`` / ``truth``: nav_msgs/Odometry, geometry_msgs/PoseStamped(WithCovarianceStamped), or
  sensor_msgs/NavSatFix: latitude, longitude and altitude converted to local ENU metres (x east, y north;
  ``pymap3d.geodetic2enu`` on WGS-84) about the section's ``datum_lat`` / ``datum_lon`` / ``datum_alt`` [deg, deg, m],
  by default the first fix; fixes with status STATUS_NO_FIX (-1) are dropped and counted in the run's metadata
  (``navsat_no_fix``).  A fix has no heading, so the section's yaw channel stays empty.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from bench.formats.channels import _check_time, _finish, _pose_channels
from bench.formats.mapping import (_ACCEL_UNITS, _GYRO_UNITS, _POS_UNITS, _POSE_PREFIX, _WHEEL_PREFIX,
                                   ImportMapping, PoseMap, WheelMap, _as_mapping, _platform, _wheel_factor)
from bench.run import Run, RunError
from bench.spec import SpecError

__all__ = ["import_bag"]


# ------------------------------------------------------------------------------------------
# Bags
# ------------------------------------------------------------------------------------------
_NAVSAT = "sensor_msgs/msg/NavSatFix"
_POSE_TYPES = ("nav_msgs/msg/Odometry", "geometry_msgs/msg/PoseStamped",
               "geometry_msgs/msg/PoseWithCovarianceStamped", _NAVSAT)
_JOINTS = "sensor_msgs/msg/JointState"
_ODOM = "nav_msgs/msg/Odometry"
_TWISTS = ("geometry_msgs/msg/Twist", "geometry_msgs/msg/TwistStamped")
_WHEEL_TYPES = {"wheels": (_JOINTS, _ODOM), "commands": (_JOINTS, *_TWISTS)}
_NO_HEADER = ("geometry_msgs/msg/Twist",)


def _yaw_from_quat(x: np.ndarray, y: np.ndarray, z: np.ndarray, w: np.ndarray) -> np.ndarray:
    return np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def _extract(msgtype: str, msg: Any) -> tuple[float, ...] | list[Any]:
    """Numeric payload of one message (kept lean: this runs once per message)."""
    if msgtype == "sensor_msgs/msg/Imu":
        a, g = msg.linear_acceleration, msg.angular_velocity
        return (a.x, a.y, a.z, g.x, g.y, g.z)
    if msgtype == "sensor_msgs/msg/JointState":
        return [list(msg.name), np.asarray(msg.velocity, float)]
    if msgtype == "nav_msgs/msg/Odometry":
        p, q, v, w = msg.pose.pose.position, msg.pose.pose.orientation, msg.twist.twist.linear, msg.twist.twist.angular
        return (p.x, p.y, q.x, q.y, q.z, q.w, v.x, v.y, w.z)
    if msgtype == "geometry_msgs/msg/Twist":
        return (msg.linear.x, msg.angular.z)
    if msgtype == "geometry_msgs/msg/TwistStamped":
        return (msg.twist.linear.x, msg.twist.angular.z)
    if msgtype == _NAVSAT:
        return (msg.latitude, msg.longitude, msg.altitude, float(msg.status.status))
    if msgtype == "geometry_msgs/msg/PoseWithCovarianceStamped":
        p, q = msg.pose.pose.position, msg.pose.pose.orientation
        return (p.x, p.y, q.x, q.y, q.z, q.w)
    p, q = msg.pose.position, msg.pose.orientation  # PoseStamped
    return (p.x, p.y, q.x, q.y, q.z, q.w)


def import_bag(bag_path: str | Path, mapping: ImportMapping | str | Path, *, check: bool = True) -> Run:
    """Import a ROS 1 ``.bag`` file or a ROS 2 bag directory (see the module docstring)."""
    from rosbags.highlevel import AnyReader

    path = Path(bag_path)
    mp = _as_mapping(mapping)
    platform = _platform(mp)
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
    if not sections:
        raise RunError(where, "<mapping>", mp.source_file or "<mapping>", "the mapping names no topic to import")

    data: dict[str, tuple[list[int], list[Any]]] = {s: ([], []) for s in sections}
    kind: dict[str, str] = {}  # section -> the message type of its topic
    try:
        reader = AnyReader([path])
        reader.open()
    except Exception as exc:  # rosbags raises several reader/storage errors: one message for all
        raise RunError(where, "<file>", f"{type(exc).__name__}: {exc}", "not a readable ROS 1/ROS 2 bag") from None
    try:
        conns = {c.topic: c for c in reader.connections}
        topic_of = {}
        for s, (topic, types) in sections.items():
            if topic not in conns:
                raise RunError(where, topic, None, f"topic named by mapping {s}.topic is not in the bag; "
                                                   f"topics: {sorted(conns)}")
            if conns[topic].msgtype not in types:
                raise RunError(where, topic, conns[topic].msgtype, f"mapping {s} expects a message of type "
                                                                   f"{' or '.join(types)}")
            topic_of.setdefault(topic, []).append(s)
            kind[s] = conns[topic].msgtype
            if kind[s] == _JOINTS and s in _WHEEL_PREFIX:
                wm = getattr(mp, s)
                if not (wm.left_joints and wm.right_joints):
                    raise SpecError(mp.source_file or "<mapping>", f"{s}.left_joints", list(wm.left_joints),
                                    "a JointState topic needs left_joints and right_joints")
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

    no_fix: dict[str, int] = {}
    for s in [s for s in data if kind.get(s) == _NAVSAT]:  # STATUS_NO_FIX (-1): no position, dropped
        keep = [i for i, p in enumerate(data[s][1]) if p[3] >= 0]
        no_fix[s] = len(data[s][1]) - len(keep)
        if not keep and data[s][1]:
            raise RunError(where, sections[s][0], f"{no_fix[s]} messages", "every NavSatFix has status STATUS_NO_FIX "
                           "(-1): the receiver never had a fix")
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
        if kind[s] != _JOINTS:  # a twist (Odometry, Twist): v, omega -> wheel speeds
            arr = np.asarray(data[s][1], float)
            v, w = (arr[:, 6], arr[:, 8]) if kind[s] == _ODOM else (arr[:, 0], arr[:, 1])
            vw = finite(s, ("twist.linear.x", "twist.angular.z"), np.column_stack([v, w]))
            r, b = _twist_geometry(wm, s, platform, mp)
            cols[f"{prefix}_wl"] = place(s, (vw[:, 0] - 0.5 * b * vw[:, 1]) / r * (-1.0 if wm.invert_left else 1.0))
            cols[f"{prefix}_wr"] = place(s, (vw[:, 0] + 0.5 * b * vw[:, 1]) / r * (-1.0 if wm.invert_right else 1.0))
            for ch in ("wl", "wr"):
                hints[f"{prefix}_{ch}"] = f"topic {wm.topic} ({kind[s]} twist, r = {r} m, B = {b} m)"
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
    for s, prefix in _POSE_PREFIX.items():
        if s not in data:
            continue
        pm = getattr(mp, s)
        arr = np.asarray(data[s][1], float)
        if kind[s] == _NAVSAT:
            arr = finite(s, ("latitude", "longitude", "altitude", "status.status"), arr)
            east, north, datum = _enu(arr, pm, mp, s)
            cols.update({k: place(s, v) for k, v in _pose_channels(prefix, east, north, None, None, None, None,
                                                                     "body").items()})
            extra[f"{s}_datum_deg_deg_m"] = list(datum)
            extra[f"navsat_no_fix_{s}"] = no_fix[s]
            continue
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


def _twist_geometry(wm: WheelMap, section: str, platform: Any, mp: ImportMapping) -> tuple[float, float]:
    """(wheel radius, track) [m] for a twist topic: the section's, else the platform's, else a SpecError naming it."""
    r = wm.wheel_radius or (platform.wheel_radius if platform else 0.0)
    b = wm.track or (platform.track if platform else 0.0)
    for key, val in (("wheel_radius", r), ("track", b)):
        if val <= 0:
            raise SpecError(mp.source_file or "<mapping>", f"{section}.{key}", getattr(wm, key),
                            "a twist topic (Odometry, Twist) needs the wheel radius and track to give wheel speeds "
                            "(here or via platform.name)")
    return float(r), float(b)


def _enu(arr: np.ndarray, pm: PoseMap, mp: ImportMapping, section: str) -> tuple[np.ndarray, np.ndarray, tuple]:
    """East and north [m] of the fixes (rows lat, lon, alt [deg, deg, m], status) about the section's datum (default
    the first fix), by pymap3d's WGS-84 geodetic -> ENU."""
    import math

    import pymap3d

    lat, lon, alt = arr[:, 0], arr[:, 1], arr[:, 2]
    for name, v, lim in (("latitude", lat, 90.0), ("longitude", lon, 180.0)):
        bad = np.flatnonzero(np.abs(v) > lim)
        if bad.size:
            raise RunError(mp.source_file or "<mapping>", f"{pm.topic} {name}", f"message {bad[0]}: {v[bad[0]]}",
                           f"a {name} in [-{lim:g}, {lim:g}] deg")
    datum = tuple(float(d) if not math.isnan(d) else float(first)
                  for d, first in ((pm.datum_lat, lat[0]), (pm.datum_lon, lon[0]), (pm.datum_alt, alt[0])))
    e, n, _ = pymap3d.geodetic2enu(lat, lon, alt, *datum)
    return np.asarray(e, float), np.asarray(n, float), datum
