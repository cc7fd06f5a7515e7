"""import-bag reads what a real Husky or Jackal bag carries: sensor_msgs/NavSatFix (to local ENU metres),
geometry_msgs/Twist and TwistStamped on cmd_vel (commands) and nav_msgs/Odometry's twist as the wheel odometry.

Bags are written here with rosbags' writers from known values.  Expectations: NavSatFix against the closed form of
small offsets on the WGS-84 ellipsoid (north = (M + h) dlat, east = (N + h) cos(lat) dlon, M and N the meridional and
normal radii of curvature) and against pymap3d's own inverse (enu2geodetic), the fix track's velocity and course
against a straight drive; the twists against the differential-drive inverse written out here and the round trip
through bench.kinematics' forward model; a Husky-like bag end to end into a Run that Liu 2020's UKF estimates; each
bad input a one-line error naming the file, field and value, exit 2 from the CLI.
"""
from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from bench.formats import import_bag
from bench.run import Run, RunError
from bench.spec import SpecError, load_platform
from tests.test_formats import _typestore, ros_header

A, F = 6378137.0, 1 / 298.257223563  # WGS-84
E2 = F * (2 - F)
TYPES = {"twist": "geometry_msgs/msg/Twist", "twist_stamped": "geometry_msgs/msg/TwistStamped",
         "navsat": "sensor_msgs/msg/NavSatFix", "odom": "nav_msgs/msg/Odometry", "imu": "sensor_msgs/msg/Imu",
         "joints": "sensor_msgs/msg/JointState"}


def write(path: Path, ros: int, topics: dict[str, tuple[str, list[tuple[float, dict[str, Any]]]]],
          receive_offset: float = 0.0) -> Path:
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.rosbag2 import Writer as Writer2

    ts = _typestore(ros)
    T = ts.types
    Vec = T["geometry_msgs/msg/Vector3"]
    Quat, Point = T["geometry_msgs/msg/Quaternion"], T["geometry_msgs/msg/Point"]

    def header(t: float) -> Any:
        return ros_header(ts, ros, t)

    def twist(f: dict[str, Any]) -> Any:
        return T["geometry_msgs/msg/Twist"](linear=Vec(x=f["v"], y=0.0, z=0.0), angular=Vec(x=0.0, y=0.0, z=f["w"]))

    def make(kind: str, t: float, f: dict[str, Any]) -> Any:
        if kind == "joints":
            return T[TYPES[kind]](header=header(t), name=f["name"], position=np.zeros(len(f["name"])),
                                  velocity=np.asarray(f["velocity"], float), effort=np.zeros(0))
        if kind == "twist":
            return twist(f)
        if kind == "twist_stamped":
            return T[TYPES[kind]](header=header(t), twist=twist(f))
        if kind == "navsat":
            st = T["sensor_msgs/msg/NavSatStatus"](status=f.get("status", 0), service=1)
            cov = np.zeros(9)
            cov[0], cov[4] = f.get("var", (0.0, 0.0))
            return T[TYPES[kind]](header=header(t), status=st, latitude=f["lat"], longitude=f["lon"],
                                  altitude=f["alt"], position_covariance=cov,
                                  position_covariance_type=2 if "var" in f else 0)  # 2: DIAGONAL_KNOWN
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
    """lat, lon [deg] of small north / east offsets [m] about (LAT0, LON0) at the height ALT0: north = (M + h) dlat,
    east = (N + h) cos(lat) dlon, M and N the meridional and normal radii of curvature at LAT0 (without the + h the
    east metres are 1.1e-5 too long at 60 m: 0.3 mm at 30 m)."""
    phi = math.radians(LAT0)
    w = math.sqrt(1 - E2 * math.sin(phi) ** 2)
    m, n = A * (1 - E2) / w ** 3, A / w
    return LAT0 + np.degrees(north / (m + ALT0)), LON0 + np.degrees(east / ((n + ALT0) * math.cos(phi)))


def _fixes(east: np.ndarray, north: np.ndarray, dt: float = 0.2, t0: float = T0, **extra: Any) -> list[tuple]:
    lat, lon = _small_offsets(north, east)
    return [(t0 + dt * i, {"lat": float(a), "lon": float(b), "alt": ALT0, **extra}) for i, (a, b) in
            enumerate(zip(lat, lon))]


