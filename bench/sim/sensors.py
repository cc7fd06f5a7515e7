"""Sensors of the testbed, synthesised after the physics run from its trace (vectorised).

Each sensor has its own rate and its own random stream (``numpy.random.SeedSequence(seed)``
spawned once per sensor in a fixed order), so the same seed gives the same numbers whatever the
order sensors are evaluated in, serial or parallel.

* Encoders: wheel angle quantised to ``counts_per_rev``; speed = count difference / period
  (Wang 2015: 8192 counts/rev).  Optional scale error and latency (gap catalogue): with latency L the sample
  at t counts the wheel angles at t - L - 1/rate and t - L (:func:`encoder_angles`).
* IMU at the centre of mass: specific force ``R^T (a - g)`` and body rates, white noise plus a
  bias random walk, saturation (Yi 2009: 125 Hz).  Optional mounting (gap catalogue): lever arm from the CoM,
  yaw misalignment of the axes, gyro z gain (:func:`imu_mounting`).
* GNSS (antenna at the CoM): position, velocity, dual-antenna heading; white noise, a decaying
  initial drift and a random walk (Liu 2020 describes the initial drift), random dropouts and
  scheduled outages (NaN).
* Reference sensor of the paper (vision 1.49 cm, laser 3 mm, DGPS 1 cm at 5 Hz): pose of the
  geometric centre with white noise.
"""
from __future__ import annotations

import math

import numpy as np

from bench.spec import Scenario

SENSOR_STREAMS = ("encoder", "imu", "gnss", "reference")


def sample_times(rate_hz: float, duration: float) -> np.ndarray:
    """Integer-microsecond sample times k / rate in [0, duration]."""
    n = int(math.floor(duration * rate_hz + 1e-9))
    return np.round(np.arange(n + 1) * (1e6 / rate_hz)).astype(np.int64)


def streams(seed: int) -> dict[str, np.random.Generator]:
    children = np.random.SeedSequence(seed).spawn(len(SENSOR_STREAMS))
    return {name: np.random.default_rng(ss) for name, ss in zip(SENSOR_STREAMS, children)}


def encoder_angles(t: np.ndarray, t_phys: np.ndarray, theta: np.ndarray, w0: float, latency: float) -> np.ndarray:
    """Wheel angles [rad] an encoder with ``latency`` [s] reports at sample times ``t``: the physics-rate angle
    ``theta`` (times ``t_phys``) at ``t - latency``, linearly interpolated.  Before the trace begins the wheel turns
    at its initial speed ``w0`` [rad/s] (a run starts in a steady state: at rest, or moving as
    :mod:`bench.sim.startup` sets it up).  Latency 0 is plain interpolation at ``t``, bit for bit."""
    if latency == 0.0:
        return np.interp(t, t_phys, theta)
    tq = np.asarray(t, float) - latency
    out = np.interp(tq, t_phys, theta)
    before = tq < t_phys[0]
    out[before] = theta[0] + w0 * (tq[before] - t_phys[0])
    return out


