"""The pybullet skid-steer testbed: one vehicle built from a Platform spec, one ground plane
(tilted for ramps), our own tire-ground tangential forces, per-side PID + DC motors.

What Bullet does: rigid-body chassis motion in 3-D, normal loads through soft sphere-plane
contacts under each wheel (load transfer on ramps and in turns), gravity.  What we do each
step: read the contact points and normal forces, compute the sliding velocity of each contact,
the tangential force of the terrain's tire law (``bench.sim.tire``), apply the summed force and
moment to the chassis, and integrate each side's wheel spin with the motor and PID
(``bench.sim.drive``) semi-implicitly (linearised in the wheel speed, so stiff tire and
back-EMF slopes stay stable at the physics step).

Both wheels of a side are chained (one spin state per side), as on the P3-AT, DUBHE and Yi's
robot.  The wheel spin is not a Bullet joint: wheels are sphere colliders on fixed links, so
Bullet's solver never sees wheel rotation (DESIGN.md testbed notes: Bullet's own wheel
friction is heading dependent and unusable).

Speed (issue 2 target: >= 100x real time for one P3-AT at dt = 1/120 s, i.e. <= 83 us a step):
a step is Bullet's ``stepSimulation`` (~20-30 us), five pybullet round trips (base pose, base
velocity, contact points, external force and torque: ~10 us) and the scalar Python of
``run_physics`` (~20-40 us; plain ``math`` on floats, constants bound once, the wheel frame computed
once per contact normal).  That arithmetic has a second implementation in C (``bench/sim/_kernel.c``,
built by ``pip install``; ~3 us a step): the same operations in the same order, so the same trace bit for
bit (tests/sim/test_kernel.py); used by default, ``SKIDBENCH_KERNEL=python`` runs the Python loop (also the
fallback when the extension is not built).  Measured on a Wang grid run at 1/1920 s: 35 us a step with the
C step against 70 us, of which ``stepSimulation`` is 19 us.  The pybullet client is kept per thread and emptied
between runs (``_client``): connecting costs ~25 ms and the first ground plane ~15 ms.  Measured numbers:
``make bench`` (tests/bench/test_bench_testbed.py).
"""
from __future__ import annotations

import atexit
import math
import os
import threading
from dataclasses import dataclass
from typing import Callable

import numpy as np

from bench.schema import SpecError
from bench.sim.commands import first_order_lag, rate_limit, wheel_reference, wheel_speed_scale
from bench.sim.drive import MotorConstants, SidePid, motor_law, motor_line_constants
from bench.sim.soil import soil_constants
from bench.sim.tire import friction_coefficient, tire_constants, tire_contact, tire_law
from bench.sim.startup import GRAVITY, ContactLaw, initial_wheel_speeds, rolling_coefficient, start_moving
from bench.sim.startup import wheel_frame as _wheel_frame
from bench.spec import Scenario
from bench.sim.ground import rough_ground  # after bench.spec: the uneven ground (ISO 8608)

try:  # the C step (built by pip install; the Python loop below is the reference and the fallback)
    from bench.sim import _kernel as KERNEL
except ImportError:  # pragma: no cover - a source tree without the built extension
    KERNEL = None



def _import_pybullet():
    """Import pybullet with its build banner sent to stderr (it prints on stdout, which would
    corrupt ``--json`` output)."""
    import os
    import sys

    sys.stdout.flush()
    saved = os.dup(1)
    os.dup2(2, 1)
    try:
        import pybullet
    finally:
        os.dup2(saved, 1)
        os.close(saved)
    return pybullet


