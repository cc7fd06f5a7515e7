"""The named catalogue of candidate missing effects.

Each :class:`Effect` is a small augmentation of the nominal model: a physical meaning, one or
two parameters with bounds and units, the spec field(s) they set (the same fields a user changes
with ``skidbench simulate --set``), the channels it mainly affects and its signature (how it shows
in the residuals; used by a reader, the selection relies on the fits).

Kinds:

* ``physics``: changes the testbed's physics; evaluating it needs a simulation.
* ``sensor``: a deterministic sensor error; applied to the model's noise-free signals without
  re-simulating (encoder scale error and latency, gyro bias, gyro scale, IMU mounting).
* ``delay``: actuator delay; simulated (the testbed delays the PID reference), screened on a
  time-shift surrogate of the nominal signals and fitted over the testbed's physics steps.

``neutral(scn)`` gives the parameter values that reproduce the nominal model (the effect "off");
``None`` for an effect that changes a model structure (shear-displacement friction on a Coulomb
terrain), which is screened on a grid instead.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping

from bench.spec import Scenario


@dataclass(frozen=True)
class Param:
    """One effect parameter: name, unit, bounds, probe step (absolute, in the parameter's unit)."""

    name: str
    unit: str
    lower: float
    upper: float
    step: float
    log: bool = False  # fitted in log10 (a scale parameter spanning decades)
    mirror: bool = False  # part of the response is even in (value - neutral): refine from both signs


@dataclass(frozen=True)
class ModelConfig:
    """A model = nominal spec + physics overrides + sensor errors + time shift (surrogate)."""

    overrides: tuple[tuple[str, Any], ...] = ()
    enc_scale: tuple[float, float] = (0.0, 0.0)
    gyro_bias: float = 0.0
    shift: float = 0.0
    enc_latency: float = 0.0  # [s] the encoders report late (EncoderSpec.latency)
    gyro_scale: float = 1.0  # gyro z gain (ImuSpec.gyro_scale_z; -1: upside down)
    imu_mount: tuple[float, float, float] = (0.0, 0.0, 0.0)  # (yaw misalignment [rad], lever x, y [m]) (ImuSpec)

    def with_overrides(self, **kv: Any) -> "ModelConfig":
        d = dict(self.overrides)
        d.update(kv)
        return dataclasses.replace(self, overrides=tuple(sorted(d.items())))

    def replace(self, **kv: Any) -> "ModelConfig":
        return dataclasses.replace(self, **kv)


@dataclass(frozen=True)
class Effect:
    name: str
    title: str
    meaning: str
    params: tuple[Param, ...]
    channels: tuple[str, ...]
    signature: str
    kind: str  # physics | sensor | delay
    _neutral: Callable[[Scenario], tuple[float, ...] | None] = field(repr=False, compare=False)
    _apply: Callable[[Scenario, ModelConfig, tuple[float, ...]], ModelConfig] = field(repr=False, compare=False)
    _spec: Callable[[Scenario, tuple[float, ...]], dict[str, Any]] = field(repr=False, compare=False)
    probe_grid: tuple[tuple[float, ...], ...] = ()  # screening points when there is no neutral value
    # whether the testbed can model this effect on a scenario (the slope: not on rough ground, bench.sim.ground)
    _modelled_on: Callable[[Scenario], bool] = field(default=lambda s: True, repr=False, compare=False)
    # limits the scenario's geometry puts on the parameters, (lower, upper) each, within the Params' own bounds
    _limits: Callable[[Scenario], tuple[tuple[float, float], ...]] | None = field(default=None, repr=False,
                                                                                   compare=False)

    @property
    def n_params(self) -> int:
        return len(self.params)

    def __reduce__(self):  # pickled by name (process pools): the catalogue is code, not data
        return (get, (self.name,))

    def neutral(self, scn: Scenario) -> tuple[float, ...] | None:
        return self._neutral(scn)

    def modelled_on(self, scn: Scenario) -> bool:
        """Whether the testbed can simulate this effect on ``scn``'s ground (otherwise it is not a candidate)."""
        return self._modelled_on(scn)

    def bounds(self, scn: Scenario | None = None) -> tuple[tuple[float, float], ...]:
        """(lower, upper) of each parameter: the Params' bounds, narrowed on ``scn`` by the limits its geometry sets
        (the centre of mass between the axles and within the track: :meth:`bench.spec.Platform._check_whole`)."""
        own = tuple((p.lower, p.upper) for p in self.params)
        if scn is None or self._limits is None:
            return own
        out = tuple((max(lo, a), min(hi, b)) for (lo, hi), (a, b) in zip(own, self._limits(scn), strict=True))
        if not all(lo < hi for lo, hi in out):
            raise ValueError(f"{self.name}: no parameter range left on {scn.id}: {out}")
        return out

    def apply(self, scn: Scenario, cfg: ModelConfig, values: tuple[float, ...]) -> ModelConfig:
        """``cfg`` with this effect set to ``values``."""
        return self._apply(scn, cfg, tuple(float(v) for v in values))

    def spec_overrides(self, scn: Scenario, values: tuple[float, ...]) -> dict[str, Any]:
        """The spec fields (``--set`` keys, SI dataclass fields) this effect sets."""
        return self._spec(scn, tuple(float(v) for v in values))

    def describe(self) -> dict[str, Any]:
        return {"name": self.name, "title": self.title, "meaning": self.meaning, "kind": self.kind,
                "channels": list(self.channels), "signature": self.signature,
                "params": [{"name": p.name, "unit": p.unit, "lower": p.lower, "upper": p.upper} for p in self.params]}


def _phys(spec_fn: Callable[[Scenario, tuple[float, ...]], dict[str, Any]]):
    def apply(scn: Scenario, cfg: ModelConfig, v: tuple[float, ...]) -> ModelConfig:
        return cfg.with_overrides(**spec_fn(scn, v))
    return apply


# ------------------------------------------------------------------------------------ effects
def _roll_spec(scn, v):
    return {"terrain.rolling_resistance": v[0]}


def _mu_spec(scn, v):
    return {"terrain.mu_sa": scn.terrain.mu_sa * v[0], "terrain.mu_op": scn.terrain.mu_op * v[0]}


def _speed_slip_spec(scn, v):
    return {"terrain.friction_speed_decay": v[0]}


def _shear_spec(scn, v):
    return {"terrain.model": "janosi", "terrain.shear_modulus": v[0]}


def _radius_spec(scn, v):
    return {"platform.wheel_radius_scale_l": v[0], "platform.wheel_radius_scale_r": v[1]}


def _cg_spec(scn, v):
    return {"platform.cg_offset_x": v[0], "platform.cg_offset_y": v[1]}


def _cg_limits(scn):
    """The centre of mass at most 90 % of the way from the centre to an axle or a wheel line (testbed choice: the
    spec refuses it on or beyond them, Platform._check_whole, and a margin keeps every wheel loaded)."""
    x, y = 0.9 * scn.platform.wheelbase / 2, 0.9 * scn.platform.track / 2
    return ((-x, x), (-y, y))


def _payload_spec(scn, v):
    return {"platform.payload": v[0]}


def _slope_spec(scn, v):
    return {"terrain.slope": math.radians(v[0])}


def _sat_spec(scn, v):
    return {"platform.motor.max_current": v[0]}


def _delay_spec(scn, v):
    return {"platform.actuator_delay": v[0]}


def _lag_spec(scn, v):
    return {"platform.powertrain_tau_l": max(v[0], 0.0), "platform.powertrain_tau_r": max(v[1], 0.0)}


def _cmd_spec(scn, v):
    return {"platform.command_gain_sum": v[0], "platform.command_gain_diff": v[1]}


def _cmd_limit_spec(scn, v):
    return {"platform.command_limit_mean": v[0], "platform.command_limit_diff": v[1]}


def _finite(values: tuple[float, ...]) -> tuple[float, ...] | None:
    """``values`` when all are finite (a limit the scenario already has), else None (no limit: no neutral value)."""
    return values if all(map(math.isfinite, values)) else None


def _cmd_limit_neutral(scn):
    return _finite((scn.platform.command_limit_mean, scn.platform.command_limit_diff))


def _wheel_limit_spec(scn, v):
    return {"platform.wheel_speed_limit": v[0]}


def _wheel_limit_neutral(scn):
    return _finite((scn.platform.wheel_speed_limit,))


def _cmd_accel_spec(scn, v):
    return {"platform.command_accel_mean": v[0], "platform.command_accel_diff": v[1]}


def _cmd_accel_neutral(scn):
    return _finite((scn.platform.command_accel_mean, scn.platform.command_accel_diff))


def _torque_spec(scn, v):
    m = scn.platform.motor
    return {"platform.motor.stall_torque": m.stall_torque * v[0], "platform.motor.max_current": m.max_current * v[0]}


def _lat_spec(scn, v):
    return {"terrain.mu_lat_ratio": v[0]}


def _enc_spec(scn, v):
    return {"platform.sensors.encoder.scale_error_l": v[0], "platform.sensors.encoder.scale_error_r": v[1]}


def _gyro_spec(scn, v):
    return {"platform.sensors.imu.gyro_bias_z": v[0]}


def _enc_latency_spec(scn, v):
    return {"platform.sensors.encoder.latency": max(v[0], 0.0)}


def _enc_latency_apply(scn, cfg, v):
    return cfg.replace(enc_latency=max(v[0], 0.0))


def _enc_apply(scn, cfg, v):
    return cfg.replace(enc_scale=(v[0], v[1]))


def _gyro_apply(scn, cfg, v):
    return cfg.replace(gyro_bias=v[0])


def _gyro_scale_apply(scn, cfg, v):
    return cfg.replace(gyro_scale=v[0])


def _gyro_scale_spec(scn, v):
    return {"platform.sensors.imu.gyro_scale_z": v[0]}


def _mount_apply(scn, cfg, v):
    return cfg.replace(imu_mount=(v[0], v[1], v[2]))


def _mount_spec(scn, v):
    return {"platform.sensors.imu.yaw_misalignment": v[0], "platform.sensors.imu.lever_x": v[1],
            "platform.sensors.imu.lever_y": v[2]}


def _delay_apply(scn, cfg, v):
    return cfg.with_overrides(**{"platform.actuator_delay": max(v[0], 0.0)})


CATALOGUE: tuple[Effect, ...] = (
    Effect(
        "rolling_resistance", "rolling resistance",
        "Rolling-resistance coefficient mu_roll of the terrain/tires: a resisting wheel torque "
        "mu_roll N r on every rolling wheel (tire hysteresis, soft ground).",
        (Param("rolling_resistance", "-", 0.0, 0.3, 0.02),),
        ("tau_l", "tau_r", "i_l", "i_r"),
        "constant extra torque on both sides whenever the wheels roll, about the same straight and "
        "turning; no change in the kinematics", "physics",
        lambda s: (s.terrain.rolling_resistance,), _phys(_roll_spec), _roll_spec),
    Effect(
        "friction", "terrain friction change (mu)",
        "Friction of the terrain scaled by mu_scale (mu_sa and mu_op together): wet, dusty or a "
        "different surface.",
        (Param("mu_scale", "-", 0.2, 3.0, 0.15),),
        ("tau_l", "tau_r", "imu_gz"),
        "turning torques scale with mu (skid-steer turning resistance), straight-line torques "
        "unchanged; yaw response in tight turns changes", "physics",
        lambda s: (1.0,), _phys(_mu_spec), _mu_spec),
    Effect(
        "speed_slip", "speed-dependent slip (friction falling with sliding speed)",
        "Friction falls with the sliding speed |s| of each contact, mu / (1 + A_s |s|) (Dugoff, Fancher and Segel "
        "1970: mu_0 (1 - A_s V_s) to first order; A_s = friction_speed_decay [s/m]): the faster the wheels slide, "
        "the less they hold, so the slip grows with speed.",
        (Param("friction_speed_decay", "s/m", 0.0, 20.0, 0.25),),
        ("imu_gz", "ref_yaw", "enc_wl", "enc_wr", "tau_l", "tau_r"),
        "slow manoeuvres as the nominal model, fast ones different: the turn rate per wheel-speed difference and "
        "the turning torques change with speed (the faster-sliding wheels lose more friction), hard starts spin "
        "the wheels more; a uniform friction change (mu) would scale the torques alike at every speed", "physics",
        lambda s: (s.terrain.friction_speed_decay,), _phys(_speed_slip_spec), _speed_slip_spec),
    Effect(
        "shear_displacement", "shear-displacement friction instead of Coulomb",
        "Janosi-Hanamoto shear-displacement friction (Yu 2010 eq. (7)) with shear modulus K "
        "instead of Coulomb friction (or a different K): the tangential force builds up with the "
        "slip ratio over the contact patch.",
        (Param("shear_modulus", "m", 2e-4, 0.05, 0.25, log=True),),
        ("imu_gz", "tau_l", "tau_r", "ref_yaw"),
        "turn rate and turning torque depend on the slip ratio: less yaw and less torque in "
        "gentle turns than Coulomb, converging in tight ones", "physics",
        lambda s: (s.terrain.shear_modulus,) if s.terrain.model == "janosi" else None,
        _phys(_shear_spec), _shear_spec,
        probe_grid=((5e-4,), (1.5e-3,), (4e-3,), (1e-2,))),
    Effect(
        "wheel_radius", "wheel-radius asymmetry (tire pressure)",
        "Effective rolling radius of each side, r_eff = r * scale (tire pressure, wear, load).",
        (Param("radius_scale_l", "-", 0.8, 1.2, 0.01), Param("radius_scale_r", "-", 0.8, 1.2, 0.01)),
        ("ref_yaw", "ref_x", "ref_y", "imu_gz", "body_vx"),
        "speed scaled on one side: a constant yaw-rate offset on straight lines (heading drift), "
        "distance scaled; wheel speeds unchanged", "physics",
        lambda s: (s.platform.wheel_radius_scale_l, s.platform.wheel_radius_scale_r),
        _phys(_radius_spec), _radius_spec),
    Effect(
        "cg_offset", "centre-of-mass offset (ICR eccentricity)",
        "Centre of mass ahead of (x) / left of (y) the geometric centre: shifts the normal loads "
        "and the ICR longitudinally (x_icr), side loads (y).",
        (Param("cg_offset_x", "m", -0.15, 0.15, 0.02, mirror=True), Param("cg_offset_y", "m", -0.15, 0.15, 0.02)),
        ("body_vy", "imu_ay", "imu_gz", "tau_l", "tau_r"),
        "lateral body velocity in turns (x_icr = -vy/wz), left/right torque split, yaw response; "
        "the turning torque changes with |x| (both signs alike), so x is fitted from both signs",
        "physics",
        lambda s: (s.platform.cg_offset_x, s.platform.cg_offset_y), _phys(_cg_spec), _cg_spec,
        _limits=_cg_limits),
    Effect(
        "payload", "extra payload mass",
        "Extra mass carried at the centre of mass [kg]: more inertia, weight and friction load.",
        (Param("payload", "kg", 0.0, 80.0, 4.0),),
        ("tau_l", "tau_r", "i_l", "i_r"),
        "torques larger in proportion everywhere, most when accelerating and braking (inertia) and "
        "turning (load); kinematics nearly unchanged", "physics",
        lambda s: (s.platform.payload,), _phys(_payload_spec), _payload_spec),
    Effect(
        "slope", "terrain slope",
        "Ground inclined by slope_deg, rising along world +x (the testbed's ramp axis).",
        (Param("slope_deg", "deg", -20.0, 20.0, 2.0),),
        ("imu_ax", "imu_ay", "tau_l", "tau_r"),
        "gravity in the accelerometer (g sin(slope) along the heading's uphill component), torque "
        "offset that changes sign with heading, drift of the path downhill", "physics",
        lambda s: (math.degrees(s.terrain.slope),), _phys(_slope_spec), _slope_spec,
        _modelled_on=lambda s: s.terrain.roughness_gd0 == 0.0),  # bench.sim.ground has no rough ramp
    Effect(
        "motor_saturation", "motor torque/current saturation",
        "Motor current (hence torque) limit per motor I_max [A] below the nominal one (controller "
        "setting, thermal derating).",
        (Param("max_current", "A", 0.1, 50.0, 0.1),),
        ("i_l", "i_r", "tau_l", "tau_r", "enc_wl", "enc_wr"),
        "measured current/torque flat at a ceiling while the model asks for more; wheel speeds lag "
        "the command in hard acceleration and tight turns", "physics",
        lambda s: (s.platform.motor.max_current,), _phys(_sat_spec), _sat_spec),
    Effect(
        "actuator_delay", "actuator delay",
        "Delay between a command and the wheel-speed controller's reference [s] (communication, "
        "controller cycle).",
        (Param("delay", "s", 0.0, 0.5, 0.02),),
        ("enc_wl", "enc_wr", "tau_l", "tau_r", "imu_ax"),
        "every transient (acceleration, braking, turn entry) late by the same time; steady "
        "states unchanged", "delay",
        lambda s: (s.platform.actuator_delay,), _delay_apply, _delay_spec),
    Effect(
        "powertrain_lag", "per-side powertrain lag",
        "Each side's wheel-speed reference follows the command through a first-order lag "
        "tau dw/dt = u - w (time constant tau_l, tau_r [s]; DRIVE's powertrain, Baril et al. 2024): the "
        "robot's own speed controller and drive train respond gradually, not at once.",
        (Param("tau_l", "s", 0.0, 1.5, 0.05), Param("tau_r", "s", 0.0, 1.5, 0.05)),
        ("enc_wl", "enc_wr", "tau_l", "tau_r", "imu_ax", "imu_gz"),
        "wheel speeds approach each new command exponentially (no corner at the step, unlike a dead "
        "time), torque peaks at command steps smaller and longer; steady states unchanged", "physics",
        lambda s: (s.platform.powertrain_tau_l, s.platform.powertrain_tau_r), _phys(_lag_spec), _lag_spec),
    Effect(
        "command_map", "the robot's own command mapping",
        "The robot's velocity controller maps the wheel-speed command before the wheel PIDs: the "
        "mean speed scaled by g_sum, the speed difference (the turn) by g_diff (a controller with "
        "its own effective track or yaw-rate gain, a units slip in the command path).",
        (Param("gain_sum", "-", 0.2, 3.0, 0.05), Param("gain_diff", "-", 0.05, 3.0, 0.05)),
        ("enc_wl", "enc_wr", "imu_gz", "ref_x", "ref_y", "ref_yaw"),
        "steady wheel speeds differ from the commanded ones by one factor on their mean (straight "
        "lines) and another on their difference (turns); the wheels still track, torques follow",
        "physics",
        lambda s: (s.platform.command_gain_sum, s.platform.command_gain_diff), _phys(_cmd_spec), _cmd_spec),
    Effect(
        "command_limit", "the robot's own command limits",
        "The robot's velocity controller clips the (mapped) command: its mean wheel speed to "
        "+-limit_mean and its half-difference (the turn) to +-limit_diff [rad/s] (a linear-speed "
        "and a yaw-rate limit).",
        (Param("limit_mean", "rad/s", 0.3, 50.0, 0.05, log=True), Param("limit_diff", "rad/s", 0.1, 50.0, 0.05, log=True)),
        ("enc_wl", "enc_wr", "imu_gz", "ref_x", "ref_y", "ref_yaw"),
        "wheel speeds flat at a ceiling in fast straight runs, turn rate flat at a ceiling in tight "
        "turns, while the command asks for more; unchanged below the limits", "physics",
        _cmd_limit_neutral, _phys(_cmd_limit_spec), _cmd_limit_spec,
        probe_grid=((2.0, 1.0), (4.0, 1.0), (4.0, 2.0), (8.0, 2.0), (8.0, 4.0), (50.0, 1.0), (2.0, 50.0))),
    Effect(
        "wheel_speed_limit", "the drive's wheel-speed limit",
        "The drive scales both sides' wheel-speed references by one factor so that the faster side is at "
        "most limit [rad/s] (Clearpath husky_base limitDifferentialSpeed: max_speed 1.0 m/s): the path's "
        "curvature is kept, its speed is not.",
        (Param("limit", "rad/s", 1.0, 50.0, 0.05, log=True),),
        ("enc_wl", "enc_wr", "imu_gz", "ref_x", "ref_y", "ref_yaw"),
        "the faster wheel flat at one speed whatever the command, the slower one in proportion (the ratio "
        "of the two wheel speeds as commanded); unchanged below the limit", "physics",
        _wheel_limit_neutral, _phys(_wheel_limit_spec), _wheel_limit_spec,
        probe_grid=((4.0,), (6.0,), (9.0,), (14.0,))),
    Effect(
        "command_accel", "the robot's own acceleration limits",
        "The robot's velocity controller limits the rate of change of the (mapped) mean wheel speed to "
        "accel_mean and of its half-difference to accel_diff [rad/s^2] (ROS diff_drive_controller's linear "
        "and angular acceleration limits, in wheel units).",
        (Param("accel_mean", "rad/s^2", 0.5, 200.0, 0.05, log=True),
         Param("accel_diff", "rad/s^2", 0.5, 200.0, 0.05, log=True)),
        ("enc_wl", "enc_wr", "imu_gz", "imu_ax", "ref_x", "ref_y", "ref_yaw"),
        "after each command step the wheel speeds' mean and difference ramp linearly (a constant slope, "
        "no corner delay, no exponential tail), the turn typically slower than the speed; steady states "
        "unchanged", "physics",
        _cmd_accel_neutral, _phys(_cmd_accel_spec), _cmd_accel_spec,
        probe_grid=((3.0, 3.0), (10.0, 3.0), (3.0, 10.0), (10.0, 10.0), (30.0, 3.0), (30.0, 30.0))),
    Effect(
        "motor_torque", "drive torque capability",
        "Each side's motor stronger or weaker than specified by torque_scale: stall torque and current "
        "limit scaled together (the torque available at every wheel speed below a power limit; the "
        "no-load speed and any power limit kept).",
        (Param("torque_scale", "-", 0.2, 6.0, 0.05, log=True),),
        ("enc_wl", "enc_wr", "imu_gz", "tau_l", "tau_r", "i_l", "i_r"),
        "the outer wheel of a tight turn (the side that needs the most torque at speed) falls short of "
        "its command in the weaker model and tracks it in the stronger; straight driving unchanged",
        "physics",
        lambda s: (1.0,), _phys(_torque_spec), _torque_spec),
    Effect(
        "lateral_friction", "lateral friction anisotropy",
        "Ratio mu_lat/mu_lon of the tire-ground friction across and along the wheel (tread pattern, "
        "sidewall scrubbing): sets how hard the treads resist the lateral sliding of a skid-steer turn.",
        (Param("mu_lat_ratio", "-", 0.3, 4.0, 0.1),),
        ("imu_gz", "ref_yaw", "ref_x", "ref_y", "tau_l", "tau_r"),
        "turn rate per wheel-speed difference (chi, the ICR spread) scales with the ratio: less yaw and "
        "more turning torque above 1; straight driving unchanged", "physics",
        lambda s: (s.terrain.mu_lat_ratio,), _phys(_lat_spec), _lat_spec),
    Effect(
        "encoder_scale", "encoder scale error",
        "Fractional scale error of each side's encoder (wrong counts per revolution, gearing).",
        (Param("scale_error_l", "-", -0.3, 0.3, 0.01), Param("scale_error_r", "-", -0.3, 0.3, 0.01)),
        ("enc_wl", "enc_wr"),
        "encoder speed proportional to the model's (ratio 1 + e) while body motion, torques and "
        "yaw agree", "sensor",
        lambda s: (s.platform.sensors.encoder.scale_error_l, s.platform.sensors.encoder.scale_error_r),
        _enc_apply, _enc_spec),
    Effect(
        "encoder_latency", "wheel-speed sensor latency",
        "The wheel-speed channel reports late by latency [s]: each sample is the count difference of the wheel "
        "angles latency before its time stamp (driver buffering or filtering, a time stamp taken on arrival, "
        "transport), while the robot itself moves on time.",
        (Param("latency", "s", 0.0, 0.5, 0.01),),
        ("enc_wl", "enc_wr"),
        "every wheel-speed transient late by the same time while the gyro, accelerometer and pose respond on "
        "time (an actuator delay delays them all); steady wheel speeds unchanged", "sensor",
        lambda s: (s.platform.sensors.encoder.latency,), _enc_latency_apply, _enc_latency_spec,
        probe_grid=tuple((0.025 * k,) for k in range(1, 21))),
    Effect(
        "gyro_scale", "gyro scale or sign (IMU mounting)",
        "Gain of the gyro's z rate: the yaw rate it reports is gain x the body's (-1: the IMU mounted upside "
        "down or its z axis flipped in the driver; |gain| != 1: a scale error).",
        (Param("gyro_scale_z", "-", -2.0, 2.0, 0.01),),  # the spec's range (ImuSpec: |gain| <= 2; 0: a dead gyro)
        ("imu_gz",),
        "measured yaw rate proportional to the model's, of the opposite sign for a flipped mount, in every "
        "turn; zero on straight lines; pose and wheels agree", "sensor",
        lambda s: (s.platform.sensors.imu.gyro_scale_z,), _gyro_scale_apply, _gyro_scale_spec,
        probe_grid=((-1.0,),)),
    Effect(
        "imu_mounting", "IMU mounting (axes turned, lever arm)",
        "The accelerometer's axes turned by yaw_misalignment [rad] about z from the body's, and the sensor "
        "at (lever_x, lever_y) [m] from the centre of mass: it reads the CoM's specific force plus the "
        "centripetal -w^2 r and tangential alpha x r terms of its lever arm (bench.sim.sensors.imu_mounting).",
        (Param("yaw_misalignment", "rad", -math.pi, math.pi, 0.02), Param("lever_x", "m", -1.0, 1.0, 0.02),
         Param("lever_y", "m", -1.0, 1.0, 0.02)),
        ("imu_ax", "imu_ay"),
        "part of the forward acceleration in a_y (and of the lateral in a_x) on every manoeuvre for turned axes; "
        "an extra -w^2 r in turns and alpha r when a turn starts or ends for a lever arm; gyro, pose and "
        "wheels agree", "sensor",
        lambda s: (s.platform.sensors.imu.yaw_misalignment, s.platform.sensors.imu.lever_x,
                   s.platform.sensors.imu.lever_y), _mount_apply, _mount_spec,
        probe_grid=((math.pi / 2, 0.0, 0.0), (-math.pi / 2, 0.0, 0.0), (math.pi - 1e-9, 0.0, 0.0))),  # mounted sideways,
    # backwards: a refinement from the nominal alone would not reach them
    Effect(
        "gyro_bias", "IMU gyro bias",
        "Constant bias of the gyro's z rate [rad/s].",
        (Param("gyro_bias_z", "rad/s", -0.5, 0.5, 0.005),),
        ("imu_gz",),
        "constant offset of the measured yaw rate, in every regime including standstill; pose "
        "and wheels agree", "sensor",
        lambda s: (s.platform.sensors.imu.gyro_bias_z,), _gyro_apply, _gyro_spec),
)

BY_NAME: Mapping[str, Effect] = {e.name: e for e in CATALOGUE}


def get(name: str) -> Effect:
    try:
        return BY_NAME[name]
    except KeyError:
        raise KeyError(f"unknown gap effect {name!r}; catalogue: {sorted(BY_NAME)}") from None


def nominal_config(scn: Scenario) -> ModelConfig:
    """The nominal model: the scenario as specified (its own sensor errors applied)."""
    enc = scn.platform.sensors.encoder
    imu = scn.platform.sensors.imu
    return ModelConfig((), (enc.scale_error_l, enc.scale_error_r), imu.gyro_bias_z, 0.0, enc.latency,
                       imu.gyro_scale_z, (imu.yaw_misalignment, imu.lever_x, imu.lever_y))


__all__ = ["Param", "Effect", "ModelConfig", "CATALOGUE", "BY_NAME", "get", "nominal_config"]
