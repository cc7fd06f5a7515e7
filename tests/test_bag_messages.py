"""import-bag reads what a real Husky or Jackal bag carries: sensor_msgs/NavSatFix (to local ENU metres),
geometry_msgs/Twist and TwistStamped on cmd_vel (commands) and nav_msgs/Odometry's twist as the wheel odometry.

Bags are written here with rosbags' writers from known values.  Expectations: NavSatFix against the closed form of
small offsets on the WGS-84 ellipsoid (north = M dlat, east = N cos(lat) dlon, M and N the meridional and normal radii
of curvature), and against pymap3d's own inverse; the twists against the differential-drive inverse written out here
and the round trip through bench.kinematics' forward model; each bad input a one-line error, exit 2 from the CLI.
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from bench.formats import import_bag
from bench.run import Run, RunError
from bench.spec import SpecError, load_platform
from tests.test_formats import _typestore

A, F = 6378137.0, 1 / 298.257223563  # WGS-84
E2 = F * (2 - F)
TYPES = {"twist": "geometry_msgs/msg/Twist", "twist_stamped": "geometry_msgs/msg/TwistStamped",
         "navsat": "sensor_msgs/msg/NavSatFix", "odom": "nav_msgs/msg/Odometry", "imu": "sensor_msgs/msg/Imu"}


def write(path: Path, ros: int, topics: dict[str, tuple[str, list[tuple[float, dict[str, Any]]]]],
          receive_offset: float = 0.0) -> Path:
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.rosbag2 import Writer as Writer2

    ts = _typestore(ros)
    T = ts.types
    Time, Header, Vec = T["builtin_interfaces/msg/Time"], T["std_msgs/msg/Header"], T["geometry_msgs/msg/Vector3"]
    Quat, Point = T["geometry_msgs/msg/Quaternion"], T["geometry_msgs/msg/Point"]

    def header(t: float) -> Any:
        ns = int(round(t * 1e9))
        kw = dict(stamp=Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000), frame_id="base_link")
        if ros == 1:
            kw["seq"] = 0
        return Header(**kw)

    def twist(f: dict[str, Any]) -> Any:
        return T["geometry_msgs/msg/Twist"](linear=Vec(x=f["v"], y=0.0, z=0.0), angular=Vec(x=0.0, y=0.0, z=f["w"]))

    def make(kind: str, t: float, f: dict[str, Any]) -> Any:
        if kind == "twist":
            return twist(f)
        if kind == "twist_stamped":
            return T[TYPES[kind]](header=header(t), twist=twist(f))
        if kind == "navsat":
            st = T["sensor_msgs/msg/NavSatStatus"](status=f.get("status", 0), service=1)
            return T[TYPES[kind]](header=header(t), status=st, latitude=f["lat"], longitude=f["lon"],
                                  altitude=f["alt"], position_covariance=np.zeros(9), position_covariance_type=0)
        if kind == "imu":
            z = Vec(x=0.0, y=0.0, z=0.0)
            return T[TYPES[kind]](header=header(t), orientation=Quat(x=0.0, y=0.0, z=0.0, w=1.0),
                                  orientation_covariance=np.zeros(9), angular_velocity=Vec(x=0.0, y=0.0, z=f["gz"]),
                                  angular_velocity_covariance=np.zeros(9), linear_acceleration=z,
                                  linear_acceleration_covariance=np.zeros(9))
        PoseCov, TwistCov = T["geometry_msgs/msg/PoseWithCovariance"], T["geometry_msgs/msg/TwistWithCovariance"]
        pose = T["geometry_msgs/msg/Pose"](position=Point(x=f.get("x", 0.0), y=0.0, z=0.0),
                                           orientation=Quat(x=0.0, y=0.0, z=0.0, w=1.0))
        return T[TYPES[kind]](header=header(t), child_frame_id="base_link",
                              pose=PoseCov(pose=pose, covariance=np.zeros(36)),
                              twist=TwistCov(twist=twist(f), covariance=np.zeros(36)))

    writer = Writer1(path) if ros == 1 else Writer2(path, version=9)
    with writer:
        conns = {tp: writer.add_connection(tp, TYPES[kind], typestore=ts) for tp, (kind, _) in topics.items()}
        msgs = sorted(((t + receive_offset, t, tp, kind, f) for tp, (kind, rows) in topics.items() for t, f in rows),
                      key=lambda m: m[0])
        for rec, t, tp, kind, f in msgs:
            m = make(kind, t, f)
            raw = ts.serialize_ros1(m, TYPES[kind]) if ros == 1 else ts.serialize_cdr(m, TYPES[kind])
            writer.write(conns[tp], int(round(rec * 1e9)), raw)
    return path


def mapping(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "map.toml"
    p.write_text(text)
    return p


T0 = 1_700_000_000.0
LAT0, LON0, ALT0 = 46.78, -71.27, 60.0  # Quebec City


def _small_offsets(north: np.ndarray, east: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """lat, lon [deg] of small north / east offsets [m] about (LAT0, LON0): the radii of curvature at LAT0."""
    phi = math.radians(LAT0)
    w = math.sqrt(1 - E2 * math.sin(phi) ** 2)
    m, n = A * (1 - E2) / w ** 3, A / w
    return LAT0 + np.degrees(north / m), LON0 + np.degrees(east / (n * math.cos(phi)))


@pytest.mark.parametrize("ros", [1, 2])
def test_navsatfix_becomes_local_enu_metres(tmp_path, ros):
    east, north = np.linspace(0.0, 30.0, 16), np.linspace(0.0, -12.0, 16)
    lat, lon = _small_offsets(north, east)
    rows = [(T0 + 0.2 * i, {"lat": la, "lon": lo, "alt": ALT0, "status": 0}) for i, (la, lo) in enumerate(zip(lat, lon))]
    rows.insert(3, (T0 + 0.2 * 2.5, {"lat": 0.0, "lon": 0.0, "alt": 0.0, "status": -1}))  # STATUS_NO_FIX
    path = write(tmp_path / ("g.bag" if ros == 1 else "g2"), ros, {"/navsat/fix": ("navsat", rows)})
    run = import_bag(path, mapping(tmp_path, '[gnss]\ntopic = "/navsat/fix"\n'))
    x, y = run["gnss_x"][np.isfinite(run["gnss_x"])], run["gnss_y"][np.isfinite(run["gnss_y"])]
    assert x.size == 16 and run.meta["navsat_no_fix_gnss"] == 1  # the no-fix sample dropped and counted
    # the closed form of small offsets is good to ~(d / R)^2 R: under a millimetre at 30 m
    np.testing.assert_allclose(x, east, atol=1e-3)
    np.testing.assert_allclose(y, north, atol=1e-3)
    assert "gnss_yaw" not in run.data.columns or not np.isfinite(run["gnss_yaw"]).any()


def test_navsatfix_datum_from_the_mapping(tmp_path):
    import pymap3d

    e, n = np.array([5.0, 120.0, -40.0]), np.array([-3.0, 80.0, 200.0])
    lat, lon, alt = pymap3d.enu2geodetic(e, n, np.zeros(3), LAT0, LON0, ALT0)
    rows = [(T0 + i, {"lat": float(a), "lon": float(b), "alt": float(c)}) for i, (a, b, c) in enumerate(zip(lat, lon, alt))]
    path = write(tmp_path / "d.bag", 1, {"/fix": ("navsat", rows)})
    run = import_bag(path, mapping(tmp_path, f'[reference]\ntopic = "/fix"\ndatum_lat = {LAT0}\ndatum_lon = {LON0}\n'
                                             f'datum_alt = {ALT0}\n'))
    np.testing.assert_allclose(run["ref_x"], e, atol=1e-6)
    np.testing.assert_allclose(run["ref_y"], n, atol=1e-6)
    assert run.meta["reference_datum_deg_deg_m"] == [LAT0, LON0, ALT0]


def _twists(n: int = 20) -> list[tuple[float, dict[str, float]]]:
    return [(T0 + 0.05 * i, {"v": 0.3 + 0.02 * i, "w": 0.5 * math.sin(i / 3)}) for i in range(n)]


@pytest.mark.parametrize("kind", ["twist", "twist_stamped"])
def test_cmd_vel_twists_are_the_commanded_wheel_speeds(tmp_path, kind):
    rows = _twists()
    path = write(tmp_path / "c.bag", 1, {"/cmd_vel": (kind, rows)}, receive_offset=0.01)
    run = import_bag(path, mapping(tmp_path, '[platform]\nname = "husky"\n[commands]\ntopic = "/cmd_vel"\n'))
    hk = load_platform("husky")
    r, b = hk.wheel_radius, hk.track
    v, w = np.array([f["v"] for _, f in rows]), np.array([f["w"] for _, f in rows])
    np.testing.assert_allclose(run["cmd_wl"], (v - w * b / 2) / r, rtol=1e-12)
    np.testing.assert_allclose(run["cmd_wr"], (v + w * b / 2) / r, rtol=1e-12)
    # a Twist has no header: its times are the receive times (+0.01 s), a TwistStamped's its header stamps
    assert run.meta["time_origin_ns"] == int(round((T0 + (0.01 if kind == "twist" else 0.0)) * 1e9))


def test_odometry_twist_as_wheel_odometry_round_trips_through_the_kinematics(tmp_path):
    from bench.kinematics import ideal_dd

    rows = _twists()
    path = write(tmp_path / "o_ros2", 2, {"/husky_velocity_controller/odom": ("odom", rows)})
    mp = mapping(tmp_path, '[wheels]\ntopic = "/husky_velocity_controller/odom"\nwheel_radius = 0.2\ntrack = 0.6\n')
    run = import_bag(path, mp)
    v, w = np.array([f["v"] for _, f in rows]), np.array([f["w"] for _, f in rows])
    np.testing.assert_allclose(run["enc_wl"], (v - 0.3 * w) / 0.2, rtol=1e-12)
    vx, _, wz = ideal_dd(0.2 * run["enc_wl"], 0.2 * run["enc_wr"], 0.6)  # the forward model of the tread speeds
    np.testing.assert_allclose(vx, v, atol=1e-12)
    np.testing.assert_allclose(wz, w, atol=1e-12)


def test_a_husky_like_bag_imports_end_to_end(tmp_path):
    """No JointState: wheel odometry, IMU, GNSS fixes and cmd_vel, as a Husky records them."""
    lat, lon = _small_offsets(np.linspace(0, 2, 10), np.linspace(0, 5, 10))
    topics = {"/husky_velocity_controller/odom": ("odom", _twists(40)),
              "/imu/data": ("imu", [(T0 + 0.01 * i, {"gz": 0.1}) for i in range(100)]),
              "/navsat/fix": ("navsat", [(T0 + 0.1 * i, {"lat": a, "lon": b, "alt": ALT0}) for i, (a, b) in
                                         enumerate(zip(lat, lon))]),
              "/cmd_vel": ("twist", _twists(40))}
    path = write(tmp_path / "husky.bag", 1, topics)
    mp = mapping(tmp_path, '[platform]\nname = "husky"\n[wheels]\ntopic = "/husky_velocity_controller/odom"\n'
                           '[commands]\ntopic = "/cmd_vel"\n[imu]\ntopic = "/imu/data"\n[gnss]\ntopic = "/navsat/fix"\n')
    run = import_bag(path, mp)
    back = Run.from_parquet(run.to_parquet(tmp_path / "husky.parquet"))
    assert back.content_hash() == run.content_hash()
    for c in ("enc_wl", "enc_wr", "cmd_wl", "cmd_wr", "imu_gz", "gnss_x", "gnss_y"):
        assert np.isfinite(back[c]).any(), c


@pytest.mark.parametrize("case, match", [
    ("wrong_type", r"'/cmd_vel' = 'geometry_msgs/msg/Twist': mapping wheels expects"),
    ("no_fix", r"every NavSatFix has status STATUS_NO_FIX"),
    ("datum", r"datum_lat' = 95"),
    ("no_geometry", r"commands.wheel_radius.*twist topic"),
])
def test_bad_inputs_are_one_line_errors(tmp_path, capsys, case, match):
    from bench.cli import main

    topics = {"/cmd_vel": ("twist", _twists(5)),
              "/fix": ("navsat", [(T0 + i, {"lat": LAT0, "lon": LON0, "alt": 0.0, "status": -1}) for i in range(3)])}
    path = write(tmp_path / "bad.bag", 1, topics)
    text = {"wrong_type": '[wheels]\ntopic = "/cmd_vel"\n', "no_fix": '[gnss]\ntopic = "/fix"\n',
            "datum": '[gnss]\ntopic = "/fix"\ndatum_lat = 95.0\n', "no_geometry": '[commands]\ntopic = "/cmd_vel"\n'}[case]
    mp = mapping(tmp_path, text)
    with pytest.raises((RunError, SpecError), match=match):
        import_bag(path, mp)
    assert main(["import-bag", str(path), "--map", str(mp), "-o", str(tmp_path / "o.parquet")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and err.startswith("error:") and not (tmp_path / "o.parquet").exists()