p = _import_pybullet()
# contact and settling constants of every platform: testbed choices (no paper gives a contact stiffness), set when the
# testbed was built (88d1e1e), before any claim was scored, and unchanged since
CONTACT_STIFFNESS_PER_KG = 3300.0  # N/m per kg of vehicle: 1e5 for the P3-AT (DESIGN.md)
CONTACT_DAMPING_PER_KG = 65.0  # N s/m per kg: 2e3 for the P3-AT
M_EFF_FRACTION = 0.13  # effective mass of one contact for the force-slope cap (4 kg of 30.6 kg)
SETTLE_TIME = 0.5  # s of settling on the ground before t = 0
HOLD_TIME = 0.2  # s: time constant of a standing wheel's patch deflection (static friction)
SOIL_EPS = 0.01  # m/s: smoothing of the compaction resistance's sign (as the rolling torque's)
WHEEL_ORDER = ("fl", "rl", "fr", "rr")  # link index 0..3; sides: 0,1 left; 2,3 right

# physics-rate record columns
REC = (
    "t", "px", "py", "pz", "qx", "qy", "qz", "qw", "vx", "vy", "vz", "wx", "wy", "wz",
    "wl", "wr", "th_l", "th_r", "tau_l", "tau_r", "i_l", "i_r", "ref_l", "ref_r",
    "n_fl", "n_rl", "n_fr", "n_rr",
)
COL = {name: i for i, name in enumerate(REC)}


@dataclass(frozen=True)
class PhysicsTrace:
    """Everything recorded at the physics rate (world-frame CoM state, wheels, drive)."""

    data: np.ndarray  # (n_steps + 1, len(REC))
    cg_offset: tuple[float, float, float]  # CoM in the base link frame

    def __getitem__(self, name: str) -> np.ndarray:
        return self.data[:, COL[name]]


def _quat_about_y(angle: float) -> tuple[float, float, float, float]:
    return (0.0, math.sin(angle / 2), 0.0, math.cos(angle / 2))


