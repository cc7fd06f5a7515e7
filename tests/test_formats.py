"""TUM export/import, CSV and ROS 1/ROS 2 bag import (bench.formats).

Bags and CSVs are written here, in the test, from known arrays (rosbags' own writers), and the
imported Run is checked against what was written, converted to SI by hand.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from bench.formats import (ImportMapping, import_bag, import_csv, load_mapping, read_tum,
                           run_to_tum, write_tum)
from bench.kinematics import integrate_se2
from bench.registry import make_estimate
from bench.run import Run, RunError, from_arrays
from bench.spec import SpecError, load_platform

# ------------------------------------------------------------------------------------------
# helpers shared with tests/test_bad_input.py
# ------------------------------------------------------------------------------------------
JOINTS = ["front_left_wheel", "rear_left_wheel", "front_right_wheel", "rear_right_wheel"]


def _typestore(ros: int):
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS1_NOETIC if ros == 1 else Stores.ROS2_HUMBLE)


def ros_header(ts: Any, ros: int, t: float) -> Any:
    """A std_msgs/Header stamped ``t`` [s] in frame base_link (ROS 1 headers also carry seq)."""
    T = ts.types
    ns = int(round(t * 1e9))
    kw = dict(stamp=T["builtin_interfaces/msg/Time"](sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000),
              frame_id="base_link")
    if ros == 1:
        kw["seq"] = 0
    return T["std_msgs/msg/Header"](**kw)


def write_bag(path: Path, ros: int, topics: dict[str, tuple[str, list[tuple[float, dict[str, Any]]]]],
              receive_offset: float = 0.0, receive_in_list_order: bool = False) -> Path:
    """Write a bag: ``topics[topic] = (kind, [(stamp_s, fields), ...])`` with kind in
    imu / joints / odom / pose.  The bag (receive) time is the header stamp +
    ``receive_offset``, or, with ``receive_in_list_order``, 1 ms per list position (so that
    out-of-order header stamps can be written)."""
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.rosbag2 import Writer as Writer2

    ts = _typestore(ros)
    T = ts.types
    Vec, Quat, Point = T["geometry_msgs/msg/Vector3"], T["geometry_msgs/msg/Quaternion"], T["geometry_msgs/msg/Point"]
    Pose, PoseCov = T["geometry_msgs/msg/Pose"], T["geometry_msgs/msg/PoseWithCovariance"]
    Twist, TwistCov = T["geometry_msgs/msg/Twist"], T["geometry_msgs/msg/TwistWithCovariance"]
    types = {"imu": "sensor_msgs/msg/Imu", "joints": "sensor_msgs/msg/JointState",
             "odom": "nav_msgs/msg/Odometry", "pose": "geometry_msgs/msg/PoseStamped"}

    def header(t: float) -> Any:
        return ros_header(ts, ros, t)

    def quat(yaw: float) -> Any:
        return Quat(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))

    def make(kind: str, t: float, f: dict[str, Any]) -> Any:
        if kind == "imu":
            return T[types[kind]](header=header(t), orientation=quat(0.0), orientation_covariance=np.zeros(9),
                                  angular_velocity=Vec(x=f["gx"], y=f["gy"], z=f["gz"]),
                                  angular_velocity_covariance=np.zeros(9),
                                  linear_acceleration=Vec(x=f["ax"], y=f["ay"], z=f["az"]),
                                  linear_acceleration_covariance=np.zeros(9))
        if kind == "joints":
            return T[types[kind]](header=header(t), name=list(f.get("name", JOINTS)),
                                  position=np.zeros(len(f["velocity"])),
                                  velocity=np.asarray(f["velocity"], float), effort=np.zeros(0))
        pose = Pose(position=Point(x=f["x"], y=f["y"], z=0.0), orientation=quat(f["yaw"]))
        if kind == "pose":
            return T[types[kind]](header=header(t), pose=pose)
        twist = Twist(linear=Vec(x=f["vx"], y=f["vy"], z=0.0), angular=Vec(x=0.0, y=0.0, z=f["wz"]))
        return T[types[kind]](header=header(t), child_frame_id="base_link",
                              pose=PoseCov(pose=pose, covariance=np.zeros(36)),
                              twist=TwistCov(twist=twist, covariance=np.zeros(36)))

    writer = Writer1(path) if ros == 1 else Writer2(path, version=9)
    with writer:
        conns = {tp: writer.add_connection(tp, types[kind], typestore=ts) for tp, (kind, _) in topics.items()}
        msgs = [(1e9 + 1e-3 * i + 1e-5 * j if receive_in_list_order else t + receive_offset, t, tp, kind, f)
                for j, (tp, (kind, rows)) in enumerate(topics.items()) for i, (t, f) in enumerate(rows)]
        msgs.sort(key=lambda m: m[0])
        for rec, t, tp, kind, f in msgs:
            m = make(kind, t, f)
            raw = ts.serialize_ros1(m, types[kind]) if ros == 1 else ts.serialize_cdr(m, types[kind])
            writer.write(conns[tp], int(round(rec * 1e9)), raw)
    return path


def sample_signals(seed: int = 0) -> dict[str, Any]:
    """Known signals: wheel speeds (rad/s) at 50 Hz, IMU at 100 Hz, odometry at 10 Hz, pose at 20 Hz."""
    rng = np.random.default_rng(seed)
    t0 = 1_700_000_000.0
    tw = t0 + np.arange(50) * 0.02
    wl = 2.0 + 0.5 * np.sin(np.arange(50) / 7.0)
    wr = 3.0 + 0.5 * np.cos(np.arange(50) / 5.0)
    ti = t0 + 0.001 + np.arange(100) * 0.01
    imu = rng.normal(0, 0.3, (100, 6)) + np.array([0, 0, 9.81, 0, 0, 0])
    to = t0 + 0.003 + np.arange(10) * 0.1
    odom = np.column_stack([np.linspace(0, 1, 10), np.linspace(0, 0.5, 10), np.linspace(-3.0, 3.0, 10),
                            rng.normal(0.5, 0.05, 10), rng.normal(0.0, 0.05, 10), rng.normal(0.2, 0.05, 10)])
    tp = t0 + 0.005 + np.arange(20) * 0.05
    pose = np.column_stack([np.linspace(0, 1, 20), np.linspace(0, -1, 20), np.linspace(0.1, 1.2, 20)])
    return dict(t0=t0, tw=tw, wl=wl, wr=wr, ti=ti, imu=imu, to=to, odom=odom, tp=tp, pose=pose)


def bag_topics(sig: dict[str, Any], wheel_scale: float = 1.0) -> dict[str, Any]:
    # the two joints of a side differ by +-0.1 so that averaging is checked; right joints inverted
    joints = [(t, {"velocity": [(l + 0.1) * wheel_scale, (l - 0.1) * wheel_scale,
                                -(r + 0.1) * wheel_scale, -(r - 0.1) * wheel_scale]})
              for t, l, r in zip(sig["tw"], sig["wl"], sig["wr"])]
    imu = [(t, dict(zip(("ax", "ay", "az", "gx", "gy", "gz"), row))) for t, row in zip(sig["ti"], sig["imu"])]
    odom = [(t, dict(zip(("x", "y", "yaw", "vx", "vy", "wz"), row))) for t, row in zip(sig["to"], sig["odom"])]
    pose = [(t, dict(zip(("x", "y", "yaw"), row))) for t, row in zip(sig["tp"], sig["pose"])]
    return {"/joint_states": ("joints", joints), "/imu/data": ("imu", imu),
            "/gnss/odom": ("odom", odom), "/vicon/pose": ("pose", pose)}


BAG_MAPPING = """
run_id = "bagtest"
[platform]
name = "p3at_pneumatic_20psi"
[wheels]
topic = "/joint_states"
left_joints = ["front_left_wheel", "rear_left_wheel"]
right_joints = ["front_right_wheel", "rear_right_wheel"]
invert_right = true
unit = "rad/s"
[imu]
topic = "/imu/data"
[gnss]
topic = "/gnss/odom"
[reference]
topic = "/vicon/pose"
"""


def write_mapping(tmp_path: Path, text: str, name: str = "mapping.toml") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


# ------------------------------------------------------------------------------------------
# TUM
# ------------------------------------------------------------------------------------------
def test_tum_round_trip_is_exact(tmp_path: Path) -> None:
    rng = np.random.default_rng(3)
    t = np.cumsum(rng.uniform(0.005, 0.02, 200)) + 1e9 / 7
    x, y, z = rng.normal(0, 100, (3, 200))
    yaw = rng.uniform(-np.pi, np.pi, 200)
    p = write_tum(tmp_path / "a.tum", t, x, y, yaw, z)
    tr = read_tum(p)
    assert np.array_equal(tr.t, t) and np.array_equal(tr.x, x) and np.array_equal(tr.y, y)
    assert np.array_equal(tr.xyz[:, 2], z)
    assert np.max(np.abs(np.angle(np.exp(1j * (tr.yaw - yaw))))) < 1e-14


def test_tum_file_is_read_identically_by_evo(tmp_path: Path) -> None:
    from evo.tools import file_interface

    rng = np.random.default_rng(4)
    t = np.arange(50) * 0.1
    x, y, yaw = rng.normal(0, 3, (3, 50))
    p = write_tum(tmp_path / "b.tum", t, x, y, yaw)
    ev = file_interface.read_tum_trajectory_file(str(p))
    assert np.array_equal(ev.timestamps, t)
    assert np.array_equal(ev.positions_xyz[:, 0], x) and np.array_equal(ev.positions_xyz[:, 1], y)
    R = np.array(ev.poses_se3)[:, :3, :3]
    assert np.allclose(np.arctan2(R[:, 1, 0], R[:, 0, 0]), np.angle(np.exp(1j * yaw)), atol=1e-14)


def test_run_to_tum_sources(tmp_path: Path) -> None:
    t = np.arange(10) * 0.1
    ref_x = np.where(np.arange(10) % 2 == 0, t, np.nan)  # reference sampled every other tick
    run = from_arrays({"t": t, "truth_x": t * 2, "truth_y": -t, "truth_yaw": t / 3,
                       "ref_x": ref_x, "ref_y": np.where(np.isfinite(ref_x), 1.0, np.nan),
                       "ref_yaw": np.where(np.isfinite(ref_x), 0.5, np.nan)}, {"run_id": "r"})
    tr = read_tum(run_to_tum(run, "truth", tmp_path / "truth.tum"))
    assert np.array_equal(tr.x, t * 2) and np.allclose(tr.yaw, t / 3, atol=1e-15)
    text = run_to_tum(run, "ref")
    rows = [r for r in text.splitlines() if not r.startswith("#")]
    assert len(rows) == 5 and rows[1].split()[0] == repr(0.2)
    est = make_estimate("m", t=t, x=t + 1, y=t, yaw=np.zeros(10))
    tr = read_tum(run_to_tum(run, est, tmp_path / "est.tum"))
    assert np.array_equal(tr.x, t + 1)


def test_tum_export_has_the_full_attitude_and_one_z_frame(tmp_path: Path) -> None:
    """The truth's roll and pitch are in its quaternion (ZYX Euler as the testbed logs them), z is the height change
    since the first pose for truth and estimate alike, so evo's unaligned APE between a planar estimate that is
    right in x, y and the truth is the planar error (0 here), not the body origin's height."""
    from evo.core import metrics, sync
    from evo.tools import file_interface
    from scipy.spatial.transform import Rotation

    n = 50
    t = np.arange(n) * 0.1
    yaw, pitch, roll = 0.3 * t, 0.2 * np.sin(t), -0.1 * np.cos(t)
    run = from_arrays({"t": t, "truth_x": t, "truth_y": t ** 2, "truth_z": 0.085 + 0.01 * t, "truth_yaw": yaw,
                       "truth_pitch": pitch, "truth_roll": roll}, {"run_id": "r"})
    tr = read_tum(run_to_tum(run, "truth", tmp_path / "truth.tum"))
    want = Rotation.from_euler("ZYX", np.column_stack([yaw, pitch, roll])).as_matrix()
    assert np.allclose(tr.rot, want, atol=1e-12) and np.allclose(tr.xyz[:, 2], 0.01 * t, atol=1e-15)
    est = make_estimate("m", t=t, x=t, y=t ** 2, yaw=yaw)  # planar: no z, roll, pitch columns
    run_to_tum(run, est, tmp_path / "est.tum")
    ref = file_interface.read_tum_trajectory_file(str(tmp_path / "truth.tum"))
    ev = file_interface.read_tum_trajectory_file(str(tmp_path / "est.tum"))
    ref, ev = sync.associate_trajectories(ref, ev)
    ape = metrics.APE(metrics.PoseRelation.translation_part)
    ape.process_data((ref, ev))
    assert ape.get_statistic(metrics.StatisticsType.max) == pytest.approx(0.049, abs=1e-9)  # the truth's 0.01 t climb
    flat = from_arrays({"t": t, "truth_x": t, "truth_y": t ** 2, "truth_z": np.full(n, 0.085), "truth_yaw": yaw},
                       {"run_id": "f"})
    run_to_tum(flat, "truth", tmp_path / "flat.tum")
    ref = file_interface.read_tum_trajectory_file(str(tmp_path / "flat.tum"))
    ref, ev = sync.associate_trajectories(ref, file_interface.read_tum_trajectory_file(str(tmp_path / "est.tum")))
    ape.process_data((ref, ev))
    assert ape.get_statistic(metrics.StatisticsType.max) == pytest.approx(0.0, abs=1e-12)


