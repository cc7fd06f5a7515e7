"""Specs as data: Platform, Terrain, SensorSpec, Scenario.

Frozen dataclasses loaded from TOML files under ``scenarios/`` with strict validation: an unknown
key, a wrong type, an out-of-range value or a missing file raises :class:`SpecError` naming the
file, the dotted field and the offending value.  TOML is parsed as data only (``tomllib``).

Units are SI inside.  Files may give a few quantities in the units the papers use; those fields
carry the unit in their name (``*_deg``, ``*_psi``) and are converted at the file
boundary, into the SI field of the dataclass.  The validation itself (:func:`build`, :class:`SpecError`)
is :mod:`bench.schema`; both names are importable from here.

Every parameter of a platform or terrain file names its source in the file's ``[sources]`` table
(:mod:`bench.sources`); :class:`Platform` and :class:`Terrain` keep them as ``sources`` (field -> source).
"""
from __future__ import annotations

import dataclasses
import math
import tomllib
import types
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

from bench.paths import SCENARIO_DIR  # the checkout's scenarios/, installed: the package data
from bench.schema import SpecError, build, nonneg, positive, read_toml
from bench.sensor_spec import SENSOR_RATE_RANGE, EncoderSpec, GnssSpec, ImuSpec, ReferenceSpec, SensorSpec, sensor_rate
from bench.sources import Source, Sources, default_sources, file_sources, override_sources, parameters
from bench.spec_files import known_file, list_scenarios, registered, resolve_name


# --------------------------------------------------------------------------------------------
# Specs
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class MotorSpec:
    """DC motor, gearbox and motor controller (Yu 2010 Table II, eqs. (26)-(27)).

    Torques and speeds are at the motor shaft; ``gear_ratio`` maps to the wheel.
    """

    stall_torque: float = 0.2775  # tau_s [N m] at nominal voltage
    no_load_speed: float = 487.16  # omega_n [rad/s] at nominal voltage
    nominal_voltage: float = 12.0  # V_nom [V]
    torque_constant: float = 0.023  # K_T [N m / A]
    max_current: float = 5.5  # I_max continuous [A]
    gear_ratio: float = 49.8  # g_r
    pwm: float = 0.95  # PWM duty limit of the controller
    supply_voltage: float = 12.0  # V_CC [V]
    controller_loss: float = 0.0  # U_loss [V]
    max_power: float = 0.0  # electrical power limit per motor [W]; 0 = none
    gear_efficiency: float = 1.0
    motors_per_side: int = 2

    _checks = {
        "stall_torque": (lambda x: 0 < x <= 1e3, "in (0, 1e3] N m (at the motor shaft)"),
        "no_load_speed": (lambda x: 0 < x <= 1e4, "in (0, 1e4] rad/s"),
        "nominal_voltage": (lambda x: 0 < x <= 1e3, "in (0, 1e3] V"),
        "torque_constant": (lambda x: 0 < x <= 100, "in (0, 100] N m/A"),
        "max_current": (lambda x: 0 < x <= 1e4, "in (0, 1e4] A"),
        "gear_ratio": (lambda x: 0.01 <= x <= 1e4, "in [0.01, 1e4]"),
        "pwm": (lambda x: 0 < x <= 1, "in (0, 1]"),
        "supply_voltage": (lambda x: 0 < x <= 1e3, "in (0, 1e3] V"),
        "controller_loss": (nonneg, ">= 0"),
        "max_power": (nonneg, ">= 0"),
        "gear_efficiency": (lambda x: 0 < x <= 1, "in (0, 1]"),
        "motors_per_side": (lambda x: x in (1, 2), "1 or 2"),
    }