def _build_world(scn: Scenario, cid: int) -> tuple[int, int, tuple[float, float, float]]:
    plat, terr = scn.platform, scn.terrain
    dt = scn.dt
    p.setGravity(0, 0, -GRAVITY, physicsClientId=cid)
    p.setPhysicsEngineParameter(
        fixedTimeStep=dt, numSubSteps=0, numSolverIterations=20, deterministicOverlappingPairs=1,
        physicsClientId=cid,
    )
    # ground: a plane rising along +x with the terrain slope (ramps of Yu 2010 Figs. 18-20)
    tilt = _quat_about_y(-terr.slope)
    z0 = 0.0  # ground height under the wheels at the start (0 on the plane)
    if terr.roughness_gd0 > 0:  # uneven ground: ISO 8608 heightfield tiles (bench/sim/ground.py)
        ground, z0 = rough_ground(p, cid, terr, plat, scn.initial_yaw)
    else:
        plane = p.createCollisionShape(p.GEOM_PLANE, physicsClientId=cid)
        ground = p.createMultiBody(0, plane, -1, (0, 0, 0), tilt, physicsClientId=cid)
        p.changeDynamics(ground, -1, lateralFriction=1.0, physicsClientId=cid)

    m_total = plat.total_mass
    m_wheel = 0.02 * m_total
    m_base = m_total - 4 * m_wheel
    a, b, r = plat.wheelbase / 2, plat.track / 2, plat.wheel_radius
    box = p.createCollisionShape(
        p.GEOM_BOX, halfExtents=(plat.body_length / 2, plat.body_width / 2, plat.body_height / 2),
        collisionFramePosition=(0, 0, plat.body_height / 2 + 0.25 * r), physicsClientId=cid,
    )
    sphere = p.createCollisionShape(p.GEOM_SPHERE, radius=r, physicsClientId=cid)
    # base link frame: geometric centre at axle height; the chassis CoM placed so that the whole vehicle's (with its
    # four wheels at the corners, at axle height) is at (cg_offset_x, cg_offset_y) from the geometric centre and
    # cg_height above the ground
    scale = m_total / m_base
    cg = (plat.cg_offset_x * scale, plat.cg_offset_y * scale, (plat.cg_height - r) * scale)
    links = [(a, b, 0.0), (-a, b, 0.0), (a, -b, 0.0), (-a, -b, 0.0)]
    # place on the tilted plane: the link origin r above the surface along its normal
    n = (-math.sin(terr.slope), 0.0, math.cos(terr.slope))  # plane normal after the tilt
    start = (n[0] * (r + 0.002), 0.0, n[2] * (r + 0.002) + z0)
    yaw = scn.initial_yaw
    q_yaw = (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2))
    orn = p.multiplyTransforms((0, 0, 0), tilt, (0, 0, 0), q_yaw)[1]
    robot = p.createMultiBody(
        baseMass=m_base, baseCollisionShapeIndex=box, baseVisualShapeIndex=-1,
        basePosition=start, baseOrientation=orn,
        baseInertialFramePosition=cg, baseInertialFrameOrientation=(0, 0, 0, 1),
        linkMasses=[m_wheel] * 4, linkCollisionShapeIndices=[sphere] * 4,
        linkVisualShapeIndices=[-1] * 4, linkPositions=links,
        linkOrientations=[(0, 0, 0, 1)] * 4,
        linkInertialFramePositions=[(0, 0, 0)] * 4, linkInertialFrameOrientations=[(0, 0, 0, 1)] * 4,
        linkParentIndices=[0] * 4, linkJointTypes=[p.JOINT_FIXED] * 4, linkJointAxis=[(0, 1, 0)] * 4,
        physicsClientId=cid,
    )
    # yaw inertia of the whole vehicle = platform's; wheels carry m_wheel (a^2 + b^2) each
    i_wheel_own = 0.4 * m_wheel * r * r
    izz_base = plat.yaw_inertia - 4 * (m_wheel * (a * a + b * b) + i_wheel_own)
    if izz_base <= 0:
        raise SpecError(f"platform {plat.name}", "platform.yaw_inertia", plat.yaw_inertia,
                        f"> {plat.yaw_inertia - izz_base:.4g} kg m^2: its four wheels at this track, wheelbase and "
                        "mass carry that much")
    ixx = m_base * (plat.body_width**2 + plat.body_height**2) / 12
    iyy = m_base * (plat.body_length**2 + plat.body_height**2) / 12
    p.changeDynamics(
        robot, -1, localInertiaDiagonal=(ixx, iyy, izz_base), linearDamping=0.0, angularDamping=0.0,
        lateralFriction=0.0, spinningFriction=0.0, rollingFriction=0.0, physicsClientId=cid,
    )
    k_c = CONTACT_STIFFNESS_PER_KG * m_total
    c_c = CONTACT_DAMPING_PER_KG * m_total
    for li in range(4):
        p.changeDynamics(
            robot, li, lateralFriction=0.0, spinningFriction=0.0, rollingFriction=0.0,
            contactStiffness=k_c, contactDamping=c_c, linearDamping=0.0, angularDamping=0.0,
            physicsClientId=cid,
        )
    return ground, robot, cg


_CLIENT = threading.local()


def _client() -> int:
    """This thread's pybullet DIRECT client, emptied for a new run.

    Connecting and building the ground on a fresh client costs ~40 ms (4 s of simulated time at
    100x real time), so the client is kept and emptied with ``resetSimulation``: it rebuilds the
    dynamics world from scratch, and ``_build_world`` sets every engine parameter we use, so a
    run on a reused client gives the same bytes as on a fresh one (tests/test_testbed.py).  One
    client per thread and per process (a forked worker connects its own).  The client is private
    to this module: nothing else may disconnect it (pybullet reuses client ids).
    """
    pid = os.getpid()
    cid = getattr(_CLIENT, "cid", -1)
    if cid >= 0 and _CLIENT.pid == pid and p.isConnected(cid):
        p.resetSimulation(physicsClientId=cid)
        return cid
    cid = p.connect(p.DIRECT)
    _CLIENT.cid, _CLIENT.pid = cid, pid
    atexit.register(_disconnect, cid, pid)
    return cid


def _disconnect(cid: int, pid: int) -> None:
    """Close a kept client at interpreter exit (only in the process that opened it)."""
    if os.getpid() == pid and p.isConnected(cid):
        p.disconnect(cid)