# ------------------------------------------------------------------------------------------ NavSatFix
@pytest.mark.parametrize("ros", [1, 2])
def test_navsatfix_becomes_local_enu_metres(tmp_path, ros):
    east, north = np.linspace(0.0, 30.0, 16), np.linspace(0.0, -12.0, 16)
    rows = _fixes(east, north, var=(0.02 ** 2, 0.03 ** 2))
    rows.insert(3, (T0 + 0.2 * 2.5, {"lat": 0.0, "lon": 0.0, "alt": 0.0, "status": -1}))  # STATUS_NO_FIX
    rows.insert(0, (T0 - 0.1, {"lat": 10.0, "lon": 10.0, "alt": 0.0, "status": -1}))  # before the first fix
    path = write(tmp_path / ("g.bag" if ros == 1 else "g2"), ros, {"/navsat/fix": ("navsat", rows)})
    with pytest.warns(RuntimeWarning, match=r"/navsat/fix: 2 of 18 NavSatFix messages with status STATUS_NO_FIX"):
        run = import_bag(path, mapping(tmp_path, '[gnss]\ntopic = "/navsat/fix"\n'))
    x, y = run["gnss_x"], run["gnss_y"]
    assert x.size == 16 and np.isfinite(x).all()  # the no-fix samples dropped: no row of their own
    meta = run.meta["navsat"]["gnss"]
    assert meta["fixes"] == 16 and meta["no_fix_dropped"] == 2 and meta["topic"] == "/navsat/fix"
    np.testing.assert_allclose(meta["position_std_median"], [0.02, 0.03], rtol=1e-12)
    # the datum is the first fix (status >= STATUS_FIX), not the no-fix sample before it
    assert run.meta["enu_datum"]["source"] == "first fix of /navsat/fix"
    np.testing.assert_allclose([run.meta["enu_datum"][k] for k in ("latitude_deg", "longitude_deg", "altitude")],
                               [LAT0, LON0, ALT0], atol=1e-12)
    # the closed form of small offsets is first order: its largest second-order term, the meridian convergence
    # east^2 tan(lat) / (2 R) in north, is 7.5e-5 m at 30 m east (measured max |error|: north 7.5e-5, east 6.0e-5 m)
    np.testing.assert_allclose(x, east, atol=1e-4)
    np.testing.assert_allclose(y, north, atol=1e-4)
    assert "gnss_yaw" not in run.data.columns and "gnss_vx" not in run.data.columns  # a fix has neither


def test_navsatfix_datum_from_the_mapping(tmp_path):
    import pymap3d

    e, n = np.array([5.0, 120.0, -40.0, 7.0]), np.array([-3.0, 80.0, 200.0, 9.0])
    lat, lon, alt = pymap3d.enu2geodetic(e, n, np.zeros(4), LAT0, LON0, ALT0)
    rows = [(T0 + i, {"lat": float(a), "lon": float(b), "alt": float(c)})
            for i, (a, b, c) in enumerate(zip(lat, lon, alt))]
    rows[3][1]["alt"] = math.nan  # "no altitude" (NavSatFix allows it): placed at the datum's altitude
    path = write(tmp_path / "d.bag", 1, {"/fix": ("navsat", rows)})
    run = import_bag(path, mapping(tmp_path, f'[reference]\ntopic = "/fix"\n[datum]\nlatitude_deg = {LAT0}\n'
                                             f'longitude_deg = {LON0}\naltitude = {ALT0}\n'))
    np.testing.assert_allclose(run["ref_x"], e, atol=1e-6)
    np.testing.assert_allclose(run["ref_y"], n, atol=1e-6)
    assert run.meta["enu_datum"] == {"latitude_deg": LAT0, "longitude_deg": LON0, "altitude": ALT0,
                                     "source": "mapping"}
    # a datum without altitude takes the first fix's: the same metres to < 1 um here (fix heights ~ the datum's)
    run2 = import_bag(path, mapping(tmp_path, f'[reference]\ntopic = "/fix"\n[datum]\nlatitude_deg = {LAT0}\n'
                                              f'longitude_deg = {LON0}\n'))
    assert run2.meta["enu_datum"]["altitude"] == pytest.approx(float(alt[0]))
    np.testing.assert_allclose(run2["ref_x"], e, atol=1e-6)