@dataclass(frozen=True)
class PidSpec:
    """Per-side wheel-speed PID (Yu 2010 Fig. 4: derivative on the reference).

    Gains act on the wheel-speed error in rad/s and output motor voltage [V] (Yu's loop).
    """

    kp: float = 30.25
    ki: float = 151.25
    kd: float = 0.0605
    rate_hz: float = 1000.0  # controller sampling rate; the testbed runs it at min(rate_hz, 1/dt)
    gain_scale: float = 1.0  # Yu's gains are on the linear speed [m/s]: scale = wheel radius

    _checks = {
        "kp": (lambda x: 0 <= x <= 1e6, "in [0, 1e6]"),
        "ki": (lambda x: 0 <= x <= 1e6, "in [0, 1e6]"),
        "kd": (lambda x: 0 <= x <= 1e6, "in [0, 1e6]"),
        "rate_hz": (positive, "> 0"),
        "gain_scale": (positive, "> 0"),
    }


# [m] a wheeled robot's wheel radius and track: Platform's ranges (its _checks, which the kinematic platforms of the
# real data use too: bench.real.platform, bench.real.drive.resolve_platform)
WHEEL_RADIUS_RANGE = (0.01, 2.0)
TRACK_RANGE = (0.05, 10.0)
MAX_SPEED = 20.0  # [m/s] the fastest a command, a segment or an initial speed may ask of a wheeled robot