def _references(scn: Scenario, seed: int, n_steps: int) -> tuple[list[float], list[float]]:
    """Per-step wheel-speed references (rad/s) as the PID sees them, through the robot's own velocity
    controller: the command delayed by the actuator delay; mapped (``Platform.command_gain_sum/diff``: mean
    speed and half-difference scaled) and clipped (``command_limit_mean/diff``); before the delayed command
    starts, the initial wheel speeds (0 from rest); the mean and half-difference rate-limited
    (``command_accel_mean/diff``); both sides scaled to the wheel-speed limit (``wheel_speed_limit``); each side's
    powertrain lag.  Each stage is skipped at its default (gains 1, no limits, no lag), so that the command
    passes bit for bit.  Python floats out (faster scalar math in the loop)."""
    plat, dt = scn.platform, scn.dt
    t_cmd = np.arange(n_steps + 1) * dt - plat.actuator_delay
    ref_l, ref_r = wheel_reference(np.maximum(t_cmd, 0.0), scn.command, plat, seed)
    g_sum, g_diff = plat.command_gain_sum, plat.command_gain_diff
    lim_mean, lim_diff = plat.command_limit_mean, plat.command_limit_diff
    if g_sum != 1.0 or g_diff != 1.0 or math.isfinite(lim_mean) or math.isfinite(lim_diff):
        mean = np.clip(g_sum * 0.5 * (ref_l + ref_r), -lim_mean, lim_mean)
        half = np.clip(g_diff * 0.5 * (ref_r - ref_l), -lim_diff, lim_diff)
        ref_l, ref_r = mean - half, mean + half
    # the initial wheel speeds (bench.sim.startup: each side's, in a turn) until the delayed command starts
    w0_l, w0_r = initial_wheel_speeds(scn)
    ref_l, ref_r = np.where(t_cmd < 0, w0_l, ref_l), np.where(t_cmd < 0, w0_r, ref_r)
    if math.isfinite(plat.command_accel_mean) or math.isfinite(plat.command_accel_diff):
        mean = rate_limit(0.5 * (ref_l + ref_r), dt, plat.command_accel_mean, 0.5 * (w0_l + w0_r))
        half = rate_limit(0.5 * (ref_r - ref_l), dt, plat.command_accel_diff, 0.5 * (w0_r - w0_l))
        ref_l, ref_r = mean - half, mean + half
    ref_l, ref_r = wheel_speed_scale(ref_l, ref_r, plat.wheel_speed_limit)
    # per-side powertrain lag (DRIVE), from the initial wheel speed
    ref_l = first_order_lag(ref_l, dt, plat.powertrain_tau_l, w0_l)
    ref_r = first_order_lag(ref_r, dt, plat.powertrain_tau_r, w0_r)
    return ref_l.tolist(), ref_r.tolist()


def _kernel_loop(kern, scn: Scenario, motor: MotorConstants, pid: list[SidePid], r_eff: tuple[float, float],
                 robot: int, cid: int, n_settle: int, n_steps: int, progress: Callable[[float], None] | None,
                 contact: ContactLaw) -> np.ndarray:
    """The loop of :func:`run_physics` with its arithmetic in the C step (``bench.sim._kernel``): the same
    pybullet calls in the same order, the same trace bit for bit (tests/sim/test_kernel.py)."""
    getpos, getvel, getcp, mat = p.getBasePositionAndOrientation, p.getBaseVelocity, p.getContactPoints, p.getMatrixFromQuaternion
    force, torque_fn, step, WORLD = p.applyExternalForce, p.applyExternalTorque, p.stepSimulation, p.WORLD_FRAME
    kstep = kern.step
    total = n_settle + n_steps
    for k in range(-n_settle, n_steps + 1):
        pos, orn = getpos(robot, cid)
        lin, ang = getvel(robot, cid)
        if k == 0 and (scn.initial_speed != 0.0 or scn.initial_yaw_rate != 0.0):
            w, refs = [0.0, 0.0], [0.0, 0.0]
            lin, ang = start_moving(scn, robot, cid, orn, ang, motor, pid, r_eff, w, refs, contact)
            for s in (0, 1):
                kern.set_side(s, w[s], refs[s], pid[s].integ, pid[s].prev_ref)
        out = kstep(k, pos, orn, lin, ang, mat(orn), getcp(robot, -1, -2, -2, cid))
        if out is None:
            break
        if progress is not None and k >= 0 and k % 2000 == 0:
            progress((k + n_settle) / total)
        force(robot, -1, out[0], pos, WORLD, cid)
        torque_fn(robot, -1, out[1], WORLD, cid)
        step(cid)
    return np.frombuffer(kern.log(), dtype=np.float64).reshape(-1, len(REC)).copy()


