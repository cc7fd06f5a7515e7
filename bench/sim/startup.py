"""Start-up of a testbed run that begins moving: the chassis velocity, each side's wheel speed, the wheel-speed
references and the PID integrators at t = 0 (``Scenario.initial_speed``, ``initial_yaw_rate``,
``initial_skid_ratio``), and the rolling-resistance helpers the start and the loop share.

A scenario that starts moving at forward speed ``v`` [m/s] and yaw rate ``w_z`` [rad/s]: at t = 0 (after the
settling on the ground) the chassis CoM gets the velocity ``v`` along the chassis's forward axis (no lateral
velocity) and the angular velocity ``w_z`` about the chassis's normal axis; each side's wheels spin at
``(v -+ chi w_z B / 2) / r_side`` (left -, right +; ``chi`` = ``initial_skid_ratio``, the ratio of the wheels'
differential yaw rate to the chassis's: 1 is the no-skid kinematics, a skid-steered vehicle in a steady turn has
chi > 1, e.g. ``1 + (a / b)^2`` for Coulomb friction, equal loads and a spot turn); the wheel-speed references start
at the wheel speeds, and each side's PID integrator holds the voltage that keeps its wheels at that speed against
the torque the side needs: slope and rolling resistance (rolling resistance opposing the side's spin), plus, in a
turn, the longitudinal tire forces of the side's contacts in that initial state (the loop's own tire law,
friction coefficient, tire contact, soil and friction patches, evaluated on the contacts of the settled chassis).
So a turn started in its own steady state has no start-up transient beyond what the kinematic start leaves out
(the lateral velocity and the load transfer of the turn).

``initial_yaw_rate = 0`` takes exactly the straight start of testbed version 3 (bit for bit for ``v >= 0``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable, Sequence

from bench.sim.drive import MotorConstants, SidePid
from bench.sim.soil import compaction_resistance, sinkage
from bench.sim.tire import friction_coefficient
from bench.spec import Platform, Scenario, Terrain

GRAVITY = 9.81
HOLD_PASSES = 3  # fixed-point passes of the hold torque <-> friction coefficient (mu_sa / mu_op on torque x speed)


@dataclass(frozen=True)
class ContactLaw:
    """What the loop's contact force needs besides the contact (bound in :func:`bench.sim.testbed.run_physics`)."""

    law: Callable[..., tuple[float, float, float]]  # bench.sim.tire.tire_law
    tire: tuple[float, float] | None  # (patch_coef, radius_coef) of a tire model, else None
    soil: tuple[float, float, float, float, float, float] | None  # bench.sim.soil.soil_constants, else None


def initial_wheel_speeds(scn: Scenario) -> tuple[float, float]:
    """Each side's wheel speed [rad/s] at t = 0: ``(v -+ chi w_z B / 2) / r_side`` (module docstring)."""
    plat, v0 = scn.platform, scn.initial_speed
    r = plat.wheel_radius
    if scn.initial_yaw_rate == 0.0:
        return v0 / (r * plat.wheel_radius_scale_l), v0 / (r * plat.wheel_radius_scale_r)
    half = 0.5 * scn.initial_skid_ratio * scn.initial_yaw_rate * plat.track
    return (v0 - half) / (r * plat.wheel_radius_scale_l), (v0 + half) / (r * plat.wheel_radius_scale_r)


def rolling_coefficient(plat: Platform, terr: Terrain) -> float:
    """Rolling-resistance coefficient on rigid ground: the terrain's plus the tire's (``Platform.tire_rolling_resistance``,
    the tire's difference from the tire the terrain's value was measured with); on soil only the compaction acts."""
    mu = terr.rolling_resistance + plat.tire_rolling_resistance
    if mu < 0.0:
        raise ValueError(f"platform {plat.name} on {terr.name}: rolling resistance {mu} < 0 "
                         f"(terrain {terr.rolling_resistance} + tire {plat.tire_rolling_resistance})")
    return mu


def side_rolling_resistance(plat: Platform, terr: Terrain, weight: float) -> float:
    """Rolling resistance [N] of one side's two wheels at rest on the slope, equal loads: mu_roll N on rigid ground
    (terrain and tire, :func:`rolling_coefficient`), Bekker's compaction resistance at the static sinkage on soil."""
    normal = weight * math.cos(terr.slope)
    if terr.soil_model != "bekker":
        return 0.5 * rolling_coefficient(plat, terr) * normal
    z = sinkage(normal / 4.0, plat.wheel_radius, plat.wheel_width, terr.soil_n, terr.soil_k_c, terr.soil_k_phi)
    return 2.0 * compaction_resistance(z, plat.wheel_width, terr.soil_n, terr.soil_k_c, terr.soil_k_phi)


def wheel_frame(fwd: tuple[float, float, float], n: tuple[float, float, float]
                ) -> tuple[float, float, float, float, float, float]:
    """Unit longitudinal axis (chassis forward projected on the contact plane) and lateral axis
    ``n x e`` of a wheel whose contact normal is ``n``."""
    nx, ny, nz = n
    dot = fwd[0] * nx + fwd[1] * ny + fwd[2] * nz
    ex, ey, ez = fwd[0] - dot * nx, fwd[1] - dot * ny, fwd[2] - dot * nz
    en = math.sqrt(ex * ex + ey * ey + ez * ez)
    ex, ey, ez = ex / en, ey / en, ez / en
    return ex, ey, ez, ny * ez - nz * ey, nz * ex - nx * ez, nx * ey - ny * ex