@dataclass(frozen=True)
class Platform:
    """A skid-steered vehicle. Body frame x forward, y left, z up (DESIGN.md).

    ``track`` is B (lateral distance between the wheel centre lines), ``wheelbase`` the distance
    between front and rear axles (2a).  ``patch_length``/``patch_gap`` are Yu's L and C
    (Table II); ``wheel_width`` is b.
    """

    name: str
    mass: float
    yaw_inertia: float
    track: float
    wheelbase: float
    wheel_radius: float
    wheel_width: float = 0.05
    patch_length: float = 0.31  # Yu's L: outer extent of the front/rear patches
    patch_gap: float = 0.24  # Yu's C
    wheel_inertia: float = 0.02  # spin inertia of one wheel incl. reflected rotor [kg m^2]
    cg_height: float = 0.15
    cg_offset_x: float = 0.0  # centre of mass ahead of the geometric centre [m]
    cg_offset_y: float = 0.0
    body_length: float = 0.5
    body_width: float = 0.4
    body_height: float = 0.2
    wheel_radius_scale_l: float = 1.0  # effective rolling radius scale (tire pressure) left
    wheel_radius_scale_r: float = 1.0
    actuator_delay: float = 0.0  # [s] delay between command and PID reference
    # per-side powertrain lag (DRIVE, Baril et al. 2024): first-order time constant [s] of each side's wheel-speed
    # reference after the command (0 = none: the command passes bit for bit)
    powertrain_tau_l: float = 0.0
    powertrain_tau_r: float = 0.0
    # the robot's own command mapping (its velocity controller between the user's wheel-speed command
    # and the wheel PIDs): the PID references are g_sum * (w_l + w_r)/2 -+ g_diff * (w_r - w_l)/2;
    # 1, 1 = the command as given (exactly: the map is skipped)
    command_gain_sum: float = 1.0
    command_gain_diff: float = 1.0
    # ... and its limits [rad/s] on the mapped mean speed and half-difference (inf = none)
    command_limit_mean: float = math.inf
    command_limit_diff: float = math.inf
    # ... its acceleration limits [rad/s^2] on the mean speed and half-difference (ROS diff_drive_controller's
    # linear and angular acceleration limits, in wheel units; inf = none)
    command_accel_mean: float = math.inf
    command_accel_diff: float = math.inf
    # ... and the drive's wheel-speed limit [rad/s]: both sides scaled by one factor so that the faster one
    # is at the limit (the turn's curvature is kept; Clearpath husky_base limitDifferentialSpeed; inf = none)
    wheel_speed_limit: float = math.inf
    payload: float = 0.0  # extra mass at the CG [kg]
    # tire contact (bench/sim/tire.py tire_contact): 0, 0 = none (patch (L - C)/2 of Yu's Table II, nominal radius);
    # a pneumatic tire's inflation pressure [Pa] (tire_pressure_psi in files): the toroidal-membrane contact gives
    # each wheel's patch length and loaded rolling radius from its load; or a solid rubber tire's Young's modulus
    # [Pa]: Hertz line contact gives the patch (the rolling radius stays nominal)
    tire_pressure: float = 0.0
    tire_modulus: float = 0.0
    tire_rolling_resistance: float = 0.0  # the tire's rolling-resistance coefficient, added to the terrain's (rigid ground)
    motor: MotorSpec = field(default_factory=MotorSpec)
    pid: PidSpec = field(default_factory=PidSpec)
    sensors: SensorSpec = field(default_factory=SensorSpec)
    source: str = ""
    # where each parameter comes from (bench.sources): provenance, not physics (no part of ==, hash, to_dict)
    sources: Sources = field(default_factory=Sources, compare=False, repr=False)

    _checks = {
        "mass": (lambda x: 0.1 <= x <= 5e4, "in [0.1, 5e4] kg (a wheeled robot)"),
        "yaw_inertia": (positive, "> 0 kg m^2"),
        "track": (lambda x: TRACK_RANGE[0] <= x <= TRACK_RANGE[1], "in [{:g}, {:g}] m".format(*TRACK_RANGE)),
        "wheelbase": (lambda x: 0.0 < x <= 10.0, "in (0, 10] m"),
        "wheel_radius": (lambda x: WHEEL_RADIUS_RANGE[0] <= x <= WHEEL_RADIUS_RANGE[1],
                         "in [{:g}, {:g}] m".format(*WHEEL_RADIUS_RANGE)),
        "wheel_width": (positive, "> 0 m"),
        "patch_length": (positive, "> 0 m"),
        "patch_gap": (nonneg, ">= 0 m"),
        "wheel_inertia": (positive, "> 0 kg m^2"),
        "cg_height": (positive, "> 0 m"),
        "body_length": (positive, "> 0 m"),
        "body_width": (positive, "> 0 m"),
        "body_height": (positive, "> 0 m"),
        "wheel_radius_scale_l": (lambda x: 0.5 < x < 1.5, "in (0.5, 1.5)"),
        "wheel_radius_scale_r": (lambda x: 0.5 < x < 1.5, "in (0.5, 1.5)"),
        "actuator_delay": (lambda x: 0 <= x < 2, "in [0, 2) s"),
        "powertrain_tau_l": (lambda x: 0 <= x < 5, "in [0, 5) s"),
        "powertrain_tau_r": (lambda x: 0 <= x < 5, "in [0, 5) s"),
        "command_gain_sum": (lambda x: 0 < x <= 5, "in (0, 5]"),
        "command_gain_diff": (lambda x: 0 < x <= 5, "in (0, 5]"),
        "command_limit_mean": (lambda x: x > 0, "> 0 rad/s (inf: no limit)"),
        "command_limit_diff": (lambda x: x > 0, "> 0 rad/s (inf: no limit)"),
        "command_accel_mean": (lambda x: x > 0, "> 0 rad/s^2 (inf: no limit)"),
        "command_accel_diff": (lambda x: x > 0, "> 0 rad/s^2 (inf: no limit)"),
        "wheel_speed_limit": (lambda x: x > 0, "> 0 rad/s (inf: no limit)"),
        "payload": (lambda x: 0 <= x <= 5e4, "in [0, 5e4] kg"),
        "tire_pressure": (lambda x: 0 <= x <= 1e6, "in [0, 1e6] Pa (0: no pneumatic tire; 145 psi)"),
        "tire_modulus": (lambda x: 0 <= x <= 1e9, "in [0, 1e9] Pa (0: no solid tire)"),
        "tire_rolling_resistance": (lambda x: -0.2 < x < 0.2, "in (-0.2, 0.2) (added to the terrain's)"),
    }

    @property
    def total_mass(self) -> float:
        return self.mass + self.payload

    def _check_whole(self) -> tuple[str, object, str] | None:
        """The centre of mass inside the wheels' support rectangle (outside it the robot tips over at rest)."""
        if not abs(self.cg_offset_x) < self.wheelbase / 2:
            return "cg_offset_x", self.cg_offset_x, (f"|cg_offset_x| < wheelbase / 2 = {self.wheelbase / 2:g} m (the "
                                                     "centre of mass between the axles)")
        if not abs(self.cg_offset_y) < self.track / 2:
            return "cg_offset_y", self.cg_offset_y, (f"|cg_offset_y| < track / 2 = {self.track / 2:g} m (the centre "
                                                     "of mass between the wheels)")
        return None


