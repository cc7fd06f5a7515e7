"""Closed-loop (Fig. 3) and open-loop (Fig. 16) simulation of the Yu 2010 model at a fixed step.

Per side (Fig. 3): modified PID (Fig. 4, derivative on the reference) on the linear speed error
e = r (w_d - w) -> motor voltage clamped to the controller limit of eq. (27) -> DC motor
torque-speed line (26), tau_m = (K_T/R_a)(V - K_B w_m), w_m = g_r w, with the current limit
|I| <= I_max and the motor power limit |tau_m w_m| <= P_max (when ``YuParams.P_max`` > 0; the
"motor power limitations" of Yu's abstract, value from the platform's motor) -> side torque
n g_r tau_m -> dynamics (25): M q_ddot + C(q_dot) + G(q) = tau.

Eq. (27): V_m,max = PWM (V_CC - U_loss) - (dn/dtau) K_T I_m / K_n.  With the motor's speed-torque gradient
dn/dtau = R_a/(K_T K_B) and the speed constant K_n = 1/K_B its current term is R_a I_m, so (27) is the Maxon
controller's maximum-speed line written in volts: K_B w_m,max = PWM (V_CC - U_loss) - R_a I_m ("V_m,max controls
the maximum speed of the motor", Sec. IV-C).  That is (26) itself at the terminal voltage PWM (V_CC - U_loss): the
controller clamps the voltage at PWM (V_CC - U_loss) and (26) takes the armature drop, once, as a motor has one
(the testbed reads (27) so too: bench/sim/drive.py).  ``YuParams.vmax_current_term = True`` takes the other
literal reading, V_m,max of (27) as the V_m of (26), which counts the drop twice (the stall torque at the limit
halved, the no-load speed unchanged; Fig. 17's 1.5 m/s run saturates 0.02 m/s lower): with the same-step current,
V <= V_max - R_a |I| and R_a I = V - K_B w_m (26) give the closed-form range
V in [(K_B w_m - V_max)/2, (K_B w_m + V_max)/2] (within +-V_max), so no algebraic loop and no one-step lag (a
lagged current would make the clamp oscillate with gain -1).  The default was that double reading until stop 54's
audit; Yu's 0.93 m/s (Fig. 17, experiment and model) does not tell them apart (0.935 / 0.912 m/s on the testbed).

The open loop replaces PID + controller by a given torque tau = K_tau V (Fig. 16 replays the
measured torque), clipped to the same motor limits (torque-speed line at V_max, current, power).

Integration: step at ``dt`` (default 1 kHz), linearly implicit in the resistance only:
(M + dt J) dq_dot = dt (tau - C - G), J = dC/dq_dot from the table slopes; this stays stable where
the resistance is stiff (low speed: C depends only on the direction of q_dot, so its gradient
grows like 1/|q_dot|).  The motor torque (PID, back-EMF) is explicit (its rate is ~60/s, far
below 1/dt), so the recorded torque is exactly the one applied over the step.  Near rest
(|q_dot| < ``rest_speed``) C is faded out linearly (regularised stick).  The per-step body uses
Python floats and list look-ups only.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from methods.yu2010.params import YuParams
from methods.yu2010.resistance import ResistanceTable, rolling_force


@dataclass(frozen=True)
class SimResult:
    """Simulated trajectories on the integration grid ``t`` (1/dt Hz).

    ``wl``/``wr`` wheel speeds [rad/s]; ``tau_l``/``tau_r`` side motor torques at the wheel [N m];
    ``volt_l``/``volt_r`` controller output voltages [V] (open loop: the voltage that puts the
    given torque on the motor line (26)); ``cur_l``/``cur_r`` current per motor [A];
    ``res_l``/``res_r`` resistance C [N m]; ``dist`` travelled distance [m]."""

    t: np.ndarray
    wl: np.ndarray
    wr: np.ndarray
    tau_l: np.ndarray
    tau_r: np.ndarray
    volt_l: np.ndarray
    volt_r: np.ndarray
    cur_l: np.ndarray
    cur_r: np.ndarray
    res_l: np.ndarray
    res_r: np.ndarray
    dist: np.ndarray


def zoh(t_src: np.ndarray, v_src: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Zero-order hold of samples (t_src, v_src) on grid ``t`` (before the first sample: the first)."""
    idx = np.searchsorted(t_src, t + 1e-12, side="right") - 1
    return v_src[np.clip(idx, 0, len(v_src) - 1)]