def test_two_navsatfix_topics_share_one_datum(tmp_path):
    """A receiver as gnss and an RTK receiver as reference: both in the frame of the earliest fix."""
    gnss = _fixes(np.array([0.0, 1.0, 2.0]), np.zeros(3), t0=T0)
    ref = _fixes(np.array([10.0, 11.0]), np.array([5.0, 5.0]), t0=T0 + 0.05)
    path = write(tmp_path / "two.bag", 1, {"/fix": ("navsat", gnss), "/rtk/fix": ("navsat", ref)})
    run = import_bag(path, mapping(tmp_path, '[gnss]\ntopic = "/fix"\n[reference]\ntopic = "/rtk/fix"\n'))
    assert run.meta["enu_datum"]["source"] == "first fix of /fix"
    np.testing.assert_allclose(run.samples("ref_x")[1], [10.0, 11.0], atol=1e-4)
    np.testing.assert_allclose(run.samples("ref_y")[1], [5.0, 5.0], atol=1e-4)


def test_navsatfix_velocity_and_course_from_the_fix_track(tmp_path):
    """At rest for 1 s, then 0.8 m/s along 30 deg (CCW from east): the velocity is the track's, the course 30 deg
    where moving and no sample at rest."""
    t = np.arange(30) * 0.2
    s = np.where(t < 1.0, 0.0, 0.8 * (t - 1.0))
    hd = math.radians(30.0)
    path = write(tmp_path / "v.bag", 1, {"/fix": ("navsat", _fixes(s * math.cos(hd), s * math.sin(hd)))})
    run = import_bag(path, mapping(tmp_path, '[gnss]\ntopic = "/fix"\nvelocity = "fix_difference"\n'
                                             'heading = "course"\ncourse_min_speed = 0.3\n'))
    moving = t >= 1.4  # np.gradient's central difference: the fix at 1.0 s still sees half the rest
    np.testing.assert_allclose(run["gnss_vx"][moving], 0.8 * math.cos(hd), atol=1e-4)
    np.testing.assert_allclose(run["gnss_vy"][moving], 0.8 * math.sin(hd), atol=1e-4)
    np.testing.assert_allclose(run["gnss_yaw"][moving], hd, atol=1e-4)
    assert np.isnan(run["gnss_yaw"][t < 0.9]).all() and np.allclose(run["gnss_vx"][t < 0.9], 0.0, atol=1e-6)


def test_navsatfix_nan_policy_drop(tmp_path):
    rows = _fixes(np.arange(4.0), np.zeros(4))
    rows[1][1]["lat"] = math.nan
    path = write(tmp_path / "n.bag", 1, {"/fix": ("navsat", rows)})
    run = import_bag(path, mapping(tmp_path, 'nan_policy = "drop"\n[gnss]\ntopic = "/fix"\n'))
    assert np.isnan(run["gnss_x"][1]) and np.isnan(run["gnss_y"][1])
    np.testing.assert_allclose(run["gnss_x"][[0, 2, 3]], [0.0, 2.0, 3.0], atol=1e-4)


# ------------------------------------------------------------------------------------------ twists
def _twists(n: int = 20, dt: float = 0.05) -> list[tuple[float, dict[str, float]]]:
    return [(T0 + dt * i, {"v": 0.3 + 0.02 * i, "w": 0.5 * math.sin(i / 3)}) for i in range(n)]


@pytest.mark.parametrize("kind", ["twist", "twist_stamped"])
def test_cmd_vel_twists_are_the_commanded_wheel_speeds(tmp_path, kind):
    rows = _twists()
    imu = [(T0 + 0.01 * i, {"gz": 0.1}) for i in range(100)]
    path = write(tmp_path / "c.bag", 1, {"/cmd_vel": (kind, rows), "/imu/data": ("imu", imu)}, receive_offset=0.013)
    run = import_bag(path, mapping(tmp_path, '[platform]\nname = "husky"\n[commands]\ntopic = "/cmd_vel"\n'
                                             '[imu]\ntopic = "/imu/data"\n'))  # time.source = "header" (default)
    hk = load_platform("husky")
    r, b = hk.wheel_radius, hk.track
    v, w = np.array([f["v"] for _, f in rows]), np.array([f["w"] for _, f in rows])
    tc, wl = run.samples("cmd_wl")
    np.testing.assert_allclose(wl, (v - w * b / 2) / r, rtol=1e-12)
    np.testing.assert_allclose(run.samples("cmd_wr")[1], (v + w * b / 2) / r, rtol=1e-12)
    # the IMU is at its header stamps; a Twist (no header) at its receive times (+13 ms), a TwistStamped at its stamps
    lag = 0.013 if kind == "twist" else 0.0
    # (to 1 us: the test's stamps T0 + 0.05 i are float64 seconds near 1.7e9, 2.4e-7 s apart)
    np.testing.assert_allclose(tc, 0.05 * np.arange(20) + lag, atol=1e-6)
    np.testing.assert_allclose(run.samples("imu_gz")[0], 0.01 * np.arange(100), atol=1e-6)
    assert run.meta["time_origin_ns"] == int(round(T0 * 1e9))
    assert run.meta.get("receive_time_topics") == (["/cmd_vel"] if kind == "twist" else None)


