"""The sensor specs of a platform: encoders, IMU, GNSS and the paper's reference sensor (part of
:class:`bench.spec.Platform`, importable from :mod:`bench.spec`).  Rates in Hz, noise in SI units (standard
deviations), as :mod:`bench.sim.sensors` draws them."""
from __future__ import annotations

import math
import types
from dataclasses import dataclass, field

from bench.schema import nonneg, positive

__all__ = ["EncoderSpec", "ImuSpec", "GnssSpec", "ReferenceSpec", "SensorSpec"]

MAX_RATE_HZ = 10_000.0  # the testbed's fastest physics step is 1e-4 s (Scenario.dt): no sensor samples faster
SENSOR_RATE_RANGE = f"in (0, {MAX_RATE_HZ:g}] Hz"


def sensor_rate(x: float) -> bool:
    """A sampling rate [Hz]: > 0 and at most MAX_RATE_HZ (1e9 Hz would ask for gigabytes of samples)."""
    return 0 < x <= MAX_RATE_HZ


@dataclass(frozen=True)
class EncoderSpec:
    counts_per_rev: int = 8192  # Wang 2015 Sec. 3.2 (at the wheel)
    rate_hz: float = 100.0
    scale_error_l: float = 0.0  # fractional scale error of the left encoder (gap catalogue)
    scale_error_r: float = 0.0
    # [s] the wheel-speed channel reports late: the sample at t is the count difference of the wheel angles at
    # t - latency - 1/rate and t - latency (driver buffering, filtering, transport; gap catalogue)
    latency: float = 0.0
    _checks = {
        "counts_per_rev": (lambda x: x > 0, "> 0"),
        "rate_hz": (sensor_rate, SENSOR_RATE_RANGE),
        "scale_error_l": (lambda x: abs(x) < 0.5, "|x| < 0.5"),
        "scale_error_r": (lambda x: abs(x) < 0.5, "|x| < 0.5"),
        "latency": (lambda x: 0 <= x <= 2 and math.isfinite(x), "in [0, 2] s"),
    }


@dataclass(frozen=True)
class ImuSpec:
    rate_hz: float = 125.0  # Yi 2009 Sec. VI
    accel_noise: float = 0.02  # white noise std per sample [m/s^2]
    gyro_noise: float = 0.002  # [rad/s]
    accel_bias_walk: float = 1e-4  # bias random walk std per sqrt(s) [m/s^2/sqrt(s)]
    gyro_bias_walk: float = 1e-5  # [rad/s/sqrt(s)]
    gyro_bias_z: float = 0.0  # constant gyro z bias [rad/s] (gap catalogue)
    saturation_accel: float = 80.0
    saturation_gyro: float = 8.0
    # mounting (gap catalogue; bench.sim.sensors.imu_mounting): the gyro's z gain (-1: mounted upside down),
    # the sensor axes turned by yaw_misalignment [rad] about z, the sensor at (lever_x, lever_y) [m] from the CoM
    gyro_scale_z: float = 1.0
    yaw_misalignment: float = 0.0
    lever_x: float = 0.0
    lever_y: float = 0.0
    _checks = {k: (nonneg, ">= 0") for k in ("accel_noise", "gyro_noise", "accel_bias_walk", "gyro_bias_walk")} | {
        "rate_hz": (sensor_rate, SENSOR_RATE_RANGE),
        "saturation_accel": (positive, "> 0"),
        "saturation_gyro": (positive, "> 0"),
        "gyro_bias_z": (lambda x: abs(x) < 1, "|x| < 1 rad/s"),
        "gyro_scale_z": (lambda x: abs(x) <= 2, "|x| <= 2"),
        "yaw_misalignment": (lambda x: abs(x) <= math.pi, "|x| <= pi rad"),
        "lever_x": (lambda x: abs(x) <= 2, "|x| <= 2 m"),
        "lever_y": (lambda x: abs(x) <= 2, "|x| <= 2 m"),
    }


@dataclass(frozen=True)
class GnssSpec:
    rate_hz: float = 5.0
    pos_noise: float = 0.02  # [m]
    vel_noise: float = 0.02  # [m/s]
    yaw_noise: float = 0.01  # [rad]
    drift_walk: float = 0.0  # random walk of the position error [m/sqrt(s)] (Liu: initial drift)
    initial_drift: float = 0.0  # [m] offset at t = 0 decaying with drift_tau
    drift_tau: float = 30.0  # [s]
    dropout_prob: float = 0.0  # probability a sample is missing
    outages: tuple[tuple[float, float], ...] = ()  # [(t_start, t_end), ...] with no fix
    _checks = {
        "rate_hz": (sensor_rate, SENSOR_RATE_RANGE),
        "pos_noise": (nonneg, ">= 0"),
        "vel_noise": (nonneg, ">= 0"),
        "yaw_noise": (nonneg, ">= 0"),
        "drift_walk": (nonneg, ">= 0"),
        "initial_drift": (nonneg, ">= 0"),
        "drift_tau": (positive, "> 0"),
        "dropout_prob": (lambda x: 0 <= x < 1, "in [0, 1)"),
    }


@dataclass(frozen=True)
class ReferenceSpec:
    """External 'ground-truth' sensor of a paper: vision (Yi), laser (Wang), DGPS (Liu)."""

    kind: str = "laser"
    rate_hz: float = 135.0
    pos_noise: float = 0.003  # [m]
    yaw_noise: float = 0.002  # [rad]
    _checks = {
        "kind": (lambda x: x in ("vision", "laser", "dgps", "mocap", "icp"), "one of vision, laser, dgps, mocap, icp"),
        "rate_hz": (sensor_rate, SENSOR_RATE_RANGE),
        "pos_noise": (nonneg, ">= 0"),
        "yaw_noise": (nonneg, ">= 0"),
    }


@dataclass(frozen=True)
class SensorSpec:
    encoder: EncoderSpec = field(default_factory=EncoderSpec)
    imu: ImuSpec = field(default_factory=ImuSpec)
    gnss: GnssSpec = field(default_factory=GnssSpec)
    reference: ReferenceSpec = field(default_factory=ReferenceSpec)


_ = types  # keep import for type evaluation of PEP 604 unions on 3.11