def equilibrium_integrator(params: YuParams, w: float, tau: float) -> float:
    """Integral state of the PID for which the motor holds torque ``tau`` at wheel speed ``w``
    with zero error (used to start the loop in steady state at a nonzero initial speed)."""
    if params.Ki == 0:
        return 0.0
    v = (tau + params.side_emf_damping * w) / params.side_torque_per_volt
    return float(np.clip(v, -params.V_max, params.V_max)) / params.Ki


def _integrate(params: YuParams, table: ResistanceTable, n: int, dt: float, ref_l: np.ndarray, ref_r: np.ndarray,
               dref_l: np.ndarray, dref_r: np.ndarray, tin_l: np.ndarray | None, tin_r: np.ndarray | None,
               w0: tuple[float, float], i0: tuple[float, float]) -> tuple[list[float], ...]:
    closed = tin_l is None
    p = params
    tab = table.as_lists()
    T_l, T_r, F_l, F_r = tab["tau_l"], tab["tau_r"], tab["F_l"], tab["F_r"]
    psi0, inv_dpsi, nmax = tab["psi0"], tab["inv_dpsi"], tab["n"] - 1
    motor_rule = p.mu_rule == "motor"
    r = p.r
    fr_torque = r * rolling_force(p)  # flat; scaled by cos(beta) below
    mu_sa, mu_op = p.mu_sa, p.mu_op
    kp, ki = p.Kp, p.Ki
    vmax = p.V_max
    cur_term = p.vmax_current_term
    kbg = p.K_B * p.g_r
    kv = p.side_torque_per_volt
    kw = p.side_emf_damping
    if p.motor_dynamics:
        kw_visc = p.n_motors * p.g_r**2 * p.D_motor
    else:
        kw_visc = 0.0
    tcap = p.side_current_torque
    pside = p.side_power
    M = p.mass_matrix()
    m11, m12 = float(M[0, 0]), float(M[0, 1])
    detM = m11 * m11 - m12 * m12
    rho_eps = p.rest_speed
    g_slope = p.m * p.g * r * math.sin(p.slope) / 2.0
    cb_slope = math.cos(p.slope)
    ramp_start = p.ramp_start
    ramp_pending = p.slope != 0.0 and ramp_start > 0.0  # flat until the ramp, then sloped
    gq, cb = (0.0, 1.0) if ramp_pending else (g_slope, cb_slope)
    anti_windup = p.anti_windup
    atan2, sqrt = math.atan2, math.sqrt

    wl, wr = float(w0[0]), float(w0[1])
    il, ir = float(i0[0]), float(i0[1])
    dist = 0.0
    half_r_dt = 0.5 * r * dt
    tml = tmr = 0.0
    o_wl = [0.0] * n
    o_wr = [0.0] * n
    o_tl = [0.0] * n
    o_tr = [0.0] * n
    o_vl = [0.0] * n
    o_vr = [0.0] * n
    o_cl = [0.0] * n
    o_cr = [0.0] * n
    rl_ = ref_l.tolist()
    rr_ = ref_r.tolist()
    dl_ = dref_l.tolist()
    dr_ = dref_r.tolist()
    if not closed:
        til = tin_l.tolist()  # type: ignore[union-attr]
        tir = tin_r.tolist()  # type: ignore[union-attr]
    for k in range(n):
        # ---------------------------------------------------------------- controller + motor
        # controller output range, eq. (27); with its current term solved with (26):
        # V <= V_max - R_a |I|, R_a I = V - K_B w_m  =>  V in [(K_B w_m - V_max)/2, (K_B w_m + V_max)/2]
        if cur_term:
            eml = kbg * wl
            emr = kbg * wr
            hil = 0.5 * (vmax + eml)
            lol = 0.5 * (eml - vmax)
            hir = 0.5 * (vmax + emr)
            lor = 0.5 * (emr - vmax)
            hil = vmax if hil > vmax else hil
            lol = -vmax if lol < -vmax else lol
            hir = vmax if hir > vmax else hir
            lor = -vmax if lor < -vmax else lor
        else:
            hil = hir = vmax
            lol = lor = -vmax
        if closed:
            el = r * (rl_[k] - wl)
            er = r * (rr_[k] - wr)
            ul = kp * el + ki * il + dl_[k]
            ur = kp * er + ki * ir + dr_[k]
            vl = hil if ul > hil else (lol if ul < lol else ul)
            vr = hir if ur > hir else (lor if ur < lor else ur)
            if not anti_windup or vl == ul or (vl > 0) != (el > 0):
                il += el * dt
            if not anti_windup or vr == ur or (vr > 0) != (er > 0):
                ir += er * dt
            tl = kv * vl - (kw + kw_visc) * wl  # eq. (26) at the wheel
            tr = kv * vr - (kw + kw_visc) * wr
        else:
            tl = til[k]
            tr = tir[k]
            hi_l = kv * hil - kw * wl
            lo_l = kv * lol - kw * wl
            tl = hi_l if tl > hi_l else (lo_l if tl < lo_l else tl)
            hi_r = kv * hir - kw * wr
            lo_r = kv * lor - kw * wr
            tr = hi_r if tr > hi_r else (lo_r if tr < lo_r else tr)
            vl = (tl + kw * wl) / kv  # the voltage that gives this torque on the line (26)
            vr = (tr + kw * wr) / kv
        tl = tcap if tl > tcap else (-tcap if tl < -tcap else tl)
        tr = tcap if tr > tcap else (-tcap if tr < -tcap else tr)
        if pside > 0.0:  # motor power limit: |tau_m w_m| <= P_max, i.e. |tau w| <= n P_max per side
            if tl * tl * wl * wl > pside * pside:
                tl = pside / abs(wl) if tl > 0.0 else -pside / abs(wl)
            if tr * tr * wr * wr > pside * pside:
                tr = pside / abs(wr) if tr > 0.0 else -pside / abs(wr)
        # ---------------------------------------------------------------- resistance C (table)
        if ramp_pending and dist >= ramp_start:
            gq, cb = g_slope, cb_slope
            ramp_pending = False
        rho2 = wl * wl + wr * wr
        if rho2 > 1e-24:
            u = (atan2(wr, wl) - psi0) * inv_dpsi
            i = int(u)
            if i > nmax:
                i = nmax
            f = u - i
            if motor_rule:
                mul = mu_sa if tml * wl > 0.0 else mu_op
                mur = mu_sa if tmr * wr > 0.0 else mu_op
                a0, a1 = F_l[i], F_l[i + 1]
                b0, b1 = F_r[i], F_r[i + 1]
                sgl = 1.0 if wl > 0.0 else (-1.0 if wl < 0.0 else 0.0)
                sgr = 1.0 if wr > 0.0 else (-1.0 if wr < 0.0 else 0.0)
                cl = r * mul * (a0 + f * (a1 - a0)) + fr_torque * sgl
                cr = r * mur * (b0 + f * (b1 - b0)) + fr_torque * sgr
                sl = r * mul * (a1 - a0) * inv_dpsi
                sr = r * mur * (b1 - b0) * inv_dpsi
            else:
                a0, a1 = T_l[i], T_l[i + 1]
                b0, b1 = T_r[i], T_r[i + 1]
                cl = a0 + f * (a1 - a0)
                cr = b0 + f * (b1 - b0)
                sl = (a1 - a0) * inv_dpsi
                sr = (b1 - b0) * inv_dpsi
            rho = sqrt(rho2)
            # d psi / d w = (-wr, wl) / rho2
            if rho < rho_eps:
                gs = rho / rho_eps
                gd = 1.0 / (rho_eps * rho)  # d g / d w = w / (rho rho_eps)
                j11 = cb * (gs * sl * (-wr) / rho2 + cl * gd * wl)
                j12 = cb * (gs * sl * wl / rho2 + cl * gd * wr)
                j21 = cb * (gs * sr * (-wr) / rho2 + cr * gd * wl)
                j22 = cb * (gs * sr * wl / rho2 + cr * gd * wr)
                cl *= gs * cb
                cr *= gs * cb
            else:
                j11 = -cb * sl * wr / rho2
                j12 = cb * sl * wl / rho2
                j21 = -cb * sr * wr / rho2
                j22 = cb * sr * wl / rho2
                cl *= cb
                cr *= cb
        else:
            cl = cr = j11 = j12 = j21 = j22 = 0.0
        # ---------------------------------------------------------------- dynamics (25)
        fl = (tl - cl - gq) * dt
        fr = (tr - cr - gq) * dt
        a11 = m11 + dt * j11
        a12 = m12 + dt * j12
        a21 = m12 + dt * j21
        a22 = m11 + dt * j22
        det = a11 * a22 - a12 * a21
        if det < 0.25 * detM or a11 <= 0.0 or a22 <= 0.0:  # non-dissipative slope: explicit step
            a11, a12, a21, a22, det = m11, m12, m12, m11, detM
        dwl = (a22 * fl - a12 * fr) / det
        dwr = (a11 * fr - a21 * fl) / det
        o_wl[k] = wl
        o_wr[k] = wr
        o_tl[k] = tl
        o_tr[k] = tr
        o_vl[k] = vl
        o_vr[k] = vr
        o_cl[k] = cl
        o_cr[k] = cr
        if ramp_pending:
            dist += abs(wl + wr) * half_r_dt
        wl += dwl
        wr += dwr
        tml, tmr = tl, tr
    return o_wl, o_wr, o_tl, o_tr, o_vl, o_vr, o_cl, o_cr


