"""Bad input: every case raises RunError/SpecError whose message names the file, the column (or
field/topic), the value and what was expected.  Plus hypothesis property tests of spec loading
(any value for a few fields either loads or raises a SpecError naming that field).

CASES maps a case name to (callable(tmp_path) that must raise, exception type, substrings the
message must contain); ``python -m tests.test_bad_input`` prints every message.
"""
from __future__ import annotations

import dataclasses
import math
import tomllib
from pathlib import Path
from typing import Any, Callable

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from bench.formats import import_bag, import_csv, load_mapping
from bench.run import Run, RunError, from_arrays
from bench.spec import SCENARIO_DIR, MotorSpec, Platform, SpecError, build, load_scenario
from tests.test_formats import BAG_MAPPING, bag_topics, sample_signals, write_bag, write_mapping

WHEEL_CSV_MAPPING = '[platform]\nname = "p3at_pneumatic_20psi"\n[wheels]\nleft = "wl"\nright = "wr"\n'


def _csv(tmp: Path, text: str, mapping: str = WHEEL_CSV_MAPPING) -> Run:
    (tmp / "log.csv").write_text(text)
    return import_csv(tmp / "log.csv", write_mapping(tmp, mapping))


def _wheel_csv(n: int = 20, scale: float = 1.0, t: np.ndarray | None = None) -> str:
    t = np.arange(n) * 0.01 if t is None else t
    wl = scale * (2.0 + 0.5 * np.sin(np.arange(t.size)))
    rows = [f"{float(a)!r},{float(b)!r},{float(b) + 0.1!r}" for a, b in zip(t, wl)]
    return "t,wl,wr\n" + "\n".join(rows) + "\n"


def _small_run(**cols: np.ndarray) -> Run:
    t = cols.pop("t", np.arange(5) * 0.01)
    return from_arrays({"t": t, "enc_wl": np.ones(t.size), **cols}, {"run_id": "r1"})