@dataclass(frozen=True)
class FrictionPatch:
    """A region of the ground with a friction scale (outside the gap catalogue on purpose)."""

    x_min: float = 0.0
    x_max: float = 0.0
    y_min: float = -1e3
    y_max: float = 1e3
    mu_scale: float = 1.0
    t_period: float = 0.0  # > 0: friction scale oscillates in time with this period [s]

    _checks = {
        "mu_scale": (lambda x: 0 <= x <= 10, "in [0, 10]"),
        "t_period": (nonneg, ">= 0 s"),
        **{k: (lambda x: not math.isnan(x), "a number (+-inf: unbounded)")
           for k in ("x_min", "x_max", "y_min", "y_max")},
    }

    def _check_whole(self) -> tuple[str, object, str] | None:
        for lo, hi in (("x_min", "x_max"), ("y_min", "y_max")):
            if not getattr(self, lo) <= getattr(self, hi):
                return hi, getattr(self, hi), f">= {lo} = {getattr(self, lo)}"
        return None


@dataclass(frozen=True)
class Terrain:
    """Ground: tangential tire force law and its parameters.

    ``model``: ``"coulomb"`` (smooth Coulomb friction ellipse on the slip velocity) or
    ``"janosi"`` (Janosi-Hanamoto shear stress vs shear displacement, Yu 2010 eq. (7), over a
    contact patch of length ``patch`` with shear modulus ``shear_modulus``).
    ``mu_sa``/``mu_op``: friction when the motor drives / brakes the wheel (Yu Sec. V-A).
    ``mu_lat_ratio`` scales lateral friction (anisotropic tires).
    """

    name: str
    model: str = "janosi"
    mu_sa: float = 0.4437
    mu_op: float = 0.3093
    mu_lat_ratio: float = 1.0
    shear_modulus: float = 0.00054  # K [m]
    shear_modulus_lat_ratio: float = 1.0  # K_lat / K (testbed tire law; 1 = isotropic)
    rolling_resistance: float = 0.0371  # mu_roll (Yu Table II, vinyl); rigid ground only (soil: Bekker compaction)
    slope: float = 0.0  # ramp angle [rad], from slope_deg in files
    slip_velocity_eps: float = 0.02  # [m/s] smoothing of Coulomb sign()
    # Dugoff's friction reduction with sliding speed, mu(s) = mu / (1 + A_s s) (bench/sim/tire.py) [s/m]; 0 = none;
    # on Bekker soil it scales the shear strength c A + W tan(phi) alike; the bound 20 s/m is a search range
    friction_speed_decay: float = 0.0
    friction_patches: tuple[FrictionPatch, ...] = ()
    # uneven ground (bench/sim/ground.py): ISO 8608 displacement PSD G_d(n0) [m^3] at n0 = 0.1 cycles/m
    # (class A 16e-6, B 64e-6, C 256e-6, D 1024e-6, E 4096e-6 ...); 0 = flat (GEOM_PLANE, as before)
    roughness_gd0: float = 0.0
    roughness_spacing: float = 0.1  # heightfield grid spacing [m]
    roughness_length_x: float = 51.2  # heightfield side along x [m], centred at roughness_centre_x
    roughness_length_y: float = 51.2  # heightfield side along y [m], centred at roughness_centre_y
    roughness_centre_x: float = 0.0  # [m]
    roughness_centre_y: float = 0.0  # [m]
    roughness_seed: int = 0  # seed of the heightfield (a terrain field: the same ground for every sensor seed)
    # deformable soil (bench/sim/soil.py): "rigid" = none (the soil fields are unused), "bekker" = Bekker
    # sinkage, compaction resistance and the Janosi-Hanamoto shear-strength limit c A + W tan(phi)
    soil_model: str = "rigid"
    soil_n: float = 1.0  # Bekker sinkage exponent n
    soil_k_c: float = 0.0  # Bekker k_c [N/m^(n+1)]
    soil_k_phi: float = 0.0  # Bekker k_phi [N/m^(n+2)]
    soil_cohesion: float = 0.0  # c [Pa]
    soil_friction_angle: float = 0.0  # phi [rad], from soil_friction_angle_deg in files
    source: str = ""
    sources: Sources = field(default_factory=Sources, compare=False, repr=False)  # as Platform.sources

    _checks = {
        "soil_model": (lambda x: x in ("rigid", "bekker"), "'rigid' or 'bekker'"),
        "soil_n": (lambda x: 0 < x < 1.5, "in (0, 1.5)"),
        "soil_k_c": (nonneg, ">= 0 N/m^(n+1)"),
        "soil_k_phi": (nonneg, ">= 0 N/m^(n+2)"),
        "soil_cohesion": (nonneg, ">= 0 Pa"),
        "soil_friction_angle": (lambda x: 0 <= x < math.radians(60), "in [0, 60) deg"),
        "model": (lambda x: x in ("coulomb", "janosi"), "'coulomb' or 'janosi'"),
        "mu_sa": (lambda x: 0 < x < 3, "in (0, 3)"),
        "mu_op": (lambda x: 0 < x < 3, "in (0, 3)"),
        "mu_lat_ratio": (lambda x: 0.1 < x < 5, "in (0.1, 5)"),
        "shear_modulus": (lambda x: 1e-6 <= x <= 1.0, "in [1e-6, 1] m"),
        "shear_modulus_lat_ratio": (lambda x: 0.2 < x < 5, "in (0.2, 5)"),
        "rolling_resistance": (lambda x: 0 <= x < 0.5, "in [0, 0.5)"),
        "slope": (lambda x: abs(x) < math.radians(45), "|slope| < 45 deg"),
        "slip_velocity_eps": (positive, "> 0"),
        "friction_speed_decay": (lambda x: 0 <= x <= 20, "in [0, 20] s/m"),
        "roughness_gd0": (lambda x: 0 <= x < 0.1, "in [0, 0.1) m^3 (ISO 8608 G_d(n0))"),
        "roughness_spacing": (lambda x: 0.01 <= x <= 1.0, "in [0.01, 1] m"),
        "roughness_length_x": (lambda x: 1.0 <= x <= 1000.0, "in [1, 1000] m"),
        "roughness_length_y": (lambda x: 1.0 <= x <= 1000.0, "in [1, 1000] m"),
        "roughness_centre_x": (lambda x: abs(x) <= 1000.0, "|x| <= 1000 m"),
        "roughness_centre_y": (lambda x: abs(x) <= 1000.0, "|y| <= 1000 m"),
        "roughness_seed": (lambda x: 0 <= x < 2**63, ">= 0"),
    }