def _grid(t0: float, t_end: float, dt: float) -> np.ndarray:
    n = int(math.floor((t_end - t0) / dt + 1e-9)) + 1
    return t0 + dt * np.arange(n)


def _result(params: YuParams, t: np.ndarray, out: tuple[list[float], ...]) -> SimResult:
    wl, wr, tl, tr, vl, vr, cl, cr = (np.asarray(o) for o in out)
    k_i = 1.0 / (params.n_motors * params.g_r * params.K_T)
    dt = t[1] - t[0] if t.size > 1 else 0.0
    dist = np.concatenate(([0.0], np.cumsum(np.abs(wl + wr)[:-1]) * 0.5 * params.r * dt))  # before step k
    return SimResult(t, wl, wr, tl, tr, vl, vr, tl * k_i, tr * k_i, cl, cr, dist)


def simulate_closed_loop(t_cmd: ArrayLike, cmd_wl: ArrayLike, cmd_wr: ArrayLike, params: YuParams,
                         dt: float = 1e-3, t_end: float | None = None, w0: tuple[float, float] = (0.0, 0.0),
                         table: ResistanceTable | None = None) -> SimResult:
    """Closed loop of Fig. 3 for both sides, driven by commanded wheel speeds (held between their
    samples), from wheel speeds ``w0`` in steady state (PID integrators preloaded).

    The derivative term of the modified PID (Fig. 4) acts on the reference linear speed:
    Kd d(r w_d)/dt, a backward difference on the integration grid."""
    t_cmd = np.asarray(t_cmd, float)
    cl_, cr_ = np.asarray(cmd_wl, float), np.asarray(cmd_wr, float)
    if t_cmd.size == 0:
        raise ValueError("simulate_closed_loop: empty command")
    t = _grid(float(t_cmd[0]), float(t_cmd[-1] if t_end is None else t_end), dt)
    table = table or ResistanceTable.build(params)
    ref_l, ref_r = zoh(t_cmd, cl_, t), zoh(t_cmd, cr_, t)
    dref_l = params.Kd * params.r * np.diff(ref_l, prepend=ref_l[0]) / dt
    dref_r = params.Kd * params.r * np.diff(ref_r, prepend=ref_r[0]) / dt
    res0 = table(w0[0], w0[1], params.slope if params.ramp_start <= 0 else 0.0)
    g0 = params.gravity()[0] if params.ramp_start <= 0 else 0.0
    i0 = (equilibrium_integrator(params, w0[0], float(res0[0]) + g0) if w0[0] or w0[1] else 0.0,
          equilibrium_integrator(params, w0[1], float(res0[1]) + g0) if w0[0] or w0[1] else 0.0)
    out = _integrate(params, table, t.size, dt, ref_l, ref_r, dref_l, dref_r, None, None, w0, i0)
    return _result(params, t, out)


def simulate_open_loop(t_in: ArrayLike, tau_l: ArrayLike, tau_r: ArrayLike, params: YuParams, dt: float = 1e-3,
                       t_end: float | None = None, w0: tuple[float, float] = (0.0, 0.0),
                       table: ResistanceTable | None = None) -> SimResult:
    """Open loop of Fig. 3 / Fig. 16: side torques tau = K_tau V (here given directly, e.g. the
    measured torques, linearly interpolated between samples) clipped to the motor's torque-speed
    line at V_max and to the current limit, then the dynamics (25)."""
    t_in = np.asarray(t_in, float)
    if t_in.size == 0:
        raise ValueError("simulate_open_loop: empty torque input")
    t = _grid(float(t_in[0]), float(t_in[-1] if t_end is None else t_end), dt)
    table = table or ResistanceTable.build(params)
    tl = np.interp(t, t_in, np.asarray(tau_l, float))
    tr = np.interp(t, t_in, np.asarray(tau_r, float))
    z = np.zeros_like(t)
    out = _integrate(params, table, t.size, dt, z, z, z, z, tl, tr, w0, (0.0, 0.0))
    return _result(params, t, out)