def test_tum_export_without_a_finite_pose_names_the_channels(tmp_path: Path) -> None:
    run = from_arrays({"t": np.arange(3.0), "truth_x": np.full(3, np.nan), "truth_y": np.zeros(3),
                       "truth_yaw": np.zeros(3)}, {"run_id": "r"})
    with pytest.raises(RunError, match="truth_x/truth_y/truth_yaw.*no finite pose"):
        run_to_tum(run, "truth", tmp_path / "x.tum")
    assert not (tmp_path / "x.tum").exists()


# ------------------------------------------------------------------------------------------
# CSV
# ------------------------------------------------------------------------------------------
CSV_MAPPING = """
run_id = "csvtest"
[time]
column = "stamp_ms"
unit = "ms"
[platform]
name = "p3at_pneumatic_20psi"
[wheels]
left = "wl_rpm"
right = "wr_rpm"
unit = "rpm"
[commands]
left = "cmd_l"
right = "cmd_r"
unit = "m/s"
[imu]
ax = "acc_x"
ay = "acc_y"
az = "acc_z"
gz = "gyro_z"
accel_unit = "g"
gyro_unit = "deg/s"
[gnss]
x = "east_cm"
y = "north_cm"
yaw = "heading_deg"
vx = "v_fwd"
vy = "v_left"
position_unit = "cm"
yaw_unit = "deg"
velocity_frame = "body"
[truth]
x = "gt_x"
y = "gt_y"
yaw = "gt_yaw"
vx = "gt_vx_world"
vy = "gt_vy_world"
velocity_frame = "world"
"""


