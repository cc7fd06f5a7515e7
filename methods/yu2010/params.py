"""Parameters of the Yu 2010 model: :class:`YuParams` (Table II defaults) and its constructor from a
skidbench :class:`~bench.spec.Platform` plus terrain-like parameters.

Symbols follow Yu et al. 2010, Table II; every quantity is SI.  Derived motor quantities
(armature resistance R_a, back-EMF constant K_B, controller limit V_max of eq. (27)) are
properties, so a calibrated copy (``dataclasses.replace``) keeps them consistent.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

G_STD = 9.81  # gravity [m/s^2]


@dataclass(frozen=True)
class YuParams:
    """Yu 2010 closed-loop model parameters (Table II defaults, Pioneer 3-AT on lab vinyl).

    Vehicle: ``m`` mass [kg], ``I`` yaw inertia [kg m^2], ``B`` track [m], ``b`` wheel width [m],
    ``L``/``C`` outer/inner extents of the front+rear contact patches [m] (Fig. 1: a patch spans
    C/2 <= |y| <= L/2 longitudinally, b laterally), ``r`` wheel radius [m].
    PID (Fig. 4): ``Kp``, ``Ki``, ``Kd`` act on the *linear* speed error e = r (w_d - w) [m/s] and
    output a motor voltage [V].
    Motor (eq. (26)): ``tau_s`` stall torque [N m] and ``omega_n`` no-load speed [rad/s] at the
    nominal voltage ``V``; ``K_T`` torque constant [N m/A]; ``I_max`` current limit [A]; ``g_r``
    gear ratio; ``n_motors`` motors per side (the P3-AT has one per wheel, two per side).
    ``I_motor``/``D_motor``: rotor inertia and viscous damping (Table II; neglected by Yu, used
    only when ``motor_dynamics`` is True).  ``P_max``: continuous mechanical power limit of one
    motor [W], |tau_m w_m| <= P_max (the "motor power limitations" of Yu's abstract and Sec. V-B;
    Table II gives no value, so 0 = no limit unless the platform's ``motor.max_power`` sets it).
    Motor controller (eq. (27)): ``PWM`` duty limit, ``V_CC`` supply, ``U_loss`` controller loss;
    ``vmax_current_term``: also subtract (27)'s current term R_a |I| from the limit, the reading that
    counts the armature drop twice (off by default; see :mod:`methods.yu2010.simulate`).
    Terrain: ``alpha`` expansion factor of eq. (1), ``K`` shear deformation modulus [m],
    ``mu_roll`` rolling resistance coefficient, ``mu_sa``/``mu_op`` friction when the motor drives
    / brakes (Sec. V-A).  ``slope`` ramp angle beta [rad] (eq. (24)) active after the vehicle has
    travelled ``ramp_start`` metres.
    Numerics: ``n_quad_y`` x ``n_quad_x`` Gauss-Legendre nodes per contact patch, ``n_table``
    points of the resistance lookup table over the wheel-speed direction, ``rest_speed`` [rad/s]
    below which the resistance is faded out linearly (regularised Coulomb stick at rest),
    ``mu_rule``: ``"consistent"`` (mu chosen from the sign of the steady resistance torque itself)
    or ``"motor"`` (sign of the previous step's motor torque vs wheel speed, literal Sec. V-A),
    ``anti_windup`` (not in the paper; off by default).
    """

    # vehicle (Table II)
    m: float = 30.6
    I: float = 0.816  # noqa: E741 - paper symbol
    B: float = 0.40
    b: float = 0.05
    L: float = 0.31
    C: float = 0.24
    r: float = 0.1075
    # PID (Table II)
    Kp: float = 30.25
    Ki: float = 151.25
    Kd: float = 0.0605
    # motor (Table II)
    tau_s: float = 0.2775
    omega_n: float = 487.16
    V: float = 12.0
    I_max: float = 5.5
    K_T: float = 0.023
    g_r: float = 49.8
    n_motors: int = 2
    I_motor: float = 0.000007
    D_motor: float = 0.000003
    P_max: float = 0.0
    motor_dynamics: bool = False
    # motor controller (Table II, eq. (27))
    PWM: float = 0.95
    V_CC: float = 12.0
    U_loss: float = 0.0
    vmax_current_term: bool = False  # (27)'s current term is (26)'s own armature drop: counted once
    # terrain: vinyl lab surface (Table II)
    alpha: float = 1.5
    K: float = 0.00054
    mu_roll: float = 0.0371
    mu_sa: float = 0.4437
    mu_op: float = 0.3093
    slope: float = 0.0
    ramp_start: float = 0.0
    g: float = G_STD
    # numerics
    n_quad_y: int = 16
    n_quad_x: int = 8
    n_table: int = 8192
    rest_speed: float = 0.05
    mu_rule: str = "consistent"
    anti_windup: bool = False

    def __post_init__(self) -> None:
        for name in ("m", "I", "B", "b", "L", "r", "tau_s", "omega_n", "V", "I_max", "K_T", "g_r",
                     "PWM", "V_CC", "alpha", "K", "mu_sa", "mu_op", "g", "rest_speed"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ValueError(f"YuParams.{name} = {v!r}: expected a finite number > 0")
        if not 0 <= self.C < self.L:
            raise ValueError(f"YuParams.C = {self.C!r}: expected 0 <= C < L = {self.L}")
        if not 0 <= self.mu_roll < 1:
            raise ValueError(f"YuParams.mu_roll = {self.mu_roll!r}: expected in [0, 1)")
        if self.mu_rule not in ("consistent", "motor"):
            raise ValueError(f"YuParams.mu_rule = {self.mu_rule!r}: expected 'consistent' or 'motor'")
        if not (math.isfinite(self.P_max) and self.P_max >= 0):
            raise ValueError(f"YuParams.P_max = {self.P_max!r}: expected a finite number >= 0 (0 = no limit)")
        if self.U_loss >= self.V_CC:
            raise ValueError(f"YuParams.U_loss = {self.U_loss!r}: expected < V_CC = {self.V_CC}")

    # ------------------------------------------------------------------ derived quantities
    @property
    def R_a(self) -> float:
        """Armature resistance from eq. (26): tau_s = V K_T / R_a at the nominal voltage."""
        return self.V * self.K_T / self.tau_s

    @property
    def K_B(self) -> float:
        """Back-EMF constant from eq. (26): omega_s = V / K_B = omega_n at the nominal voltage."""
        return self.V / self.omega_n

    @property
    def V_max(self) -> float:
        """First part of the controller output limit, eq. (27): PWM (V_CC - U_loss).  The
        current-dependent term, (dn/dtau) K_T I_m / K_n = R_a I_m, is applied per step when
        ``vmax_current_term`` is set (:mod:`methods.yu2010.simulate`)."""
        return self.PWM * (self.V_CC - self.U_loss)

    def saturation_wheel_speed(self, load_torque: float) -> float:
        """Steady wheel speed [rad/s] of a side at the controller limit carrying ``load_torque``
        [N m at the wheel]: the torque-speed line (26) at V_max, with the current term of (27)
        counted when ``vmax_current_term`` is set (closed form of the saturated closed loop)."""
        i_motor = load_torque / (self.n_motors * self.g_r * self.K_T)
        drops = 2.0 if self.vmax_current_term else 1.0
        return (self.V_max - drops * self.R_a * i_motor) / self.K_B / self.g_r

    @property
    def pressure(self) -> float:
        """Uniform normal pressure on flat ground, p = m g / (2 (L - C) b) (Wang 2015 after (21))."""
        return self.m * self.g / (2.0 * (self.L - self.C) * self.b)

    @property
    def side_torque_per_volt(self) -> float:
        """d tau_side / dV of the torque-speed line (26) at the wheel: n g_r K_T / R_a."""
        return self.n_motors * self.g_r * self.K_T / self.R_a

    @property
    def side_emf_damping(self) -> float:
        """Back-EMF damping of one side at the wheel: n g_r^2 K_T K_B / R_a [N m s/rad]."""
        return self.n_motors * self.g_r**2 * self.K_T * self.K_B / self.R_a

    @property
    def side_power(self) -> float:
        """Largest mechanical power of one side, n P_max [W] (0 = no limit): the side torque at the
        wheel obeys |tau w| <= n P_max, since tau_m w_m = (tau / (n g_r)) (g_r w)."""
        return self.n_motors * self.P_max

    @property
    def side_current_torque(self) -> float:
        """Largest side torque the current limit allows: n g_r K_T I_max [N m]."""
        return self.n_motors * self.g_r * self.K_T * self.I_max

    def mass_matrix(self) -> np.ndarray:
        """Mass matrix M of eq. (5), as printed: diagonal m r^2/4 + r^2 I/(alpha B^2), off-diagonal
        m r^2/4 - r^2 I/(alpha B^2).  (A kinetic-energy derivation with eq. (1) gives (alpha B)^2
        in the yaw term; we keep the paper's form.)  With ``motor_dynamics`` the reflected rotor
        inertia n g_r^2 I_motor is added to the diagonal."""
        a = self.m * self.r**2 / 4.0
        c = self.r**2 * self.I / (self.alpha * self.B**2)
        extra = self.n_motors * self.g_r**2 * self.I_motor if self.motor_dynamics else 0.0
        return np.array([[a + c + extra, a - c], [a - c, a + c + extra]])

    def gravity(self, slope: float | None = None) -> np.ndarray:
        """Gravitational term G(q) of eq. (24): m g r sin(beta)/2 per side."""
        beta = self.slope if slope is None else slope
        return np.full(2, self.m * self.g * self.r * math.sin(beta) / 2.0)

    def no_load_wheel_speed(self, voltage: float | None = None) -> float:
        """Wheel speed of the unloaded motor at ``voltage`` (default V_max) [rad/s]."""
        v = self.V_max if voltage is None else voltage
        return v / self.K_B / self.g_r

    def replace(self, **changes: Any) -> "YuParams":
        return dataclasses.replace(self, **changes)

    def with_platform(self, platform: Any) -> "YuParams":
        """A copy with the vehicle, motor and PID fields taken from a skidbench Platform (or its dict
        form, ``run.meta["platform"]``); terrain and numerical fields are kept.

        The Platform PID gains act on the wheel speed scaled by ``gain_scale`` (rad/s -> m/s when
        the scale is the wheel radius); Yu's gains act on the linear speed error, so
        Kp_yu = kp * gain_scale / r.  The nominal ``wheel_radius`` is used (Yu's r); the
        platform's effective-radius scales are testbed effects a user does not know."""
        p = _as_mapping(platform)
        if not p:
            return self
        kw: dict[str, Any] = {}
        r = float(p.get("wheel_radius", self.r))
        kw.update(
            m=float(p.get("mass", self.m)) + float(p.get("payload", 0.0)),
            I=float(p.get("yaw_inertia", self.I)),
            B=float(p.get("track", self.B)),
            b=float(p.get("wheel_width", self.b)),
            L=float(p.get("patch_length", self.L)),
            C=float(p.get("patch_gap", self.C)),
            r=r,
        )
        motor = _as_mapping(p.get("motor"))
        if motor:
            kw.update(
                tau_s=float(motor.get("stall_torque", self.tau_s)),
                omega_n=float(motor.get("no_load_speed", self.omega_n)),
                V=float(motor.get("nominal_voltage", self.V)),
                K_T=float(motor.get("torque_constant", self.K_T)),
                I_max=float(motor.get("max_current", self.I_max)),
                g_r=float(motor.get("gear_ratio", self.g_r)),
                PWM=float(motor.get("pwm", self.PWM)),
                V_CC=float(motor.get("supply_voltage", self.V_CC)),
                U_loss=float(motor.get("controller_loss", self.U_loss)),
                n_motors=int(motor.get("motors_per_side", self.n_motors)),
                P_max=float(motor.get("max_power", self.P_max)),
            )
        pid = _as_mapping(p.get("pid"))
        if pid:
            scale = float(pid.get("gain_scale", 1.0)) / r
            kw.update(Kp=float(pid.get("kp", self.Kp)) * scale, Ki=float(pid.get("ki", self.Ki)) * scale,
                      Kd=float(pid.get("kd", self.Kd)) * scale)
        return dataclasses.replace(self, **kw)

    def with_terrain(self, terrain: Any) -> "YuParams":
        """A copy with terrain fields from a :class:`~bench.spec.Terrain` or any object/mapping with
        ``mu_sa``, ``mu_op``, ``shear_modulus`` (or ``K``), ``rolling_resistance`` (or ``mu_roll``) and
        optionally ``slope``, ``ramp_start``, ``alpha``."""
        t = _as_mapping(terrain)
        names = {"mu_sa": "mu_sa", "mu_op": "mu_op", "shear_modulus": "K", "K": "K",
                 "rolling_resistance": "mu_roll", "mu_roll": "mu_roll", "slope": "slope",
                 "ramp_start": "ramp_start", "alpha": "alpha"}
        kw = {dst: float(t[src]) for src, dst in names.items() if src in t and t[src] is not None}
        return dataclasses.replace(self, **kw) if kw else self

    @classmethod
    def from_platform(cls, platform: Any, terrain: Any = None, **overrides: Any) -> "YuParams":
        """Parameters from a skidbench Platform (or its dict form) and optional terrain-like
        parameters (see :meth:`with_platform`, :meth:`with_terrain`); Table II values fill whatever
        is not given; ``overrides`` (field=value) win."""
        out = cls().with_platform(platform).with_terrain(terrain)
        return dataclasses.replace(out, **overrides) if overrides else out


def _as_mapping(obj: Any) -> Mapping[str, Any]:
    if obj is None:
        return {}
    if isinstance(obj, Mapping):
        return obj
    if dataclasses.is_dataclass(obj):
        return {f.name: getattr(obj, f.name) for f in dataclasses.fields(obj)}
    return {k: getattr(obj, k) for k in dir(obj) if not k.startswith("_")}