def run_physics(scn: Scenario, seed: int, progress: Callable[[float], None] | None = None) -> PhysicsTrace:
    """Step the testbed through the scenario; return the physics-rate trace.

    Per step: two state queries (base pose, base velocity), one contact query, then per side the
    PID, the motor line and the tire law at each wheel contact, one external force and torque on
    the chassis, and ``stepSimulation``.  Scalar ``math`` on Python floats throughout (a tiny
    numpy operation costs ~1 us; this loop is the testbed's whole cost besides Bullet's step).
    """
    plat, terr = scn.platform, scn.terrain
    dt = scn.dt
    n_steps = int(round(scn.duration / dt))
    n_settle = int(round(SETTLE_TIME / dt))
    ref_l, ref_r = _references(scn, seed, n_steps)
    accel_w = scn.command.accel / plat.wheel_radius if scn.command.accel > 0 else math.inf

    cid = _client()
    try:
        ground, robot, cg = _build_world(scn, cid)
        motor = MotorConstants.from_spec(plat.motor)
        pid = [SidePid(plat.pid, motor.v_max), SidePid(plat.pid, motor.v_max)]
        motor_fn = motor_law(motor)
        r_eff = (plat.wheel_radius * plat.wheel_radius_scale_l, plat.wheel_radius * plat.wheel_radius_scale_r)
        dt_rr = (dt * r_eff[0] * r_eff[0], dt * r_eff[1] * r_eff[1])
        i_side = 2.0 * plat.wheel_inertia
        janosi = terr.model == "janosi"
        K, patch, eps = terr.shear_modulus, plat.patch_length - plat.patch_gap, terr.slip_velocity_eps
        patch = max(patch, 1e-3)  # Yu's L - C: the front plus rear patch extent of one side
        patch_wheel = patch / 2.0  # one wheel's patch length (L - C)/2
        k_max = M_EFF_FRACTION * plat.total_mass / dt
        k_hold = k_max / HOLD_TIME  # stiffness of a standing patch: settles in ~HOLD_TIME
        k_hold_dt = k_hold * dt
        defl = [[0.0, 0.0] for _ in range(4)]
        mu_roll = rolling_coefficient(plat, terr)
        tire = plat.tire_pressure > 0.0 or plat.tire_modulus > 0.0  # per-wheel patch and loaded radius from the load
        p_coef, q_coef = tire_contact(plat.wheel_radius, plat.wheel_width, plat.tire_pressure,
                                      plat.tire_modulus) if tire else (0.0, 0.0)
        patch_law = 1.0 if tire else patch_wheel  # with a tire, the law per metre of patch, scaled per wheel
        pid_slope = -motor.n * motor.gear * motor.eff * motor.K_T * plat.pid.kp * plat.pid.gain_scale / motor.R_a
        patches = terr.friction_patches
        mu_sa, mu_op = terr.mu_sa, terr.mu_op
        soil = terr.soil_model == "bekker"  # bench/sim/soil.py: a force model, the contact geometry stays rigid
        if soil:
            z_coef, z_exp, rc_coef, n1, tan_phi, ca_coef = soil_constants(
                plat.wheel_radius, plat.wheel_width, terr.soil_n, terr.soil_k_c, terr.soil_k_phi,
                terr.soil_cohesion, terr.soil_friction_angle)
        v_max, i_max = motor.v_max, motor.i_max
        lim = accel_w * dt
        # PID sampling: every physics step when the platform's rate is at least the physics rate
        # (Yu, Yi: 1 kHz; the step-convergence test shows the physics rate already converged);
        # a slower controller holds its output between samples.
        pid_every = max(1, int(round(1.0 / (dt * plat.pid.rate_hz))))
        pid_dt = dt * pid_every
        pid_adds_slope = pid_every == 1
        volts = [0.0, 0.0]
        law = tire_law(janosi, terr.mu_lat_ratio, K, terr.shear_modulus_lat_ratio, patch_law, eps, k_max,
                       terr.friction_speed_decay)
        contact = ContactLaw(law, (p_coef, q_coef) if tire else None,
                             (z_coef, z_exp, rc_coef, n1, tan_phi, ca_coef) if soil else None)
        k_amp = motor.n * motor.gear * motor.eff * motor.K_T  # side torque per ampere of one motor
        w = [0.0, 0.0]
        th = [0.0, 0.0]
        tau = [0.0, 0.0]
        cur = [0.0, 0.0]
        refs = [0.0, 0.0]
        normal = [0.0] * 4
        cpos: list = [None] * 4
        cnorm: list = [None] * 4
        if KERNEL is not None and os.environ.get("SKIDBENCH_KERNEL", "c") != "python":
            c_lon, c_lat, eps2 = tire_constants(K, terr.shear_modulus_lat_ratio, patch_law, eps)
            kern = KERNEL.Kernel(
                (dt, lim, eps, k_max, k_hold, k_hold_dt, mu_roll, pid_slope, mu_sa, mu_op, v_max, i_max, pid_dt,
                 i_side, k_amp, r_eff[0], r_eff[1], dt_rr[0], dt_rr[1], c_lon, c_lat, terr.mu_lat_ratio, eps2,
                 plat.pid.kp, plat.pid.ki, plat.pid.kd, terr.friction_speed_decay),
                (float(janosi), float(pid_every), float(pid_adds_slope), float(n_steps)),
                [(fp.x_min, fp.x_max, fp.y_min, fp.y_max, fp.mu_scale, fp.t_period) for fp in patches],
                ref_l, ref_r, math.hypot)
            kern.set_motor(*motor_line_constants(motor), plat.pid.gain_scale)
            if soil:
                kern.set_soil(z_coef, z_exp, rc_coef, n1, tan_phi, ca_coef)
            if tire:
                kern.set_tire(p_coef, q_coef)
            return PhysicsTrace(_kernel_loop(kern, scn, motor, pid, r_eff, robot, cid, n_settle, n_steps, progress,
                                                    contact), cg)
        # the log is one flat list of floats: floats are not tracked by the cyclic GC, so the loop
        # allocates no lasting GC-tracked object (a list of row tuples triggered a collection
        # every ~700 steps, ~1 us a step)
        log: list[float] = []
        log_row = log.extend

        getpos = p.getBasePositionAndOrientation
        getvel = p.getBaseVelocity
        getcp = p.getContactPoints
        force = p.applyExternalForce
        torque_fn = p.applyExternalTorque
        step = p.stepSimulation
        mat = p.getMatrixFromQuaternion
        WORLD = p.WORLD_FRAME
        tanh, hypot, copysign = math.tanh, math.hypot, math.copysign

        total = n_settle + n_steps
        for k in range(-n_settle, n_steps + 1):
            # positional client ids: keyword parsing costs ~0.25 us a call, ~1.2 us a step
            pos, orn = getpos(robot, cid)
            lin, ang = getvel(robot, cid)
            if k == 0 and (scn.initial_speed != 0.0 or scn.initial_yaw_rate != 0.0):
                lin, ang = start_moving(scn, robot, cid, orn, ang, motor, pid, r_eff, w, refs, contact)
            # references (rate-limited)
            if k >= 0:
                dref = ref_l[k] - refs[0]
                refs[0] += dref if abs(dref) <= lim else copysign(lim, dref)
                dref = ref_r[k] - refs[1]
                refs[1] += dref if abs(dref) <= lim else copysign(lim, dref)
            R = mat(orn)
            fwd = (R[0], R[3], R[6])
            px, py, pz = pos
            lx_, ly_, lz_ = lin
            wx_, wy_, wz_ = ang
            normal[0] = normal[1] = normal[2] = normal[3] = 0.0
            # the robot's only contacts are with the ground; robot is body A of each point
            for c in getcp(robot, -1, -2, -2, cid):  # (bodyA, any bodyB, any links)
                li = c[3]
                if li >= 0:
                    normal[li] += c[9]
                    cpos[li] = c[6]
                    cnorm[li] = c[7]
            frame_n = frame = None  # wheel frame of the last contact normal (all equal on a plane)
            fx = fy = fz = 0.0
            mx = my = mz = 0.0
            t_now = k * dt
            pid_tick = k % pid_every == 0
            for s in (0, 1):
                ws = w[s]
                if pid_tick:  # the controller samples at min(pid.rate_hz, 1/dt); its output is held between
                    volts[s] = pid[s](refs[s], ws, pid_dt)
                volt = volts[s]
                tq, cu, dtq = motor_fn(volt, ws)
                if pid_tick and pid_adds_slope and abs(volt) < v_max and abs(cu) < i_max:
                    dtq += pid_slope  # the PID's proportional action reacts to the new wheel speed too
                mu_base = friction_coefficient(mu_sa, mu_op, tq, ws)
                rr = r_eff[s]
                u = rr * ws
                f_lon_sum = 0.0
                stiff_sum = 0.0
                n_side = 0.0
                # stiffness-weighted wheel directions and moments: the force correction for the
                # new wheel speed is rr * dw * (these sums), applied after the side's update
                sx = sy = sz = smx = smy = smz = 0.0
                for i in (2 * s, 2 * s + 1):
                    nf = normal[i]
                    if nf <= 0.0 or cpos[i] is None:
                        continue
                    if tire:  # this wheel's patch length and loaded rolling radius r q (bench.sim.tire.tire_contact)
                        ps = p_coef * math.sqrt(nf)
                        q = 1.0 - q_coef * nf
                    else:
                        ps = q = 1.0
                    ui = u * q
                    n_side += nf * q
                    cx, cy_, cz = cpos[i]
                    rx, ry, rz = cx - px, cy_ - py, cz - pz
                    # velocity of the chassis material point at the contact
                    vcx = lx_ + wy_ * rz - wz_ * ry
                    vcy = ly_ + wz_ * rx - wx_ * rz
                    vcz = lz_ + wx_ * ry - wy_ * rx
                    if cnorm[i] != frame_n:
                        frame_n = cnorm[i]
                        frame = _wheel_frame(fwd, frame_n)
                    ex, ey, ez, lx, ly, lz = frame
                    v_lon = vcx * ex + vcy * ey + vcz * ez
                    v_lat = vcx * lx + vcy * ly + vcz * lz
                    mu = mu_base
                    f_rc = 0.0
                    if soil:  # Bekker sinkage under the current load; shear strength c A + W tan phi
                        z = z_coef * nf ** z_exp
                        mu = tan_phi + ca_coef * math.sqrt(z) / nf
                        # compaction resistance R_c: the rim's normal pressure, horizontal component against the
                        # travel, a force on the body (Wong Ch. 2: DP = F - R_c), not a torque on the wheel; its
                        # smooth sign's slope capped at k_max like the tire law's
                        rc = rc_coef * z ** n1
                        f_rc = -rc * tanh(v_lon / max(SOIL_EPS, rc / k_max))
                    if patches:
                        for fp in patches:
                            if fp.x_min <= cx <= fp.x_max and fp.y_min <= cy_ <= fp.y_max:
                                scale = fp.mu_scale
                                if fp.t_period > 0:
                                    scale = 1.0 + (fp.mu_scale - 1.0) * 0.5 * (1 - math.cos(2 * math.pi * t_now / fp.t_period))
                                mu *= scale
                    f_lon, f_lat, stiff = law(v_lon - ui, v_lat, ui, v_lon, nf, mu, ps)
                    if abs(ui) < eps and abs(v_lon) < eps and abs(v_lat) < eps:
                        # standing wheel: the patch sticks. Its elastic deflection (a bristle
                        # spring, LuGre-like) holds the robot on a slope without creep; the
                        # velocity cap alone would act as a viscous damper and let it creep.
                        d = defl[i]
                        d[0] += (v_lon - ui) * dt
                        d[1] += v_lat * dt
                        f_lon -= k_hold * d[0]
                        f_lat -= k_hold * d[1]
                        f_abs = hypot(f_lon, f_lat)
                        f_lim = mu * nf
                        if f_abs > f_lim:  # breaks away: sliding friction, deflection relaxes
                            scale = f_lim / f_abs
                            f_lon, f_lat = f_lon * scale, f_lat * scale
                            d[0] *= scale
                            d[1] *= scale
                        stiff += k_hold_dt
                    else:
                        d = defl[i]
                        d[0] = d[1] = 0.0
                    # the wheel's radius r q: its torque q rr f_lon, its stiffness seen by the spin (q rr)^2 stiff
                    f_lon_sum += q * f_lon
                    stiff_sum += q * q * stiff
                    f_body = f_lon + f_rc  # the tire's shear and the soil's compaction resistance (0 off soil)
                    gx = f_body * ex + f_lat * lx
                    gy = f_body * ey + f_lat * ly
                    gz = f_body * ez + f_lat * lz
                    fx += gx
                    fy += gy
                    fz += gz
                    mx += ry * gz - rz * gy
                    my += rz * gx - rx * gz
                    mz += rx * gy - ry * gx
                    sq = stiff * q
                    sx += sq * ex
                    sy += sq * ey
                    sz += sq * ez
                    smx += sq * (ry * ez - rz * ey)
                    smy += sq * (rz * ex - rx * ez)
                    smz += sq * (rx * ey - ry * ex)
                # rolling resistance torque on the side's wheels, smooth sign: mu_roll sum N_i q_i (terrain + tire
                # coefficient) on rigid ground (the pressure shifted ahead of the axle); none on soil, where the
                # rim's pressure passes through the axle and the compaction resistance acts on the body (above)
                sgn = tanh(u / 0.01)
                roll = 0.0 if soil else mu_roll * n_side * rr
                t_roll = roll * sgn
                dt_roll = roll * (1 - sgn * sgn) * rr / 0.01
                num = tq - rr * f_lon_sum - t_roll
                den = i_side - dt * dtq + dt_rr[s] * stiff_sum + dt * dt_roll
                dw = dt * num / den
                c = rr * dw  # longitudinal forces consistent with the new wheel speed
                fx += c * sx
                fy += c * sy
                fz += c * sz
                mx += c * smx
                my += c * smy
                mz += c * smz
                ws += dw
                w[s] = ws
                th[s] += ws * dt
                # log what the wheel update applied: the linearised torque at the new wheel speed
                # (the open-loop replay of Yu Fig. 16 integrates exactly this impulse)
                tau[s] = tq + dtq * dw
                cur[s] = cu + dtq * dw / k_amp
            if k >= 0:
                log_row((
                    t_now, px, py, pz, orn[0], orn[1], orn[2], orn[3],
                    lx_, ly_, lz_, wx_, wy_, wz_,
                    w[0], w[1], th[0], th[1], tau[0], tau[1], cur[0], cur[1], refs[0], refs[1],
                    normal[0], normal[1], normal[2], normal[3],
                ))
                if k == n_steps:
                    break
                if progress is not None and k % 2000 == 0:
                    progress((k + n_settle) / total)
            else:
                th[0] = th[1] = 0.0
            force(robot, -1, (fx, fy, fz), pos, WORLD, cid)
            torque_fn(robot, -1, (mx, my, mz), WORLD, cid)
            step(cid)
    except BaseException:
        _CLIENT.cid = -1  # a failed run leaves its client to be dropped, not reused
        p.disconnect(cid)
        raise
    if progress is not None:
        progress(1.0)
    return PhysicsTrace(np.array(log, dtype=np.float64).reshape(-1, len(REC)), cg)