def test_odometry_twist_as_wheel_odometry_round_trips_through_the_kinematics(tmp_path):
    from bench.kinematics import ideal_dd

    rows = _twists()
    path = write(tmp_path / "o_ros2", 2, {"/husky_velocity_controller/odom": ("odom", rows)})
    mp = mapping(tmp_path, '[wheels]\ntopic = "/husky_velocity_controller/odom"\nwheel_radius = 0.2\ntrack = 0.6\n')
    run = import_bag(path, mp)
    v, w = np.array([f["v"] for _, f in rows]), np.array([f["w"] for _, f in rows])
    np.testing.assert_allclose(run["enc_wl"], (v - 0.3 * w) / 0.2, rtol=1e-12)  # the closed-form DD inverse
    np.testing.assert_allclose(run["enc_wr"], (v + 0.3 * w) / 0.2, rtol=1e-12)
    vx, vy, wz = ideal_dd(0.2 * run["enc_wl"], 0.2 * run["enc_wr"], 0.6)  # the forward model of the tread speeds
    np.testing.assert_allclose(vx, v, atol=1e-12)
    np.testing.assert_allclose(wz, w, atol=1e-12)
    assert run.meta["wheels_twist_geometry"] == {"wheel_radius": 0.2, "track": 0.6}


def test_odometry_wheels_default_to_the_platform_geometry(tmp_path):
    rows = _twists()
    path = write(tmp_path / "o.bag", 1, {"/odom": ("odom", rows)})
    run = import_bag(path, mapping(tmp_path, '[platform]\nname = "husky"\n[wheels]\ntopic = "/odom"\n'))
    hk = load_platform("husky")
    v, w = np.array([f["v"] for _, f in rows]), np.array([f["w"] for _, f in rows])
    np.testing.assert_allclose(run["enc_wr"], (v + w * hk.track / 2) / hk.wheel_radius, rtol=1e-12)


# ------------------------------------------------------------------------------------------ a Husky's bag
def _husky_bag(tmp_path: Path, ros: int = 1) -> Path:
    """No JointState: wheel odometry (50 Hz), IMU (100 Hz), GNSS fixes (5 Hz, one without a fix) and cmd_vel (20 Hz)
    of a drive at rest for 1 s and then along an arc, as a Husky records them."""
    from bench.kinematics import integrate_se2

    t = np.arange(0, 12.0, 0.01)
    v = np.where(t < 1.0, 0.0, 0.6)
    w = np.where(t < 1.0, 0.0, 0.15)
    x, y, _ = integrate_se2(t, v, np.zeros_like(t), w, yaw0=0.4)
    odom = [(T0 + t[i], {"v": v[i], "w": w[i]}) for i in range(0, t.size, 2)]
    cmd = [(T0 + t[i], {"v": v[i], "w": w[i]}) for i in range(0, t.size, 5)]
    imu = [(T0 + t[i] + 0.001, {"gz": w[i]}) for i in range(t.size)]
    gi = np.arange(0, t.size, 20)
    fix = _fixes(x[gi], y[gi], dt=0.2, var=(0.02 ** 2, 0.02 ** 2))
    fix[7] = (fix[7][0], dict(fix[7][1], status=-1))
    topics = {"/husky_velocity_controller/odom": ("odom", odom), "/imu/data": ("imu", imu),
              "/navsat/fix": ("navsat", fix), "/cmd_vel": ("twist", cmd)}
    return write(tmp_path / ("husky.bag" if ros == 1 else "husky_ros2"), ros, topics, receive_offset=0.004)