def _write_csv(path: Path, columns: dict[str, np.ndarray]) -> None:
    names = list(columns)
    n = len(next(iter(columns.values())))
    lines = [",".join(names)]
    for i in range(n):
        lines.append(",".join("" if not np.isfinite(columns[c][i]) else repr(float(columns[c][i])) for c in names))
    path.write_text("\n".join(lines) + "\n")


def test_import_csv_converts_units(tmp_path: Path) -> None:
    rng = np.random.default_rng(5)
    n = 40
    stamp = 1_000.0 + np.arange(n) * 10.0  # ms
    wl, wr = rng.uniform(-60, 60, (2, n))  # rpm (< 93 rpm = 9.8 rad/s)
    cl, cr = rng.uniform(-0.5, 0.5, (2, n))  # m/s tread speed
    acc = rng.normal(0, 0.05, (n, 3)) + [0, 0, 1.0]  # g
    gz = rng.uniform(-40, 40, n)  # deg/s
    gnss_rows = np.arange(n) % 5 == 0  # GNSS at a fifth of the rate: other cells empty
    e, no = rng.normal(0, 500, (2, n))
    hdg = rng.uniform(-180, 180, n)
    vf, vl = rng.normal(0, 0.5, (2, n))
    gx, gy, gyaw, gvx, gvy = rng.normal(0, 1, (5, n))
    cols = {"stamp_ms": stamp, "wl_rpm": wl, "wr_rpm": wr, "cmd_l": cl, "cmd_r": cr,
            "acc_x": acc[:, 0], "acc_y": acc[:, 1], "acc_z": acc[:, 2], "gyro_z": gz,
            "east_cm": np.where(gnss_rows, e, np.nan), "north_cm": np.where(gnss_rows, no, np.nan),
            "heading_deg": np.where(gnss_rows, hdg, np.nan), "v_fwd": np.where(gnss_rows, vf, np.nan),
            "v_left": np.where(gnss_rows, vl, np.nan), "unused": np.zeros(n),
            "gt_x": gx, "gt_y": gy, "gt_yaw": gyaw, "gt_vx_world": gvx, "gt_vy_world": gvy}
    _write_csv(tmp_path / "log.csv", cols)
    run = import_csv(tmp_path / "log.csv", write_mapping(tmp_path, CSV_MAPPING))
    plat = load_platform("p3at_pneumatic_20psi")
    assert run.id == "csvtest" and run.meta["platform"]["name"] == plat.name
    assert np.allclose(run.t, (stamp - stamp[0]) * 1e-3, rtol=0, atol=1e-12)
    assert np.allclose(run["enc_wl"], wl * 2 * np.pi / 60, rtol=1e-15)
    assert np.allclose(run["enc_wr"], wr * 2 * np.pi / 60, rtol=1e-15)
    assert np.allclose(run["cmd_wl"], cl / plat.wheel_radius, rtol=1e-15)
    assert np.allclose(run["imu_az"], acc[:, 2] * 9.80665, rtol=1e-15)
    assert np.allclose(run["imu_gz"], np.deg2rad(gz), rtol=1e-15)
    assert "imu_gx" not in run.channels and "unused" not in run.channels
    m = gnss_rows
    assert np.array_equal(np.isfinite(run["gnss_x"]), m)
    assert np.allclose(run["gnss_x"][m], e[m] / 100) and np.allclose(run["gnss_y"][m], no[m] / 100)
    yaw = np.deg2rad(hdg[m])
    assert np.allclose(run["gnss_yaw"][m], yaw)
    # body-frame velocities (cm/s: position_unit) rotated into the world frame (ENU)
    assert np.allclose(run["gnss_vx"][m], (np.cos(yaw) * vf[m] - np.sin(yaw) * vl[m]) / 100)
    assert np.allclose(run["gnss_vy"][m], (np.sin(yaw) * vf[m] + np.cos(yaw) * vl[m]) / 100)
    # truth velocities given in the world frame are rotated into the body frame
    assert np.allclose(run["truth_vx"], np.cos(gyaw) * gvx + np.sin(gyaw) * gvy)
    assert np.allclose(run["truth_vy"], -np.sin(gyaw) * gvx + np.cos(gyaw) * gvy)