MAX_SEGMENT_VALUE = 1e4  # |a|, |b| of a command segment in its units (rad/s, rpm, m/s): beyond, a unit error


@dataclass(frozen=True)
class Segment:
    """One piece of a piecewise-constant command: until ``t_end`` hold (a, b)."""

    t_end: float
    a: float
    b: float

    _checks = {
        "t_end": (positive, "> 0 s"),
        "a": (lambda x: abs(x) <= MAX_SEGMENT_VALUE, f"a finite number, |a| <= {MAX_SEGMENT_VALUE:g}"),
        # b may be infinite (a straight v_radius or v_curvature_ratio segment): this check stands in for the finite
        # one of bench.schema.build; CommandSpec._check_whole decides per kind
        "b": (lambda x: not math.isnan(x), "a number (inf: straight)"),
    }


@dataclass(frozen=True)
class CommandSpec:
    """A command profile.

    kind:
      - ``wheel_speeds``: ``segments`` of (t_end, w_l, w_r) in ``units`` (rad/s | rpm | m/s tread)
      - ``v_radius``: segments of (t_end, v [m/s], radius [m], +CCW; inf for straight)
      - ``v_curvature_ratio``: segments of (t_end, v, curvature_ratio (v_l+v_r)/(v_r-v_l))
      - ``lemniscate``: Yu 2010 eqs. (29)-(30), ``t0``..``t0+duration`` of the curve
      - ``random``: joystick-like random (v, yaw rate) steps, seeded (Mandow's validation paths)
      - ``rotation``: pure rotation at tread speed ``v``
    ``accel`` limits the ramp from one segment to the next [m/s^2] (0 = steps).
    """

    kind: str = "wheel_speeds"
    units: str = "rad/s"
    segments: tuple[Segment, ...] = ()
    accel: float = 0.0
    v: float = 0.2
    t0: float = 0.0
    step: float = 2.0
    v_max: float = 0.5
    w_max: float = 1.0
    _checks = {
        "kind": (
            lambda x: x in ("wheel_speeds", "v_radius", "v_curvature_ratio", "lemniscate", "random", "rotation"),
            "one of wheel_speeds, v_radius, v_curvature_ratio, lemniscate, random, rotation",
        ),
        "units": (lambda x: x in ("rad/s", "rpm", "m/s"), "one of rad/s, rpm, m/s"),
        "accel": (nonneg, ">= 0"),
        "step": (lambda x: 1e-3 <= x <= 3600.0, "in [1e-3, 3600] s"),
        "v_max": (lambda x: 0 < x <= MAX_SPEED, f"in (0, {MAX_SPEED:g}] m/s"),
        "w_max": (lambda x: 0 <= x <= 20.0, "in [0, 20] rad/s"),
        "v": (lambda x: abs(x) <= MAX_SPEED, f"in [-{MAX_SPEED:g}, {MAX_SPEED:g}] m/s"),
    }

    def _check_whole(self) -> tuple[str, object, str] | None:
        """What the fields' own ranges cannot see: a segment value the command's kind cannot turn into wheel speeds
        (a wheel speed that is infinite, a radius of 0, a curvature ratio below 0); (field, value, expected)."""
        for i, s in enumerate(self.segments):
            if self.kind == "wheel_speeds" and not abs(s.b) <= MAX_SEGMENT_VALUE:
                return f"segments[{i}].b", s.b, f"a finite wheel speed, |b| <= {MAX_SEGMENT_VALUE:g}"
            if self.kind in ("v_radius", "v_curvature_ratio") and not abs(s.a) <= MAX_SPEED:
                return f"segments[{i}].a", s.a, f"a speed in [-{MAX_SPEED:g}, {MAX_SPEED:g}] m/s"
            if self.kind == "v_radius" and not abs(s.b) >= 1e-3:
                return f"segments[{i}].b", s.b, "a radius with |b| >= 1 mm (inf: straight)"
            if self.kind == "v_curvature_ratio" and not s.b >= 0.0:
                return f"segments[{i}].b", s.b, "a curvature ratio >= 0 (the right tread the faster; inf: straight)"
        return None