HUSKY_MAPPING = """
run_id = "husky_field"
[platform]
name = "husky"
[wheels]
topic = "/husky_velocity_controller/odom"
track = 1.0702          # 1.875 x 0.5708 m: the Husky controller's wheel_separation_multiplier x the URDF's
[commands]
topic = "/cmd_vel"
track = 1.0702
[imu]
topic = "/imu/data"
[gnss]
topic = "/navsat/fix"
velocity = "fix_difference"
heading = "course"
"""


@pytest.mark.parametrize("ros", [1, 2])
def test_a_husky_like_bag_imports_end_to_end(tmp_path, ros):
    path = _husky_bag(tmp_path, ros)
    with pytest.warns(RuntimeWarning, match="1 of 60 NavSatFix"):
        run = import_bag(path, mapping(tmp_path, HUSKY_MAPPING))
    back = Run.from_parquet(run.to_parquet(tmp_path / "husky.parquet"))
    assert back.content_hash() == run.content_hash() and back.id == "husky_field"
    for c in ("enc_wl", "enc_wr", "cmd_wl", "cmd_wr", "imu_gz", "gnss_x", "gnss_y", "gnss_vx", "gnss_vy", "gnss_yaw"):
        assert np.isfinite(back[c]).any(), c
    assert back.meta["navsat"]["gnss"]["no_fix_dropped"] == 1 and back.meta["receive_time_topics"] == ["/cmd_vel"]
    # strict JSON metadata of the import (the mapping's "not given" NaNs are None; the platform's infinite command
    # limits are the platform's own business)
    json.dumps({k: back.meta[k] for k in ("mapping", "navsat", "enu_datum")}, allow_nan=False)
    assert back.meta["mapping"]["datum"] == {"latitude_deg": None, "longitude_deg": None, "altitude": None}
    # on the arc, the course is the heading (no side slip here): yaw0 + w (t - 1)
    tg, yaw = back.samples("gnss_yaw")
    late = (tg > 2.0) & (tg < tg[-1])  # the last fix's difference is one-sided: w dt / 2 = 0.015 rad behind
    np.testing.assert_allclose(np.angle(np.exp(1j * (yaw[late] - (0.4 + 0.15 * (tg[late] - 1.0))))), 0.0, atol=0.01)


def test_liu_ukf_runs_on_an_imported_husky_bag(tmp_path):
    """The channels are the ones Liu's UKF reads (gnss_x, _y, _yaw, _vx, _vy, enc_*, imu_*): it estimates the drive."""
    from bench import registry

    with pytest.warns(RuntimeWarning, match="STATUS_NO_FIX"):
        run = import_bag(_husky_bag(tmp_path), mapping(tmp_path, HUSKY_MAPPING))
    run = Run.from_parquet(run.to_parquet(tmp_path / "h.parquet"))
    est = registry.estimate(registry.get("liu2020.ukf_icr"), run.without_truth())
    gx, gy = run.samples("gnss_x")[1], run.samples("gnss_y")[1]
    d = est.data
    assert np.isfinite(d["x"]).all() and np.hypot(d["x"].iloc[-1] - gx[-1], d["y"].iloc[-1] - gy[-1]) < 0.5