def test_import_csv_nan_policy_drop(tmp_path: Path) -> None:
    (tmp_path / "l.csv").write_text("t,wl,wr\n0,1,2\n0.01,nan,2\n0.02,1,inf\n")
    mp = write_mapping(tmp_path, 'nan_policy = "drop"\n[wheels]\nleft = "wl"\nright = "wr"\n')
    run = import_csv(tmp_path / "l.csv", mp)
    assert np.array_equal(np.isnan(run["enc_wl"]), [False, True, False])
    assert np.array_equal(np.isnan(run["enc_wr"]), [False, False, True])


# ------------------------------------------------------------------------------------------
# Bags
# ------------------------------------------------------------------------------------------
@pytest.mark.parametrize("ros", [1, 2])
def test_import_bag_values(tmp_path: Path, ros: int) -> None:
    sig = sample_signals(ros)
    path = tmp_path / ("log.bag" if ros == 1 else "log_ros2")
    write_bag(path, ros, bag_topics(sig), receive_offset=0.0123)
    run = import_bag(path, write_mapping(tmp_path, BAG_MAPPING))
    t0 = sig["t0"]
    assert run.id == "bagtest"
    assert run.meta["time_origin_ns"] == int(round(t0 * 1e9))
    # the rows are the union of all sample stamps
    all_t = np.unique(np.round(np.concatenate([sig["tw"], sig["ti"], sig["to"], sig["tp"]]) * 1e9).astype(np.int64))
    assert run.t.size == all_t.size
    assert np.allclose(run.t, (all_t - all_t[0]) * 1e-9, atol=1e-12)

    def at(ts: np.ndarray) -> np.ndarray:
        return np.searchsorted(all_t, np.round(ts * 1e9).astype(np.int64))

    iw = at(sig["tw"])
    assert np.allclose(run["enc_wl"][iw], sig["wl"], atol=1e-12)  # mean of wl+0.1, wl-0.1
    assert np.allclose(run["enc_wr"][iw], sig["wr"], atol=1e-12)  # inverted right joints
    assert np.isfinite(run["enc_wl"]).sum() == sig["tw"].size
    ii = at(sig["ti"])
    for k, c in enumerate(("imu_ax", "imu_ay", "imu_az", "imu_gx", "imu_gy", "imu_gz")):
        assert np.array_equal(run[c][ii], sig["imu"][:, k])
    io = at(sig["to"])
    od = sig["odom"]
    assert np.array_equal(run["gnss_x"][io], od[:, 0])
    yaw = np.angle(np.exp(1j * od[:, 2]))
    assert np.allclose(run["gnss_yaw"][io], yaw, atol=1e-12)
    assert np.allclose(run["gnss_vx"][io], np.cos(yaw) * od[:, 3] - np.sin(yaw) * od[:, 4], atol=1e-12)
    assert np.allclose(run["gnss_vy"][io], np.sin(yaw) * od[:, 3] + np.cos(yaw) * od[:, 4], atol=1e-12)
    ip = at(sig["tp"])
    assert np.array_equal(run["ref_x"][ip], sig["pose"][:, 0])
    assert np.allclose(run["ref_yaw"][ip], sig["pose"][:, 2], atol=1e-12)
    assert np.isnan(run["ref_x"]).sum() == run.t.size - sig["tp"].size
    # the imported Run is an ordinary Run: it round-trips through Parquet bit for bit
    back = Run.from_parquet(run.to_parquet(tmp_path / "imported.parquet"))
    assert back.content_hash() == run.content_hash()