@dataclass(frozen=True)
class Scenario:
    id: str
    platform: Platform
    terrain: Terrain
    command: CommandSpec
    duration: float
    dt: float = 1.0 / 120.0  # physics step [s]
    log_rate_hz: float = 100.0
    initial_speed: float = 0.0  # [m/s] forward speed at t = 0 (Yu's ramps)
    initial_yaw: float = 0.0
    initial_yaw_rate: float = 0.0  # [rad/s] chassis yaw rate at t = 0 (bench.sim.startup: a run that starts in a turn)
    initial_skid_ratio: float = 1.0  # wheels' differential yaw rate / the chassis's at t = 0 (chi; 1 = no skid)
    description: str = ""
    paper: str = ""
    source_file: str = ""

    _checks = {
        "duration": (lambda x: 0 < x <= 4 * 3600, "in (0, 14400] s"),
        "dt": (lambda x: 1e-4 <= x <= 0.02, "in [1e-4, 0.02] s"),
        "log_rate_hz": (sensor_rate, SENSOR_RATE_RANGE),
        "initial_speed": (lambda x: abs(x) <= MAX_SPEED, f"in [-{MAX_SPEED:g}, {MAX_SPEED:g}] m/s"),
        "initial_yaw_rate": (lambda x: math.isfinite(x) and abs(x) <= 10.0, "in [-10, 10] rad/s"),
        "initial_skid_ratio": (lambda x: 0.0 <= x <= 20.0, "in [0, 20]"),
    }