def encoders(t: np.ndarray, theta_l: np.ndarray, theta_r: np.ndarray, scn: Scenario,
             rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Quantised encoder speeds (rad/s) at times t from wheel angles at those times: count differences over the
    sample period.  Each wheel's count origin is an independent uniform phase within one count (drawn from
    ``rng``): a disc's edges are not aligned with the wheel's starting angle, so a wheel at rest on an edge does not
    tick from creep, and two wheels turning at related speeds do not quantise in lockstep."""
    spec = scn.platform.sensors.encoder
    q = 2.0 * math.pi / spec.counts_per_rev
    phase = rng.uniform(0.0, 1.0, 2)
    out = []
    for theta, scale, u in ((theta_l, spec.scale_error_l, phase[0]), (theta_r, spec.scale_error_r, phase[1])):
        counts = np.floor(theta * (1.0 + scale) / q + u)
        speed = np.diff(counts, prepend=counts[0]) * q / np.diff(t, prepend=t[0] - 1.0 / spec.rate_hz)
        out.append(speed)
    return out[0], out[1]


def yaw_acceleration(t: np.ndarray, t_phys: np.ndarray, wz: np.ndarray) -> np.ndarray:
    """The yaw acceleration [rad/s^2] at times ``t``: the physics-rate yaw rate ``wz`` (times ``t_phys``)
    differentiated (central differences) and interpolated; zero for a trace of one step."""
    if t_phys.size < 2:
        return np.zeros(np.asarray(t).size)
    return np.interp(t, t_phys, np.gradient(wz, t_phys))


def imu_mounting(fx: np.ndarray, fy: np.ndarray, wz: np.ndarray, alpha_z: np.ndarray, yaw_misalignment: float,
                 lever_x: float, lever_y: float) -> tuple[np.ndarray, np.ndarray]:
    """Planar specific force ``(fx, fy)`` [m/s^2] an accelerometer reads when mounted at ``(lever_x, lever_y)`` [m]
    from the centre of mass (body axes) with its axes turned by ``yaw_misalignment`` [rad] about z, from the CoM's
    body-frame specific force ``(fx, fy)``, yaw rate ``wz`` and yaw acceleration ``alpha_z``.

    Rigid body, rotation about z only: a_P = a_CoM + alpha x r + w x (w x r), i.e. x: -wz^2 lx - alpha ly,
    y: -wz^2 ly + alpha lx; then the sensor's axes: f_s = R(psi)^T f_b.  Roll and pitch rates are neglected
    (planar driving).  Identity, bit for bit, at zero lever and misalignment."""
    if lever_x or lever_y:
        w2 = wz * wz
        fx, fy = fx - w2 * lever_x - alpha_z * lever_y, fy - w2 * lever_y + alpha_z * lever_x
    if yaw_misalignment:
        c, s = math.cos(yaw_misalignment), math.sin(yaw_misalignment)
        fx, fy = c * fx + s * fy, -s * fx + c * fy
    return fx, fy


def imu(t: np.ndarray, f_body: np.ndarray, w_body: np.ndarray, scn: Scenario, rng: np.random.Generator,
        alpha_z: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(accel (n,3), gyro (n,3)) with white noise, bias random walk and saturation; mounted as the spec says
    (:func:`imu_mounting`, gyro z gain ``gyro_scale_z``; ``alpha_z``, the yaw acceleration at ``t``, is needed
    only for a lever arm)."""
    spec = scn.platform.sensors.imu
    if (spec.lever_x or spec.lever_y) and alpha_z is None:
        raise ValueError("an IMU lever arm needs the yaw acceleration alpha_z at the sample times")
    if spec.lever_x or spec.lever_y or spec.yaw_misalignment:
        fx, fy = imu_mounting(f_body[:, 0], f_body[:, 1], w_body[:, 2],
                              alpha_z if alpha_z is not None else np.zeros(t.size),
                              spec.yaw_misalignment, spec.lever_x, spec.lever_y)
        f_body = np.column_stack([fx, fy, f_body[:, 2]])
    if spec.gyro_scale_z != 1.0:
        w_body = np.column_stack([w_body[:, 0], w_body[:, 1], spec.gyro_scale_z * w_body[:, 2]])
    n = t.size
    dt = 1.0 / spec.rate_hz
    acc_bias = np.cumsum(rng.normal(0.0, spec.accel_bias_walk * math.sqrt(dt), (n, 3)), axis=0)
    gyr_bias = np.cumsum(rng.normal(0.0, spec.gyro_bias_walk * math.sqrt(dt), (n, 3)), axis=0)
    gyr_bias[:, 2] += spec.gyro_bias_z
    acc = f_body + acc_bias + rng.normal(0.0, spec.accel_noise, (n, 3))
    gyr = w_body + gyr_bias + rng.normal(0.0, spec.gyro_noise, (n, 3))
    return (np.clip(acc, -spec.saturation_accel, spec.saturation_accel),
            np.clip(gyr, -spec.saturation_gyro, spec.saturation_gyro))


def gnss(t: np.ndarray, xy: np.ndarray, vxy: np.ndarray, yaw: np.ndarray, scn: Scenario,
         rng: np.random.Generator) -> dict[str, np.ndarray]:
    spec = scn.platform.sensors.gnss
    n = t.size
    dt = 1.0 / spec.rate_hz
    direction = rng.uniform(0, 2 * math.pi)
    drift = spec.initial_drift * np.exp(-t / spec.drift_tau)[:, None] * np.array([math.cos(direction), math.sin(direction)])
    drift = drift + np.cumsum(rng.normal(0.0, spec.drift_walk * math.sqrt(dt), (n, 2)), axis=0)
    pos = xy + drift + rng.normal(0.0, spec.pos_noise, (n, 2))
    vel = vxy + rng.normal(0.0, spec.vel_noise, (n, 2))
    hdg = np.angle(np.exp(1j * (yaw + rng.normal(0.0, spec.yaw_noise, n))))
    missing = rng.random(n) < spec.dropout_prob
    for t0, t1 in spec.outages:
        missing |= (t >= t0) & (t < t1)
    out = {"gnss_x": pos[:, 0], "gnss_y": pos[:, 1], "gnss_vx": vel[:, 0], "gnss_vy": vel[:, 1], "gnss_yaw": hdg}
    return {k: np.where(missing, np.nan, v) for k, v in out.items()}


def reference(t: np.ndarray, xy: np.ndarray, yaw: np.ndarray, scn: Scenario, rng: np.random.Generator
              ) -> dict[str, np.ndarray]:
    spec = scn.platform.sensors.reference
    n = t.size
    pos = xy + rng.normal(0.0, spec.pos_noise, (n, 2))
    hdg = np.angle(np.exp(1j * (yaw + rng.normal(0.0, spec.yaw_noise, n))))
    return {"ref_x": pos[:, 0], "ref_y": pos[:, 1], "ref_yaw": hdg}