def _tire_torques(scn: Scenario, contact: ContactLaw, contacts: Sequence[Any], pos: Sequence[float],
                  rot: Sequence[float], lin: Sequence[float], ang: Sequence[float], w: Sequence[float],
                  r_eff: tuple[float, float], torque: Sequence[float]) -> list[float]:
    """Per side, the torque [N m] the side's tire forces put on its wheels in the given chassis and wheel state: the
    loop's contact force (run_physics: slip of the chassis point at each contact against the tread, the tire law,
    the friction coefficient for the side's motor ``torque``, tire, soil, friction patches at t = 0)."""
    terr = scn.terrain
    normal, cpos, cnorm = [0.0] * 4, [None] * 4, [None] * 4
    for c in contacts:
        li = c[3]
        if li >= 0:
            normal[li] += c[9]
            cpos[li] = c[6]
            cnorm[li] = c[7]
    fwd = (rot[0], rot[3], rot[6])
    (px, py, pz), (vx, vy, vz), (wx, wy, wz) = pos, lin, ang
    out = []
    for s in (0, 1):
        rr = r_eff[s]
        u = rr * w[s]
        mu_base = friction_coefficient(terr.mu_sa, terr.mu_op, torque[s], w[s])
        f_sum = 0.0
        for i in (2 * s, 2 * s + 1):
            nf = normal[i]
            if nf <= 0.0 or cpos[i] is None:
                continue
            ps, q = (contact.tire[0] * math.sqrt(nf), 1.0 - contact.tire[1] * nf) if contact.tire else (1.0, 1.0)
            cx, cy, cz = cpos[i]
            rx, ry, rz = cx - px, cy - py, cz - pz
            vcx, vcy, vcz = vx + wy * rz - wz * ry, vy + wz * rx - wx * rz, vz + wx * ry - wy * rx
            ex, ey, ez, lx, ly, lz = wheel_frame(fwd, cnorm[i])
            v_lon = vcx * ex + vcy * ey + vcz * ez
            v_lat = vcx * lx + vcy * ly + vcz * lz
            mu = mu_base
            if contact.soil is not None:
                z_coef, z_exp, _, _, tan_phi, ca_coef = contact.soil
                mu = tan_phi + ca_coef * math.sqrt(z_coef * nf ** z_exp) / nf
            for fp in terr.friction_patches:  # at t = 0 a periodic patch's scale is 1
                if fp.t_period <= 0 and fp.x_min <= cx <= fp.x_max and fp.y_min <= cy <= fp.y_max:
                    mu *= fp.mu_scale
            ui = u * q
            f_sum += q * contact.law(v_lon - ui, v_lat, ui, v_lon, nf, mu, ps)[0]
        out.append(rr * f_sum)
    return out


def start_moving(scn: Scenario, robot: int, cid: int, orn: Sequence[float], ang: Sequence[float],
                 motor: MotorConstants, pid: list[SidePid], r_eff: tuple[float, float], w: list[float],
                 refs: list[float], contact: ContactLaw) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """At t = 0 of a scenario that starts moving (module docstring): set the chassis velocity in pybullet, the wheel
    speeds ``w``, references ``refs`` and the PID integrators (in place); returns the chassis (linear, angular)
    velocity now in force."""
    import pybullet as p  # imported (banner handled) by bench.sim.testbed before any run

    plat, terr = scn.platform, scn.terrain
    v0, wz0 = scn.initial_speed, scn.initial_yaw_rate
    R0 = p.getMatrixFromQuaternion(orn)
    lin = (R0[0] * v0, R0[3] * v0, R0[6] * v0)
    if wz0 != 0.0:  # about the chassis's normal axis (world frame)
        ang = (ang[0] + wz0 * R0[2], ang[1] + wz0 * R0[5], ang[2] + wz0 * R0[8])
    p.resetBaseVelocity(robot, lin, ang, physicsClientId=cid)
    w[0], w[1] = initial_wheel_speeds(scn)
    weight = plat.total_mass * GRAVITY
    base = [(0.5 * weight * math.sin(terr.slope) + math.copysign(1.0, w[s]) * side_rolling_resistance(plat, terr, weight))
            * r_eff[s] for s in (0, 1)]
    hold = list(base)
    if wz0 != 0.0:
        pos = p.getBasePositionAndOrientation(robot, physicsClientId=cid)[0]
        contacts = p.getContactPoints(robot, -1, -2, -2, physicsClientId=cid)
        for _ in range(HOLD_PASSES):
            tire = _tire_torques(scn, contact, contacts, pos, R0, lin, ang, w, r_eff, hold)
            hold = [base[s] + tire[s] for s in (0, 1)]
    for s in (0, 1):
        amps = hold[s] / (motor.n * motor.gear * motor.eff * motor.K_T)
        volt = motor.K_B * motor.gear * w[s] + motor.R_a * amps
        pid[s].integ = volt / max(plat.pid.ki, 1e-9)
        pid[s].prev_ref = refs[s] = w[s]
    return tuple(lin), tuple(ang)