# --------------------------------------------------------------------------------------------
# Loading
# --------------------------------------------------------------------------------------------
def _set_dotted(data: dict[str, Any], dotted: str, value: Any) -> None:
    parts = dotted.split(".")
    node = data
    for p in parts[:-1]:
        node = node.setdefault(p, {})
        if not isinstance(node, dict):
            raise SpecError("<--set>", dotted, value, "cannot set a field inside a non-table")
    node[parts[-1]] = value


def parse_override(text: str) -> tuple[str, Any]:
    """Parse ``key.path=value`` (value in TOML syntax; bare words are strings)."""
    if "=" not in text:
        raise SpecError("<--set>", text, text, "expected key=value")
    key, raw = text.split("=", 1)
    key = key.strip()
    try:
        value = tomllib.loads(f"v = {raw.strip()}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw.strip()
    return key, value


def _read_part(path: Path, cls: type) -> dict[str, Any]:
    """A platform or terrain file as data, its ``[sources]`` checked (:func:`bench.sources.file_sources`) and
    completed with the sources of the defaults it does not set, as ``data["sources"]`` (field -> Source)."""
    raw = read_toml(path)
    srcs = dict(Sources._from_spec(file_sources(raw, path), path, "sources"))
    data = {k: v for k, v in raw.items() if k != "sources"}
    if "dt_max" in data:  # a terrain's physics-step requirement: applied to the scenario (load_scenario), not kept
        dt_max, srcs = data["dt_max"], {k: v for k, v in srcs.items() if k != "dt_max"}
        if cls is not Terrain or not (isinstance(dt_max, float) and 1e-4 <= dt_max <= 0.02):
            raise SpecError(path, "dt_max", dt_max, "a terrain's largest physics step, in [1e-4, 0.02] s")
    data["sources"] = {**default_sources(cls, srcs), **srcs}
    return data


def _apply_dt_max(data: dict[str, Any]) -> None:
    """A scenario that sets no physics step runs at its terrain's ``dt_max`` when that is smaller than the
    default and the terrain's law is still the Janosi law the requirement was measured for (bench.sources)."""
    terr = data.get("terrain")
    dt_max = terr.pop("dt_max", None) if isinstance(terr, dict) else None
    if dt_max is not None and "dt" not in data and terr.get("model", "janosi") == "janosi":
        data["dt"] = min(Scenario.dt, dt_max)


def _mark_overrides(part: dict[str, Any], keys: list[str], ref: str,
                    given: Mapping[str, Source] | None = None) -> None:
    """The overridden fields of a platform / terrain table get kind ``override`` (``ref`` says where), or the
    source ``given`` names for them (a scenario file's [sources])."""
    srcs = part.get("sources")
    if isinstance(srcs, Mapping):
        part["sources"] = Sources(srcs).overridden([k for k in keys if k.split(".")[0] != "sources"], ref).sourced(
            given or {})


def load_platform(name_or_path: str | Path, root: Path = SCENARIO_DIR) -> Platform:
    path = known_file(name_or_path, root, "platform")
    return build(Platform, _read_part(path, Platform), path)


def load_terrain(name_or_path: str | Path, root: Path = SCENARIO_DIR) -> Terrain:
    path = known_file(name_or_path, root, "terrain")
    data = _read_part(path, Terrain)
    data.pop("dt_max", None)  # a requirement on the scenario's step (load_scenario), not a terrain field
    return build(Terrain, data, path)


def scenario_data(name_or_path: str | Path, root: Path = SCENARIO_DIR) -> tuple[Path, dict[str, Any]]:
    """The raw merged dict of a scenario: its platform and terrain files inlined as tables."""
    path = known_file(name_or_path, root, "scenario")
    raw = read_toml(path)
    data = dict(raw)
    for key, folder, cls in (("platform", "platforms", Platform), ("terrain", "terrains", Terrain)):
        ref = data.get(key)
        if ref is None:
            raise SpecError(path, key, None, "required field is missing")
        if isinstance(ref, str):
            ppath = resolve_name(ref, root / folder)
            if not ppath.is_file():
                raise SpecError(path, key, ref, f"unknown {key}: no file {ppath}")
            data[key] = _read_part(ppath, cls)
        elif not isinstance(ref, dict):
            raise SpecError(path, key, ref, f"expected a {key} name or table")
    # [platform_overrides] / [terrain_overrides] tables merge on top of the referenced files, each leaf with the
    # source the scenario's [sources] gives it (bench.sources.override_sources)
    given = override_sources(raw, path)
    data.pop("sources", None)
    for key in ("platform", "terrain"):
        ov = data.pop(f"{key}_overrides", None)
        if ov:
            data[key] = _deep_merge(data[key], ov)
            _mark_overrides(data[key], [k for k, _ in parameters(ov)], f"{path.name} [{key}_overrides]",
                            {k.partition(".")[2]: v for k, v in given.items() if k.startswith(key + ".")})
    return path, data


def _deep_merge(a: dict[str, Any], b: Mapping[str, Any]) -> dict[str, Any]:
    out = dict(a)
    for k, v in b.items():
        if isinstance(v, Mapping) and isinstance(out.get(k), dict):
            out[k] = _deep_merge(out[k], v)
        else:
            out[k] = v
    return out


def load_scenario(
    name_or_path: str | Path,
    overrides: Mapping[str, Any] | None = None,
    root: Path = SCENARIO_DIR,
) -> Scenario:
    """Load ``scenarios/<name>.toml`` with its platform and terrain, applying dotted overrides
    (``{"terrain.mu_sa": 0.5}``, as ``--set terrain.mu_sa=0.5`` on the command line)."""
    path, data = scenario_data(name_or_path, root)
    for key, value in (overrides or {}).items():
        _set_dotted(data, key, value)
        head, _, rest = key.partition(".")
        if head in ("platform", "terrain") and rest and isinstance(data.get(head), dict):
            keys = [rest + "." + k for k, _ in parameters(value)] if isinstance(value, Mapping) else [rest]
            _mark_overrides(data[head], keys, "--set")
    _apply_dt_max(data)
    data.setdefault("id", path.stem)
    data["source_file"] = str(path)
    return build(Scenario, data, path)


def scenario_from_dict(data: Mapping[str, Any], file: str = "<dict>") -> Scenario:
    return build(Scenario, data, file)


def replace(spec: Any, **changes: Any) -> Any:
    """``dataclasses.replace`` with dotted keys: replace(scn, **{"terrain.mu_sa": 0.5})."""
    nested: dict[str, dict[str, Any]] = {}
    flat: dict[str, Any] = {}
    for k, v in changes.items():
        if "." in k:
            head, rest = k.split(".", 1)
            nested.setdefault(head, {})[rest] = v
        else:
            flat[k] = v
    for head, sub in nested.items():
        flat[head] = replace(getattr(spec if head not in flat else flat, head), **sub)
    if isinstance(getattr(spec, "sources", None), Sources) and "sources" not in changes:
        flat["sources"] = spec.sources.overridden(changes, "replace()")
    return dataclasses.replace(spec, **flat)


def to_dict(spec: Any) -> dict[str, Any]:
    """Plain-data form (for hashing and metadata); the parameter sources are left out (provenance, not
    physics: a reworded source changes no run)."""
    return _without_sources(dataclasses.asdict(spec))


def _without_sources(d: Any) -> Any:
    if isinstance(d, dict):
        return {k: _without_sources(v) for k, v in d.items() if not isinstance(v, Sources)}
    return d


__all__ = [
    "SpecError", "MotorSpec", "PidSpec", "EncoderSpec", "ImuSpec", "GnssSpec", "ReferenceSpec",
    "SensorSpec", "Platform", "Terrain", "FrictionPatch", "Segment", "CommandSpec", "Scenario", "Source", "Sources",
    "build", "load_platform", "load_terrain", "load_scenario", "scenario_from_dict", "replace",
    "to_dict", "list_scenarios", "registered", "parse_override", "scenario_data",
]
_ = types  # keep import for type evaluation of PEP 604 unions on 3.11
