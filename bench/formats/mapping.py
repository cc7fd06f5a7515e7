"""The import mapping: a TOML file naming, per Run channel group, the CSV columns or the bag topic
and the units the log uses (:class:`ImportMapping`, :func:`load_mapping`; the format is in the
docstring of :mod:`bench.formats`), the unit tables that convert them to SI, and the mapping's
platform.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from bench.schema import read_toml
from bench.spec import Platform, SpecError, build, load_platform

__all__ = ["G0", "TimeMap", "WheelMap", "ImuMap", "PoseMap", "DatumMap", "PlatformMap", "ImportMapping", "load_mapping"]

G0 = 9.80665

_TIME_UNITS = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
_WHEEL_UNITS = ("rad/s", "rpm", "deg/s", "m/s")
_GYRO_UNITS = {"rad/s": 1.0, "deg/s": math.pi / 180.0}
_ACCEL_UNITS = {"m/s^2": 1.0, "g": G0}
_POS_UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001}
_ANGLE_UNITS = {"rad": 1.0, "deg": math.pi / 180.0}
_NAVSAT_VELOCITY = ("none", "fix_difference")
_NAVSAT_HEADING = ("none", "course")


@dataclass(frozen=True)
class TimeMap:
    column: str = "t"  # CSV column
    unit: str = "s"
    source: str = "header"  # bags: header stamp or bag receive time
    _checks = {
        "unit": (lambda x: x in _TIME_UNITS, f"one of {sorted(_TIME_UNITS)}"),
        "source": (lambda x: x in ("header", "receive"), "'header' or 'receive'"),
        "column": (lambda x: x != "", "a column name"),
    }


@dataclass(frozen=True)
class WheelMap:
    """Wheel speeds of the left/right side (both wheels of a side share one speed)."""

    left: str = ""  # CSV columns
    right: str = ""
    # bags: sensor_msgs/JointState; [wheels] also nav_msgs/Odometry, [commands] geometry_msgs/Twist(Stamped)
    topic: str = ""
    left_joints: tuple[str, ...] = ()
    right_joints: tuple[str, ...] = ()
    unit: str = "rad/s"
    wheel_radius: float = 0.0  # [m], for unit m/s and a twist topic; 0 = the platform's
    track: float = 0.0  # [m], for a twist topic (Odometry, Twist): v, omega -> wheel speeds; 0 = the platform's
    invert_left: bool = False
    invert_right: bool = False
    _checks = {
        "unit": (lambda x: x in _WHEEL_UNITS, f"one of {list(_WHEEL_UNITS)}"),
        "wheel_radius": (lambda x: 0 <= x < 5 and math.isfinite(x), "in [0, 5) m (0 = platform's)"),
        "track": (lambda x: 0 <= x < 20 and math.isfinite(x), "in [0, 20) m (0 = platform's)"),
    }

    @property
    def used(self) -> bool:
        return bool(self.left or self.right or self.topic)


@dataclass(frozen=True)
class ImuMap:
    topic: str = ""  # bags: sensor_msgs/Imu
    ax: str = ""  # CSV columns
    ay: str = ""
    az: str = ""
    gx: str = ""
    gy: str = ""
    gz: str = ""
    accel_unit: str = "m/s^2"
    gyro_unit: str = "rad/s"
    _checks = {
        "accel_unit": (lambda x: x in _ACCEL_UNITS, f"one of {sorted(_ACCEL_UNITS)}"),
        "gyro_unit": (lambda x: x in _GYRO_UNITS, f"one of {sorted(_GYRO_UNITS)}"),
    }

    @property
    def used(self) -> bool:
        return bool(self.topic or any((self.ax, self.ay, self.az, self.gx, self.gy, self.gz)))


@dataclass(frozen=True)
class PoseMap:
    """A planar pose source (GNSS/odometry, external reference or ground truth)."""

    topic: str = ""  # bags: nav_msgs/Odometry, geometry_msgs/PoseStamped(WithCovarianceStamped), sensor_msgs/NavSatFix
    x: str = ""  # CSV columns
    y: str = ""
    yaw: str = ""
    vx: str = ""
    vy: str = ""
    wz: str = ""
    position_unit: str = "m"  # also for vx, vy (per second)
    yaw_unit: str = "rad"  # also for wz (per second)
    velocity_frame: str = "body"  # CSV vx, vy given in the body or the world frame
    yaw_unwrapped: bool = False  # True: yaw may exceed +-pi (skips the degrees check)
    # bags, sensor_msgs/NavSatFix topics only (a fix has a position, no heading and no velocity):
    velocity: str = "none"  # "fix_difference": world-frame gnss_vx, gnss_vy from the fixes' ENU track ([gnss] only)
    heading: str = "none"  # "course": yaw = the course over ground of that track, where it is >= course_min_speed
    course_min_speed: float = 0.2  # [m/s] below it the course is undefined (at rest): no yaw sample
    _checks = {
        "velocity": (lambda x: x in _NAVSAT_VELOCITY, f"one of {list(_NAVSAT_VELOCITY)}"),
        "heading": (lambda x: x in _NAVSAT_HEADING, f"one of {list(_NAVSAT_HEADING)}"),
        "course_min_speed": (lambda x: 0 < x < 100 and math.isfinite(x), "in (0, 100) m/s"),
        "position_unit": (lambda x: x in _POS_UNITS, f"one of {sorted(_POS_UNITS)}"),
        "yaw_unit": (lambda x: x in _ANGLE_UNITS, f"one of {sorted(_ANGLE_UNITS)}"),
        "velocity_frame": (lambda x: x in ("body", "world"), "'body' or 'world'"),
    }

    @property
    def used(self) -> bool:
        return bool(self.topic or self.x or self.y or self.yaw)


@dataclass(frozen=True)
class PlatformMap:
    name: str = ""  # scenarios/platforms/<name>.toml
    max_wheel_speed: float = 0.0  # [rad/s] override of the motor-derived limit; 0 = derive
    _checks = {"max_wheel_speed": (lambda x: 0 <= x < 1e4 and math.isfinite(x), "in [0, 1e4) rad/s")}


@dataclass(frozen=True)
class DatumMap:
    """The origin of the local ENU frame (x east, y north) of every sensor_msgs/NavSatFix topic, WGS-84; all NaN
    (the section left out) = the first fix with status >= STATUS_FIX of the NavSatFix topics, by time."""

    latitude_deg: float = math.nan
    longitude_deg: float = math.nan
    altitude: float = math.nan  # [m] above the WGS-84 ellipsoid; NaN = the first fix's (0 if it has none)
    _checks = {
        "latitude_deg": (lambda x: -90 <= x <= 90, "a latitude in [-90, 90] deg"),
        "longitude_deg": (lambda x: -180 <= x <= 180, "a longitude in [-180, 180] deg"),
        "altitude": (lambda x: -1e4 < x < 1e5, "an ellipsoidal height in (-1e4, 1e5) m"),
    }

    @property
    def used(self) -> bool:
        return not (math.isnan(self.latitude_deg) and math.isnan(self.longitude_deg) and math.isnan(self.altitude))


@dataclass(frozen=True)
class ImportMapping:
    run_id: str = ""
    nan_policy: str = "error"  # error | drop (a NaN/inf sample becomes "no sample")
    time: TimeMap = field(default_factory=TimeMap)
    platform: PlatformMap = field(default_factory=PlatformMap)
    wheels: WheelMap = field(default_factory=WheelMap)
    commands: WheelMap = field(default_factory=WheelMap)
    imu: ImuMap = field(default_factory=ImuMap)
    gnss: PoseMap = field(default_factory=PoseMap)
    reference: PoseMap = field(default_factory=PoseMap)
    truth: PoseMap = field(default_factory=PoseMap)
    datum: DatumMap = field(default_factory=DatumMap)
    source_file: str = ""
    _checks = {"nan_policy": (lambda x: x in ("error", "drop"), "'error' or 'drop'")}


_POSE_PREFIX = {"gnss": "gnss", "reference": "ref", "truth": "truth"}
_WHEEL_PREFIX = {"wheels": "enc", "commands": "cmd"}


def load_mapping(path: str | Path) -> ImportMapping:
    """Parse and validate a mapping TOML (unknown keys, wrong types and units raise
    :class:`SpecError` naming the file and the dotted field)."""
    path = Path(path)
    data = dict(read_toml(path, "mapping file"), source_file=str(path))
    return build(ImportMapping, data, path)


def _as_mapping(mapping: ImportMapping | str | Path) -> ImportMapping:
    return mapping if isinstance(mapping, ImportMapping) else load_mapping(mapping)


def _platform(mapping: ImportMapping) -> Platform | None:
    name = mapping.platform.name
    if not name:
        return None
    if name.lower().endswith(".toml") and mapping.source_file and not Path(name).is_absolute():
        name = str(Path(mapping.source_file).parent / name)  # a path in the mapping is relative to the mapping file
    try:
        return load_platform(name)
    except SpecError as exc:
        if exc.field not in ("<file>", "platform"):  # a missing file, an unknown name: named after the mapping
            raise
        from bench.spec import registered

        known = registered("platform")
        raise SpecError(mapping.source_file or "<mapping>", "platform.name", name,
                        f"unknown platform; known: {known}") from None


def _wheel_factor(wm: WheelMap, section: str, platform: Platform | None, mapping: ImportMapping) -> float:
    if wm.unit == "rad/s":
        return 1.0
    if wm.unit == "rpm":
        return 2.0 * math.pi / 60.0
    if wm.unit == "deg/s":
        return math.pi / 180.0
    r = wm.wheel_radius or (platform.wheel_radius if platform else 0.0)
    if r <= 0:
        raise SpecError(mapping.source_file or "<mapping>", f"{section}.wheel_radius", wm.wheel_radius,
                        "unit m/s needs the wheel radius (here or via platform.name)")
    return 1.0 / r


def _mapping_meta(mp: ImportMapping) -> dict[str, Any]:
    """The mapping as metadata (strict JSON: a NaN "not given", as of the datum, becomes None)."""
    def clean(v: Any) -> Any:
        if isinstance(v, dict):
            return {k: clean(x) for k, x in v.items()}
        if isinstance(v, float) and not math.isfinite(v):
            return None
        return v

    return clean(asdict(mp))
