"""Drive train of one side: Yu's modified PID, DC motor line, controller limits (Yu 2010 Sec. IV).

* PID (Fig. 4): ``u = Kp e + Ki int(e) + Kd d(ref)/dt`` with ``e = gain_scale (w_ref - w)`` (Yu's
  gains act on linear speed in m/s, so ``gain_scale`` = wheel radius), output = voltage command.
  Anti-windup: the integrator holds while the output saturates in the error's direction.
* Motor controller voltage limit (eq. (27)): ``V_max = PWM (V_CC - U_loss)``; the current-dependent
  term of (27) is the armature drop ``R_a I``, already in the motor line below.
* DC motor (eq. (26)): ``I = (V - K_B w_m) / R_a`` with ``R_a = V_nom K_T / tau_s``,
  ``K_B = V_nom / w_n``; current clamped to ``I_max``; mechanical power clamped to ``P_max``.
  Motor dynamics (inductance, rotor inertia) are neglected as Yu does; rotor inertia is part of
  the platform's wheel inertia.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

from bench.spec import MotorSpec, PidSpec


@dataclass(frozen=True)
class MotorConstants:
    R_a: float
    K_B: float
    K_T: float
    gear: float
    n: int
    eff: float
    i_max: float
    p_max: float
    v_max: float

    @classmethod
    def from_spec(cls, m: MotorSpec) -> "MotorConstants":
        return cls(
            R_a=m.nominal_voltage * m.torque_constant / m.stall_torque,
            K_B=m.nominal_voltage / m.no_load_speed,
            K_T=m.torque_constant,
            gear=m.gear_ratio,
            n=m.motors_per_side,
            eff=m.gear_efficiency,
            i_max=m.max_current,
            p_max=m.max_power,
            v_max=m.pwm * (m.supply_voltage - m.controller_loss),
        )


def motor_line_constants(c: MotorConstants) -> tuple[float, float, float, float, float, float, float, float]:
    """(gear, K_B, K_T, R_a, i_max, p_max, d tau_m / d w unsaturated, motor torque -> side torque at the
    wheels) bound by :func:`motor_law` and by the testbed's C step (one computation for both)."""
    slope_free = -c.K_T * c.K_B * c.gear / c.R_a
    k = c.n * c.gear * c.eff
    return c.gear, c.K_B, c.K_T, c.R_a, c.i_max, c.p_max, slope_free, k


def motor_law(c: MotorConstants) -> Callable[[float, float], tuple[float, float, float]]:
    """The side's motor line with its constants bound (called twice per physics step):
    ``law(volt, w) -> (wheel-side torque [N m], current per motor [A], d torque / d w)``."""
    gear, K_B, K_T, R_a, i_max, p_max, slope_free, k = motor_line_constants(c)
    copysign = math.copysign

    def law(volt: float, w: float) -> tuple[float, float, float]:
        wm = gear * w
        cur = (volt - K_B * wm) / R_a
        slope = slope_free
        if cur > i_max:
            cur, slope = i_max, 0.0
        elif cur < -i_max:
            cur, slope = -i_max, 0.0
        tau_m = K_T * cur
        if p_max > 0.0 and abs(tau_m * wm) > p_max:
            tau_m = copysign(p_max / max(abs(wm), 1e-9), tau_m)
            cur = tau_m / K_T
            slope = -abs(tau_m) / max(abs(w), 1e-9) * (1.0 if tau_m * w > 0 else -1.0)
        return k * tau_m, cur, k * slope

    return law


def motor_side_torque(c: MotorConstants, volt: float, w: float) -> tuple[float, float, float]:
    """(wheel-side torque [N m], current per motor [A], d torque / d w) for voltage and wheel speed
    (one-off evaluation of :func:`motor_law`)."""
    return motor_law(c)(volt, w)


class SidePid:
    """Yu 2010 Fig. 4 PID with derivative on the reference; state is per instance (one per side)."""

    __slots__ = ("kp", "ki", "kd", "scale", "v_max", "integ", "prev_ref")

    def __init__(self, spec: PidSpec, v_max: float):
        self.kp, self.ki, self.kd, self.scale = spec.kp, spec.ki, spec.kd, spec.gain_scale
        self.v_max = v_max
        self.integ = 0.0
        self.prev_ref = None

    def __call__(self, ref: float, w: float, dt: float) -> float:
        e = self.scale * (ref - w)
        d_ref = 0.0 if self.prev_ref is None else self.scale * (ref - self.prev_ref) / dt
        self.prev_ref = ref
        integ = self.integ + e * dt
        u = self.kp * e + self.ki * integ + self.kd * d_ref
        if u > self.v_max:
            u = self.v_max
            if e < 0:
                self.integ = integ
        elif u < -self.v_max:
            u = -self.v_max
            if e > 0:
                self.integ = integ
        else:
            self.integ = integ
        return u