# ------------------------------------------------------------------------------------------ bad input
BAD = {  # case: (mapping text, words of the one-line message)
    "twist_as_wheels": ('[wheels]\ntopic = "/cmd_vel"\n',
                        "'/cmd_vel' = 'geometry_msgs/msg/Twist': mapping wheels expects"),
    "fix_as_imu": ('[imu]\ntopic = "/fix"\n', "'/fix' = 'sensor_msgs/msg/NavSatFix': mapping imu expects"),
    "odom_as_commands": ('[commands]\ntopic = "/odom"\n', "'/odom' = 'nav_msgs/msg/Odometry': mapping commands"),
    "no_fix_at_all": ('[gnss]\ntopic = "/nofix"\n', "'/nofix status.status' = '3 messages, all -1': every NavSatFix"),
    "datum_latitude": ('[gnss]\ntopic = "/fix"\n[datum]\nlatitude_deg = 95.0\nlongitude_deg = 0.0\n',
                       "'datum.latitude_deg' = 95.0: expected a latitude in [-90, 90] deg"),
    "datum_longitude": ('[gnss]\ntopic = "/fix"\n[datum]\nlatitude_deg = 5.0\nlongitude_deg = -181.0\n',
                        "'datum.longitude_deg' = -181.0: expected a longitude in [-180, 180] deg"),
    "datum_partial": ('[gnss]\ntopic = "/fix"\n[datum]\nlatitude_deg = 46.0\n',
                      "'datum.longitude_deg' = None: the datum needs latitude_deg and longitude_deg"),
    "datum_far": ('[gnss]\ntopic = "/fix"\n[datum]\nlatitude_deg = -71.27\nlongitude_deg = 46.78\n',
                  "'/fix latitude/longitude' = 'message 0: "),
    "latitude_in_message": ('[gnss]\ntopic = "/badlat"\n', "'/badlat latitude' = 'message 1: 91.5 deg': a WGS-84"),
    "no_geometry": ('[commands]\ntopic = "/cmd_vel"\n', "'commands.wheel_radius' = 0.0: a twist topic"),
    "joints_on_odom": ('[wheels]\ntopic = "/odom"\nleft_joints = ["a"]\nright_joints = ["b"]\n',
                       "'wheels.left_joints' = ['a']: joints are for a JointState; /odom is a nav_msgs/msg/Odometry"),
    "track_on_joints": ('[wheels]\ntopic = "/joints"\nleft_joints = ["l"]\nright_joints = ["r"]\ntrack = 0.5\n',
                        "'wheels.track' = 0.5: track is for a twist topic; /joints is a JointState"),
    "unit_on_odom": ('[wheels]\ntopic = "/odom"\nunit = "rpm"\nwheel_radius = 0.2\ntrack = 0.5\n',
                     "'wheels.unit' = 'rpm': /odom is a nav_msgs/msg/Odometry"),
    "heading_on_odom": ('[gnss]\ntopic = "/odom"\nheading = "course"\n',
                        "'gnss.heading' = 'course': for a sensor_msgs/NavSatFix topic; /odom is"),
    "velocity_on_reference": ('[reference]\ntopic = "/fix"\nvelocity = "fix_difference"\n',
                              "'reference.velocity' = 'fix_difference': a velocity from the fixes is for [gnss]"),
    "heading_value": ('[gnss]\ntopic = "/fix"\nheading = "compass"\n', "'gnss.heading' = 'compass': expected one of"),
    "nan_latitude": ('[gnss]\ntopic = "/nanlat"\n', "'/nanlat latitude' = 'message 1: nan': NaN/inf in a message"),
    "inf_altitude": ('[gnss]\ntopic = "/infalt"\n', "'/infalt altitude' = 'message 0: inf': a finite altitude"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_inputs_are_one_line_errors(tmp_path, capsys, case):
    from bench.cli import main

    topics = {"/cmd_vel": ("twist", _twists(5)), "/odom": ("odom", _twists(5)),
              "/joints": ("joints", [(T0 + i, {"name": ["l", "r"], "velocity": [1.0, 1.0]}) for i in range(3)]),
              "/fix": ("navsat", _fixes(
              np.arange(3.0), np.zeros(3))),
              "/nofix": ("navsat", [(T0 + i, {"lat": LAT0, "lon": LON0, "alt": 0.0, "status": -1}) for i in range(3)]),
              "/badlat": ("navsat", [(T0, {"lat": 45.0, "lon": 0.0, "alt": 0.0}), (T0 + 1, {"lat": 91.5, "lon": 0.0,
                                                                                            "alt": 0.0})]),
              "/infalt": ("navsat", [(T0, {"lat": 45.0, "lon": 0.0, "alt": math.inf})]),
              "/nanlat": ("navsat", [(T0 + i, {"lat": [45.0, math.nan, 45.0][i], "lon": 0.0, "alt": 0.0})
                                     for i in range(3)])}
    path = write(tmp_path / "bad.bag", 1, topics)
    text, words = BAD[case]
    mp = mapping(tmp_path, text)
    with pytest.raises((RunError, SpecError)) as ei:
        import_bag(path, mp)
    msg = str(ei.value)
    assert words in msg and "\n" not in msg
    assert msg.startswith(str(path) if isinstance(ei.value, RunError) else str(mp))  # names the file
    out = tmp_path / "o.parquet"
    assert main(["import-bag", str(path), "--map", str(mp), "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err == f"error: {msg}" and not out.exists()