def test_import_bag_receive_time(tmp_path: Path) -> None:
    sig = sample_signals(9)
    path = write_bag(tmp_path / "r.bag", 1, {"/imu/data": bag_topics(sig)["/imu/data"]}, receive_offset=0.5)
    mp = write_mapping(tmp_path, '[time]\nsource = "receive"\n[imu]\ntopic = "/imu/data"\n')
    run = import_bag(path, mp)
    assert run.meta["time_origin_ns"] == int(round((sig["ti"][0] + 0.5) * 1e9))
    ns = np.array([int(round((t + 0.5) * 1e9)) for t in sig["ti"]], dtype=np.int64)
    assert np.allclose(run.t, (ns - ns[0]) * 1e-9, rtol=0, atol=1e-12)


def test_imported_run_feeds_metrics(tmp_path: Path) -> None:
    """End to end: a bag with a known path imports into a Run whose reference trajectory
    scores zero against the truth it was written from."""
    from bench import metrics as M

    t = np.arange(0, 5, 0.05)
    x, y, yaw = integrate_se2(t, np.full_like(t, 0.4), np.zeros_like(t), np.full_like(t, 0.3))
    rows = [(1e9 + ti, {"x": a, "y": b, "yaw": c}) for ti, a, b, c in zip(t, x, y, yaw)]
    path = write_bag(tmp_path / "p.bag", 1, {"/vicon/pose": ("pose", rows)})
    run = import_bag(path, write_mapping(tmp_path, '[reference]\ntopic = "/vicon/pose"\n'))
    ref = M.Trajectory.from_run(run, "ref")
    truth = M.Trajectory.planar(t - t[0], x, y, yaw)
    assert M.ape(truth, ref, max_diff=1e-6).stats.max < 1e-9
    assert M.ape(truth, ref, "rotation_angle_rad", max_diff=1e-6).stats.max < 1e-9


def test_load_mapping_names_bad_field(tmp_path: Path) -> None:
    with pytest.raises(SpecError) as ei:
        load_mapping(write_mapping(tmp_path, '[wheels]\nunit = "furlongs"\n'))
    assert ei.value.field == "wheels.unit" and "furlongs" in str(ei.value)
    with pytest.raises(SpecError) as ei:
        load_mapping(write_mapping(tmp_path, '[imu]\ntopik = "/imu"\n'))
    assert ei.value.field == "imu.topik"
    assert isinstance(load_mapping(write_mapping(tmp_path, BAG_MAPPING)), ImportMapping)