# ------------------------------------------------------------------------------------------
# Parquet / Run
# ------------------------------------------------------------------------------------------
def parquet_truncated(tmp: Path) -> Any:
    p = _small_run().to_parquet(tmp / "run.parquet")
    p.write_bytes(p.read_bytes()[: p.stat().st_size // 2])
    return Run.from_parquet(p)


def parquet_garbage(tmp: Path) -> Any:
    p = tmp / "run.parquet"
    p.write_bytes(b"PAR1 this is not parquet" * 10)
    return Run.from_parquet(p)


def parquet_inf(tmp: Path) -> Any:
    g = np.zeros(5)
    g[3] = np.inf
    p = _small_run(imu_gz=g).to_parquet(tmp / "run.parquet")
    return Run.from_parquet(p).validate()


def run_nonmonotonic(tmp: Path) -> Any:
    return _small_run(t=np.array([0.0, 0.01, 0.02, 0.015, 0.04])).validate()


def run_duplicated(tmp: Path) -> Any:
    return _small_run(t=np.array([0.0, 0.01, 0.01, 0.03, 0.04])).validate()


def run_empty(tmp: Path) -> Any:
    return from_arrays({"t": np.zeros(0)}, {"run_id": "empty_run"}).validate()


def run_missing_channel(tmp: Path) -> Any:
    return _small_run().require({"enc_wl", "imu_gz"}, "yi2009.ekf")


def run_all_nan_channel(tmp: Path) -> Any:
    return _small_run(imu_gz=np.full(5, np.nan)).require({"imu_gz"}, "yi2009.ekf")


def run_wheel_speed_implausible(tmp: Path) -> Any:
    from bench.formats import check_plausible
    from bench.spec import load_platform, to_dict

    run = from_arrays({"t": np.arange(5) * 0.01, "enc_wl": np.full(5, 2.0), "enc_wr": np.full(5, 180.0)},
                      {"run_id": "sim_42", "platform": to_dict(load_platform("p3at_solid"))})
    return check_plausible(run)


def tum_malformed(tmp: Path) -> Any:
    from bench.formats import read_tum

    p = tmp / "traj.tum"
    p.write_text("# t x y z qx qy qz qw\n0 1 2 0 0 0 0 1\n0.1 1 2 0 0 0 1\n")
    return read_tum(p)


# ------------------------------------------------------------------------------------------
# CSV
# ------------------------------------------------------------------------------------------
def csv_truncated(tmp: Path) -> Any:
    text = _wheel_csv()
    return _csv(tmp, text[: text.rfind(",")])  # cut in the middle of the last row


def csv_extra_field(tmp: Path) -> Any:
    return _csv(tmp, "t,wl,wr\n0,1,1\n0.01,1,1,7\n")


def csv_empty_file(tmp: Path) -> Any:
    return _csv(tmp, "")


def csv_header_only(tmp: Path) -> Any:
    return _csv(tmp, "t,wl,wr\n")


def csv_not_a_number(tmp: Path) -> Any:
    return _csv(tmp, "t,wl,wr\n0,1,1\n0.01,1.2.3,1\n")


def csv_nan(tmp: Path) -> Any:
    return _csv(tmp, "t,wl,wr\n0,1,1\n0.01,1,1\n0.02,NaN,1\n")


def csv_inf(tmp: Path) -> Any:
    return _csv(tmp, "t,wl,wr\n0,1,1\n0.01,1,-inf\n")


def csv_nonmonotonic(tmp: Path) -> Any:
    return _csv(tmp, _wheel_csv(t=np.array([0.0, 0.01, 0.02, 0.03, 0.025, 0.05])))


def csv_duplicated(tmp: Path) -> Any:
    return _csv(tmp, _wheel_csv(t=np.array([0.0, 0.01, 0.02, 0.02, 0.04])))


def csv_missing_time(tmp: Path) -> Any:
    return _csv(tmp, "t,wl,wr\n0,1,1\n,1,1\n")


def csv_missing_column(tmp: Path) -> Any:
    return _csv(tmp, "t,left,right\n0,1,1\n")


def csv_rpm_as_rad_s(tmp: Path) -> Any:
    # 2.0..2.5 rad/s logged in rpm (19..24 rpm) while the mapping says rad/s
    return _csv(tmp, _wheel_csv(scale=60 / (2 * np.pi)))


def csv_gyro_deg_as_rad(tmp: Path) -> Any:
    t = np.arange(20) * 0.01
    gz = np.rad2deg(0.8 * np.sin(t * 30))  # up to 0.8 rad/s, logged in deg/s
    text = "t,gz\n" + "\n".join(f"{float(a)!r},{float(b)!r}" for a, b in zip(t, gz)) + "\n"
    return _csv(tmp, text, '[platform]\nname = "p3at_pneumatic_20psi"\n[imu]\ngz = "gz"\n')


def csv_accel_in_g(tmp: Path) -> Any:
    t = np.arange(20) * 0.01
    rows = [f"{float(a)!r},0.01,-0.02,1.0" for a in t]
    return _csv(tmp, "t,ax,ay,az\n" + "\n".join(rows) + "\n",
                '[platform]\nname = "p3at_pneumatic_20psi"\n[imu]\nax = "ax"\nay = "ay"\naz = "az"\n')


def csv_yaw_in_degrees(tmp: Path) -> Any:
    t = np.arange(20) * 0.1
    rows = [f"{float(a)!r},{float(a)!r},0.0,{float(170 - 10 * a)!r}" for a in t]
    return _csv(tmp, "t,x,y,heading\n" + "\n".join(rows) + "\n", '[gnss]\nx = "x"\ny = "y"\nyaw = "heading"\n')


def csv_file_missing(tmp: Path) -> Any:
    return import_csv(tmp / "nope.csv", write_mapping(tmp, WHEEL_CSV_MAPPING))


# ------------------------------------------------------------------------------------------
# Bags
# ------------------------------------------------------------------------------------------
def _bag(tmp: Path, ros: int = 1, topics: dict | None = None, mapping: str = BAG_MAPPING) -> Any:
    path = tmp / ("b.bag" if ros == 1 else "b_ros2")
    write_bag(path, ros, topics if topics is not None else bag_topics(sample_signals()))
    return path, write_mapping(tmp, mapping)


def bag_truncated_ros1(tmp: Path) -> Any:
    path, mp = _bag(tmp)
    path.write_bytes(path.read_bytes()[: int(path.stat().st_size * 0.6)])
    return import_bag(path, mp)


def bag_corrupt_ros2(tmp: Path) -> Any:
    path, mp = _bag(tmp, ros=2)
    for db in path.glob("*.db3"):
        db.write_bytes(b"SQLite format 3\x00" + b"\x13" * 300)
    return import_bag(path, mp)


def bag_missing_topic(tmp: Path) -> Any:
    path, mp = _bag(tmp, mapping=BAG_MAPPING.replace("/imu/data", "/imu/raw"))
    return import_bag(path, mp)


def bag_wrong_type(tmp: Path) -> Any:
    path, mp = _bag(tmp, mapping='[imu]\ntopic = "/vicon/pose"\n')
    return import_bag(path, mp)


def bag_empty_topic(tmp: Path) -> Any:
    topics = bag_topics(sample_signals())
    topics["/imu/data"] = ("imu", [])
    path, mp = _bag(tmp, topics=topics)
    return import_bag(path, mp)


def bag_nan_in_imu(tmp: Path) -> Any:
    topics = bag_topics(sample_signals())
    topics["/imu/data"][1][7][1]["gz"] = float("nan")
    path, mp = _bag(tmp, ros=2, topics=topics)
    return import_bag(path, mp)


def bag_nonmonotonic_stamps(tmp: Path) -> Any:
    sig = sample_signals()
    sig["to"] = sig["to"].copy()
    sig["to"][4] = sig["to"][2] - 0.01  # header stamp earlier than its predecessors
    path = write_bag(tmp / "b.bag", 1, bag_topics(sig), receive_in_list_order=True)
    return import_bag(path, write_mapping(tmp, BAG_MAPPING))


def bag_duplicated_stamps(tmp: Path) -> Any:
    sig = sample_signals()
    sig["ti"] = sig["ti"].copy()
    sig["ti"][11] = sig["ti"][10]
    path = write_bag(tmp / "b.bag", 1, bag_topics(sig), receive_in_list_order=True)
    return import_bag(path, write_mapping(tmp, BAG_MAPPING))


def bag_missing_joint(tmp: Path) -> Any:
    path, mp = _bag(tmp, mapping=BAG_MAPPING.replace('"rear_left_wheel"', '"middle_left_wheel"'))
    return import_bag(path, mp)


def bag_rpm_as_rad_s(tmp: Path) -> Any:
    path = tmp / "b.bag"
    write_bag(path, 1, bag_topics(sample_signals(), wheel_scale=60 / (2 * math.pi)))
    return import_bag(path, write_mapping(tmp, BAG_MAPPING))


def bag_file_missing(tmp: Path) -> Any:
    return import_bag(tmp / "nothing.bag", write_mapping(tmp, BAG_MAPPING))


# ------------------------------------------------------------------------------------------
# Specs and mappings
# ------------------------------------------------------------------------------------------
def mapping_unknown_platform(tmp: Path) -> Any:
    return import_csv(tmp / "x.csv", write_mapping(tmp, '[platform]\nname = "p3at_hover"\n'))


def mapping_bad_unit(tmp: Path) -> Any:
    return load_mapping(write_mapping(tmp, '[imu]\ngyro_unit = "rpm"\n'))


def scenario_unknown_platform(tmp: Path) -> Any:
    p = tmp / "my_scenario.toml"
    p.write_text('platform = "p3at_hover"\nterrain = "vinyl"\nduration = 10.0\n'
                 '[command]\nkind = "rotation"\n')
    return load_scenario(p, root=SCENARIO_DIR)


Case = tuple[Callable[[Path], Any], type, tuple[str, ...]]
CASES: dict[str, Case] = {
    "parquet truncated": (parquet_truncated, RunError, ("run.parquet", "'<file>'", "not a readable Parquet file")),
    "parquet garbage": (parquet_garbage, RunError, ("run.parquet", "not a readable Parquet file")),
    "parquet inf in a channel": (parquet_inf, RunError, ("run.parquet", "'imu_gz'", "row 3: inf", "finite")),
    "run non-monotonic t": (run_nonmonotonic, RunError, ("r1", "'t'", "row 3: ", "0.015", "after", "0.02", "non-monotonic")),
    "run duplicated t": (run_duplicated, RunError, ("r1", "'t'", "row 2: ", "0.01", "duplicated")),
    "run empty": (run_empty, RunError, ("empty_run", "'t'", "'empty'", "at least one sample")),
    "run missing channel": (run_missing_channel, RunError, ("r1", "'imu_gz'", "required by yi2009.ekf")),
    "run all-NaN channel": (run_all_nan_channel, RunError, ("r1", "'imu_gz'", "all NaN", "no sample")),
    "run wheel speed implausible for its platform": (run_wheel_speed_implausible, RunError, (
        "sim_42", "'enc_wr'", "180.0", "p3at_solid", "looks like deg/s")),
    "tum malformed row": (tum_malformed, RunError, ("traj.tum", "TUM rows must be 8 numbers")),
    "csv truncated": (csv_truncated, RunError, ("log.csv", "line 21", "expected 3 fields", "found 2", "truncated")),
    "csv extra field": (csv_extra_field, RunError, ("log.csv", "Expected 3 fields in line 3, saw 4", "malformed CSV")),
    "csv empty file": (csv_empty_file, RunError, ("log.csv", "empty file")),
    "csv header only (empty run)": (csv_header_only, RunError, ("log.csv", "'t'", "'empty'", "no rows")),
    "csv not a number": (csv_not_a_number, RunError, ("log.csv", "'wl'", "line 3: '1.2.3'", "expected a number")),
    "csv NaN": (csv_nan, RunError, ("log.csv", "'wl'", "line 4: 'NaN'", "NaN/inf is not a sample")),
    "csv inf": (csv_inf, RunError, ("log.csv", "'wr'", "line 3: '-inf'", "NaN/inf is not a sample")),
    "csv non-monotonic t": (csv_nonmonotonic, RunError, ("log.csv", "'t'", "line 6: 0.025 after 0.03", "non-monotonic")),
    "csv duplicated t": (csv_duplicated, RunError, ("log.csv", "'t'", "line 5: 0.02 after 0.02", "duplicated")),
    "csv missing timestamp": (csv_missing_time, RunError, ("log.csv", "'t'", "line 3: empty", "timestamp")),
    "csv missing column": (csv_missing_column, RunError, ("log.csv", "'wl'", "wheels.left", "columns: ['t', 'left', 'right']")),
    "csv rpm given as rad/s": (csv_rpm_as_rad_s, RunError, ("log.csv", "enc_wl (CSV column 'wl'", "unit = 'rad/s'",
                                                            "9.78 rad/s", "p3at_pneumatic_20psi", "looks like rpm",
                                                            "set unit = \"rpm\"")),
    "csv gyro deg/s given as rad/s": (csv_gyro_deg_as_rad, RunError, ("log.csv", "imu_gz (CSV column 'gz'",
                                                                       "looks like deg/s", "gyro_unit = \"deg/s\"")),
    "csv accelerometer in g": (csv_accel_in_g, RunError, ("log.csv", "imu_az", "9.81 m/s^2", "accel_unit = \"g\"")),
    "csv yaw in degrees": (csv_yaw_in_degrees, RunError, ("log.csv", "'heading'", "170.0", "gnss.yaw_unit = \"deg\"")),
    "csv file missing": (csv_file_missing, RunError, ("nope.csv", "file not found")),
    "bag truncated (ROS 1)": (bag_truncated_ros1, RunError, ("b.bag", "'<file>'", "not a readable ROS 1/ROS 2 bag")),
    "bag corrupt (ROS 2)": (bag_corrupt_ros2, RunError, ("b_ros2", "'<file>'", "not a readable ROS 1/ROS 2 bag")),
    "bag missing topic": (bag_missing_topic, RunError, ("b.bag", "'/imu/raw'", "imu.topic", "/imu/data")),
    "bag wrong message type": (bag_wrong_type, RunError, ("b.bag", "'/vicon/pose'", "geometry_msgs/msg/PoseStamped",
                                                          "sensor_msgs/msg/Imu")),
    "bag topic without messages (empty run)": (bag_empty_topic, RunError, ("b.bag", "'/imu/data'", "0 messages", "empty run")),
    "bag NaN in a message": (bag_nan_in_imu, RunError, ("b_ros2", "'/imu/data angular_velocity.z'", "'message 7: nan'", "NaN/inf")),
    "bag non-monotonic stamps": (bag_nonmonotonic_stamps, RunError, ("b.bag", "'/gnss/odom'", "message 4",
                                                                     "non-monotonic")),
    "bag duplicated stamps": (bag_duplicated_stamps, RunError, ("b.bag", "'/imu/data'", "message 11", "duplicated")),
    "bag missing joint": (bag_missing_joint, RunError, ("b.bag", "/joint_states name", "middle_left_wheel")),
    "bag rpm given as rad/s": (bag_rpm_as_rad_s, RunError, ("b.bag", "enc_wl (topic /joint_states", "looks like rpm")),
    "bag file missing": (bag_file_missing, RunError, ("nothing.bag", "file not found")),
    "mapping unknown platform": (mapping_unknown_platform, SpecError, ("mapping.toml", "'platform.name'", "p3at_hover",
                                                                       "unknown platform", "p3at_solid")),
    "mapping bad unit": (mapping_bad_unit, SpecError, ("mapping.toml", "'imu.gyro_unit'", "'rpm'", "deg/s")),
    "scenario unknown platform": (scenario_unknown_platform, SpecError, ("my_scenario.toml", "'platform'", "p3at_hover",
                                                                         "unknown platform")),
}


@pytest.mark.parametrize("name", list(CASES))
def test_bad_input_is_named(tmp_path: Path, name: str) -> None:
    fn, exc, parts = CASES[name]
    with pytest.raises(exc) as ei:
        fn(tmp_path)
    msg = str(ei.value)
    for part in parts:
        assert part in msg, f"{name}: {part!r} not in {msg!r}"


def test_nan_in_a_parquet_channel_means_no_sample(tmp_path: Path) -> None:
    """NaN is the Run's 'no sample' marker: it round-trips and is not an error."""
    g = np.array([0.1, np.nan, 0.3, np.nan, 0.5])
    run = Run.from_parquet(_small_run(imu_gz=g).to_parquet(tmp_path / "r.parquet")).validate()
    t, v = run.samples("imu_gz")
    assert np.array_equal(v, [0.1, 0.3, 0.5]) and np.array_equal(t, run.t[[0, 2, 4]])


def test_plausible_units_pass(tmp_path: Path) -> None:
    """The same logs with the right unit in the mapping import fine (the checks are not
    tripped by normal magnitudes)."""
    run = _csv(tmp_path, _wheel_csv(scale=60 / (2 * np.pi)), WHEEL_CSV_MAPPING + 'unit = "rpm"\n')
    assert np.allclose(run["enc_wl"][:3], 2.0 + 0.5 * np.sin(np.arange(3)))


# ------------------------------------------------------------------------------------------
# Property tests: spec loading
# ------------------------------------------------------------------------------------------
BASE = tomllib.loads((SCENARIO_DIR / "platforms" / "p3at_pneumatic_20psi.toml").read_text())


def _real(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _finite_real(v: Any) -> bool:
    try:
        return _real(v) and math.isfinite(float(v))
    except OverflowError:
        return False


FIELDS: dict[str, Callable[[Any], bool]] = {  # dotted field -> independent validity oracle
    "mass": lambda v: _finite_real(v) and 0.1 <= v <= 5e4,  # a wheeled robot's mass [kg]
    "track": lambda v: _finite_real(v) and 0.05 <= v <= 10,  # [m]
    "wheel_radius_scale_l": lambda v: _finite_real(v) and 0.5 < v < 1.5,
    "actuator_delay": lambda v: _finite_real(v) and 0 <= v < 2,
    "motor.pwm": lambda v: _finite_real(v) and 0 < v <= 1,
    "motor.motors_per_side": lambda v: isinstance(v, int) and not isinstance(v, bool) and v in (1, 2),
    "sensors.imu.rate_hz": lambda v: _finite_real(v) and 0 < v <= 1e4,  # no faster than the finest physics step
}

values = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(min_value=-10**6, max_value=10**6),
    st.sampled_from([0, 1, 2, 3, 0.5, 1.0, -0.0, 1e-300, 1e300]),
    st.booleans(), st.text(max_size=5), st.lists(st.floats(), max_size=2),
    st.dictionaries(st.text(max_size=3), st.integers(), max_size=1),
)


def _with(field_: str, value: Any) -> dict[str, Any]:
    data = {k: (dict(v) if isinstance(v, dict) else v) for k, v in BASE.items()}
    node = data
    parts = field_.split(".")
    for p in parts[:-1]:
        node[p] = dict(node.get(p, {}))
        node = node[p]
    node[parts[-1]] = value
    return data


@settings(max_examples=150, deadline=None)
@given(st.sampled_from(sorted(FIELDS)), values)
def test_spec_field_loads_or_names_the_field(field_: str, value: Any) -> None:
    data = _with(field_, value)
    if FIELDS[field_](value):
        spec = build(Platform, data, "p.toml")
        got: Any = spec
        for p in field_.split("."):
            got = getattr(got, p)
        assert got == value
    else:
        with pytest.raises(SpecError) as ei:
            build(Platform, data, "p.toml")
        assert ei.value.field == field_ and str(ei.value).startswith("p.toml: field ")


@settings(max_examples=100, deadline=None)
@given(st.text(min_size=1, max_size=8).filter(lambda s: s.isidentifier()), st.integers())
def test_spec_unknown_key_is_named(key: str, value: int) -> None:
    assume(key not in {f.name for f in dataclasses.fields(MotorSpec)})
    with pytest.raises(SpecError) as ei:
        build(Platform, _with(f"motor.{key}", value), "p.toml")
    assert ei.value.field == f"motor.{key}" and "unknown key" in str(ei.value)


if __name__ == "__main__":  # print every case's message (for reports)
    import tempfile

    for case, (fn, _, _) in CASES.items():
        with tempfile.TemporaryDirectory() as d:
            try:
                fn(Path(d))
                print(f"{case}: NO ERROR")
            except (RunError, SpecError) as e:
                print(f"{case}:\n    {type(e).__name__}: {str(e).replace(d, '<tmp>')}")


def test_noise_identification_needs_the_reference_noise_in_the_meta() -> None:
    """A run whose meta gives no reference position noise is an error naming the key (the noise
    identifications of the consistent filters subtract it), not a silently perfect reference."""
    import numpy as np

    from bench.run import RunError, from_arrays, reference_position_noise

    run = from_arrays({"t": np.arange(3) * 0.1}, {"run_id": "imported"})
    with pytest.raises(RunError) as ei:
        reference_position_noise(run)
    assert "platform.sensors.reference.pos_noise" in str(ei.value) and "imported" in str(ei.value)
    ok = from_arrays({"t": np.arange(3) * 0.1}, {"platform": {"sensors": {"reference": {"pos_noise": 0.003}}}})
    assert reference_position_noise(ok) == 0.003


@pytest.mark.parametrize("meta, expect", [
    ({}, None),  # no platform
    ({"platform": None}, None),  # an imported log's null platform
    ({"platform": {"sensors": None}}, None),
    ({"platform": {"sensors": {"encoder": {"counts_per_rev": 2000}}}}, None),  # rate absent
    ({"platform": {"sensors": {"encoder": {"counts_per_rev": 2000, "rate_hz": float("nan")}}}}, None),
    ({"platform": {"sensors": {"encoder": {"counts_per_rev": True, "rate_hz": 100.0}}}}, None),  # a bool
    ({"platform": {"sensors": {"encoder": {"counts_per_rev": 0, "rate_hz": 100.0}}}}, None),
    ({"platform": {"sensors": {"encoder": {"counts_per_rev": 2000, "rate_hz": 100.0}}}}, 2 * math.pi * 100 / 2000),
])
def test_encoder_count_speed_reads_the_spec_or_gives_none(meta: dict, expect: float | None) -> None:
    """One count per sample as a wheel speed, 2 pi rate / counts_per_rev (closed form: 0.3142 rad/s at 2000
    counts/rev and 100 Hz), read by Yi's quantisation floor and Yu's start-at-rest test alike; an absent, null,
    non-finite, boolean or non-positive value gives None instead of an AttributeError deep in a method."""
    from bench.run import encoder_count_speed

    run = from_arrays({"t": np.arange(3) * 0.1}, meta)
    got = encoder_count_speed(run)
    assert got == expect if expect is None else got == pytest.approx(expect, rel=1e-15)


def test_bad_spec_values_are_named_with_the_value_found() -> None:
    """The reference noise and IMU saturation readers name the key and the value they found (a string, a negative
    number), not a None from the conversion."""
    from bench.robustness.faults import imu_saturation
    from bench.run import reference_position_noise

    run = from_arrays({"t": np.arange(3) * 0.1}, {"run_id": "imported", "platform": {"sensors": {
        "reference": {"pos_noise": "3 mm"}, "imu": {"saturation_accel": -1.0, "saturation_gyro": 8.0}}}})
    with pytest.raises(RunError, match=r"pos_noise.*3 mm"):
        reference_position_noise(run)
    with pytest.raises(RunError, match=r"saturation_accel.*-1\.0"):
        imu_saturation(run)


def test_a_platform_path_in_a_mapping_is_read_beside_the_mapping(tmp_path, monkeypatch):
    """`name = "robot.toml"` in a mapping names the file next to it, whatever the working directory (a new user's
    first try; it was resolved from the working directory)."""
    d = tmp_path / "lab"
    d.mkdir()
    spec = (SCENARIO_DIR / "platforms" / "p3at_pneumatic_20psi.toml").read_text()
    (d / "robot.toml").write_text(spec.replace('name = "p3at_pneumatic_20psi"', 'name = "lab_robot"', 1))
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    run = _csv(d, _wheel_csv(), WHEEL_CSV_MAPPING.replace('"p3at_pneumatic_20psi"', '"robot.toml"'))
    assert run.meta["platform"]["name"] == "lab_robot"


@pytest.mark.parametrize("load, what", [("load_platform", "platform"), ("load_terrain", "terrain")])
def test_an_unknown_name_lists_the_known_ones(load, what):
    import bench.spec as S

    with pytest.raises(SpecError) as exc:
        getattr(S, load)("no_such_thing")
    msg = str(exc.value)
    assert f"unknown {what}" in msg and "no_such_thing" in msg and ("husky" in msg or "vinyl" in msg)
