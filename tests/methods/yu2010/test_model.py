"""Tests of methods.yu2010 (Yu et al. 2010 dynamic model, closed and open loop).

Independent expectations: closed forms (rolling resistance, uniform stress, gravity, motor line,
saturation speed, constant-torque acceleration), the paper's literal equations (12)-(16) and their
integral definition (11)-(12), a second evaluation path (table vs quadrature, open vs closed
loop), symmetry/scale invariance, and self-consistency of the identification.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import quad

from bench.registry import calibrate, estimate
from bench.run import RunError, from_arrays
from bench.spec import load_platform
from methods.yu2010 import (
    LEMNISCATE_TAU0,
    ResistanceTable,
    Yu2010,
    Yu2010OpenLoop,
    YuParams,
    chi_vs_curvature_ratio,
    commanded_radii,
    evenly_spaced,
    identify,
    inverse_kinematics,
    lemniscate_command,
    lemniscate_v_radius,
    lemniscate_xy,
    resistance,
    shear_displacement,
    side_unit_forces,
    simulate_closed_loop,
    simulate_open_loop,
    steady_torques,
    unit_long_forces,
    wang2015_table1_params,
    wang_steady_state,
)
from methods.yu2010.resistance import patch_nodes

P = YuParams()
PLUG = P.replace(n_table=2048)  # a coarser resistance table keeps the plugin tests fast
WEIGHT = P.m * P.g
ROLL_TORQUE = P.r * P.mu_roll * WEIGHT / 2.0  # r f_r per side on flat ground


@pytest.fixture(scope="module")
def table() -> ResistanceTable:
    return ResistanceTable.build(P)


# ------------------------------------------------------------------------------------ helpers
def test_commanded_radii_are_yus_31() -> None:
    R = commanded_radii()
    assert R.size == 31
    np.testing.assert_allclose(R[:9], np.arange(2, 11) / 10)
    np.testing.assert_allclose(R[9:18], np.arange(2, 11))
    np.testing.assert_allclose(np.log10(R[18:23]), [1.2, 1.4, 1.6, 1.8, 2.0])
    np.testing.assert_allclose(np.log10(R[23:29]), [2.2, 2.4, 2.6, 2.8, 3.0, 3.2])
    np.testing.assert_allclose(np.log10(R[29:]), [3.6, 4.0])


def test_evenly_spaced_experiments() -> None:
    for n in range(2, 32):
        idx = evenly_spaced(31, n)
        assert idx.size == n and idx[0] == 0 and idx[-1] == 30
        assert np.ptp(np.diff(idx)) <= 1  # spacings differ by at most one


def test_inverse_kinematics_inverts_eq1() -> None:
    v, rho = np.array([0.2, 0.5, -0.3, 0.4]), np.array([4.0, -0.7, 2.0, np.inf])
    wl, wr = inverse_kinematics(v, rho, P)
    np.testing.assert_allclose(P.r * (wl + wr) / 2, v)  # eq. (1), first row
    wz = P.r * (wr - wl) / (P.alpha * P.B)  # eq. (1), second row
    np.testing.assert_allclose(wz, np.where(np.isinf(rho), 0.0, v / rho), atol=1e-15)


def test_from_platform_gives_table_ii() -> None:
    q = YuParams.from_platform(load_platform("p3at_pneumatic_20psi"))
    for f in ("m", "I", "B", "b", "L", "C", "r", "Kp", "Ki", "Kd", "tau_s", "omega_n", "K_T", "I_max", "g_r", "PWM"):
        assert getattr(q, f) == pytest.approx(getattr(P, f), rel=1e-12), f
    q2 = YuParams.from_platform({"wheel_radius": 0.095, "mass": 30.0, "payload": 2.0},
                                {"mu_sa": 0.6, "shear_modulus": 0.001}, alpha=2.0)
    assert (q2.r, q2.m, q2.mu_sa, q2.K, q2.alpha) == (0.095, 32.0, 0.6, 0.001, 2.0)


def test_bad_params_rejected() -> None:
    with pytest.raises(ValueError, match="K"):
        YuParams(K=0.0)
    with pytest.raises(ValueError, match="C"):
        YuParams(C=0.4)


# ------------------------------------------------------------------------------------ resistance
def test_pure_rolling_gives_only_rolling_resistance() -> None:
    w = np.array([0.5, 2.0, 9.0, -3.0])
    tl, tr = resistance(w, w, P)
    np.testing.assert_allclose(tl, np.sign(w) * ROLL_TORQUE, rtol=1e-12)
    np.testing.assert_allclose(tr, np.sign(w) * ROLL_TORQUE, rtol=1e-12)
    Fl, Fr = unit_long_forces(w, w, P)
    assert np.all(Fl == 0) and np.all(Fr == 0)  # no sliding friction at all


def test_uniform_shear_stress_integrates_to_p_mu_area() -> None:
    q = P.replace(K=1e-9)  # 1 - exp(-j/K) -> 1 wherever the tread slides
    area = (q.L - q.C) * q.b  # two patches of (L-C)/2 x b per side
    # locked wheel dragged straight ahead: sliding velocity (0, v) everywhere
    F, Flat, _ = side_unit_forces(0.0, 0.0, 0.4, 0.0, q.B / 2, q)
    assert F == pytest.approx(-q.pressure * area, rel=1e-12)
    assert Flat == pytest.approx(0.0, abs=1e-9)
    # wheel spinning on the spot (body at rest): sliding velocity (0, -r w)
    F2, _, _ = side_unit_forces(5.0, 0.0, 0.0, 0.0, -q.B / 2, q)
    assert F2 == pytest.approx(q.pressure * area, rel=1e-12)
    assert q.pressure * area == pytest.approx(q.m * q.g / 2)  # each side carries half the weight


def _paper_right_wheel(R, phidot, w, x_r, y, front):
    """Literal eqs. (12)-(13) (front) and (15)-(16) (rear), right wheel, Yu's frame."""
    X = R + P.B / 2 + x_r
    if front:
        th = (P.L / 2 - y) * phidot / (P.r * w)
        return X * (np.cos(th) - 1) - y * np.sin(th), X * np.sin(th) - P.L / 2 + y * np.cos(th)
    th = (-P.C / 2 - y) * phidot / (P.r * w)
    return X * (np.cos(th) - 1) - y * np.sin(th), X * np.sin(th) + P.C / 2 + y * np.cos(th)


def _integral_definition(w, ux, uy, phidot, x, y, y_e):
    """Eqs. (8), (11)-(12) generalised: integrate the element's sliding velocity rotated into the
    ground frame over its contact time (numerical quadrature)."""
    t = (y_e - y) / (P.r * w)

    def vel(tau):
        yy = y_e - P.r * w * tau
        vx, vy = ux - phidot * yy, uy + phidot * x - P.r * w
        c, s = math.cos(phidot * tau), math.sin(phidot * tau)
        return c * vx - s * vy, s * vx + c * vy

    jx = quad(lambda s: vel(s)[0], 0, t, epsabs=1e-13, epsrel=1e-11)[0]
    jy = quad(lambda s: vel(s)[1], 0, t, epsabs=1e-13, epsrel=1e-11)[0]
    return jx, jy


def test_shear_displacement_matches_paper_closed_form_and_integral() -> None:
    rng = np.random.default_rng(1)
    for _ in range(20):
        v = rng.uniform(0.05, 1.5)  # a physical turn: body speed v on radius R, wheel slip within +-50 %
        R = rng.choice([-1, 1]) * 10 ** rng.uniform(-0.7, 2.5)
        phidot = v / R
        w = (R + P.B / 2) * phidot * (1 + rng.uniform(-0.5, 0.5)) / P.r
        if w <= 0:
            w = -w
        front = bool(rng.integers(2))
        x_r = rng.uniform(-P.b / 2, P.b / 2)
        y = rng.uniform(P.C / 2, P.L / 2) * (1 if front else -1)
        y_e = P.L / 2 if front else -P.C / 2
        jx, jy, _ = shear_displacement(w, 0.0, R * phidot, phidot, P.B / 2 + x_r, y, y_e, P.r)
        if abs((y_e - y) * phidot / (P.r * w)) < np.pi:  # the paper's formula (no half-turn clamp)
            ex, ey = _paper_right_wheel(R, phidot, w, x_r, y, front)
            assert jx == pytest.approx(ex, abs=1e-12) and jy == pytest.approx(ey, abs=1e-12)
        ix, iy = _integral_definition(w, 0.0, R * phidot, phidot, P.B / 2 + x_r, y, y_e)
        assert jx == pytest.approx(ix, abs=1e-10) and jy == pytest.approx(iy, abs=1e-10)
    # general twist with lateral body velocity, backward rotation, straight motion
    for w, ux, uy, ph, y, y_e in [(-3.0, 0.05, -0.3, 0.4, 0.13, 0.12), (4.0, -0.1, 0.5, -0.7, -0.14, -0.12),
                                  (2.0, 0.02, 0.2, 0.0, 0.14, 0.155)]:
        jx, jy, _ = shear_displacement(w, ux, uy, ph, 0.21, y, y_e, P.r)
        ix, iy = _integral_definition(w, ux, uy, ph, 0.21, y, y_e)
        assert jx == pytest.approx(ix, abs=1e-10) and jy == pytest.approx(iy, abs=1e-10)


def test_quadrature_converges() -> None:
    R = commanded_radii()
    wl, wr = inverse_kinematics(0.2, R, P, alpha=1.0)
    base = np.array(resistance(wl, wr, P, nodes=patch_nodes(P)))
    fine = np.array(resistance(wl, wr, P, nodes=patch_nodes(P, 2 * P.n_quad_y, 2 * P.n_quad_x)))
    scale = np.maximum(np.abs(fine), ROLL_TORQUE)  # relative to the torque (rolling at least)
    assert np.max(np.abs(base - fine) / scale) < 0.005


def test_resistance_depends_only_on_direction_of_wheel_speeds() -> None:
    rng = np.random.default_rng(2)
    wl, wr = rng.normal(size=50) * 4, rng.normal(size=50) * 4
    a = np.array(resistance(wl, wr, P))
    for k in (0.1, 3.0):
        np.testing.assert_allclose(np.array(resistance(k * wl, k * wr, P)), a, rtol=1e-9, atol=1e-12)


def test_left_right_mirror_symmetry() -> None:
    wl, wr = inverse_kinematics(0.3, commanded_radii(), P, alpha=1.0)
    tl, tr = resistance(wl, wr, P)
    tl2, tr2 = resistance(wr, wl, P)  # the mirrored (clockwise) turn
    np.testing.assert_allclose(tl, tr2, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(tr, tl2, rtol=1e-9, atol=1e-12)


def test_table_matches_quadrature(table: ResistanceTable) -> None:
    rng = np.random.default_rng(3)
    psi = rng.uniform(-np.pi, np.pi, 3000)
    # away from the wheel-stop directions (w_l = 0 or w_r = 0), where C jumps (mu_sa <-> mu_op)
    psi = psi[np.minimum(np.abs(np.cos(psi)), np.abs(np.sin(psi))) > 2 * table.dpsi]
    wl, wr = 3 * np.cos(psi), 3 * np.sin(psi)
    exact = np.array(resistance(wl, wr, P))
    tab = np.array(table(wl, wr))
    peak = np.max(np.abs(exact))
    assert np.max(np.abs(tab - exact)) < 0.005 * peak
    wl, wr = inverse_kinematics(0.2, commanded_radii()[1:], P, alpha=1.0)  # all radii but the wheel stop
    np.testing.assert_allclose(np.array(table(wl, wr)), np.array(resistance(wl, wr, P)), atol=0.005 * peak)


def test_torque_magnitudes_fall_with_radius_fig9() -> None:
    tl, tr = steady_torques(commanded_radii(), 0.2, P)
    assert np.all(np.diff(tr) <= 1e-12)  # outer (right, CCW) wheel: driving torque falls
    assert np.all(np.diff(tl[1:]) >= -1e-12)  # inner wheel: braking torque shrinks towards rolling
    assert tr[0] > 5 * ROLL_TORQUE and tl[0] < -3 * ROLL_TORQUE
    assert tr[-1] == pytest.approx(ROLL_TORQUE, rel=0.01) and tl[-1] == pytest.approx(ROLL_TORQUE, rel=0.01)
    # speed independence Yu reports for 0.1-0.6 m/s (Sec. V-A)
    np.testing.assert_allclose(np.array(steady_torques(commanded_radii(), 0.6, P)), np.array([tl, tr]), rtol=1e-9)


def test_gravity_term_on_15_degree_ramp() -> None:
    beta = math.radians(15)
    G = P.gravity(beta)
    np.testing.assert_allclose(G, P.m * P.g * P.r * math.sin(beta) / 2)  # eq. (24)
    assert G[0] == pytest.approx(4.17, abs=0.01)  # 2.09 N m per wheel (DESIGN testbed note)


# ------------------------------------------------------------------------------------ identification
def test_identification_recovers_model_parameters() -> None:
    truth = P.replace(K=0.0007, mu_sa=0.5, mu_op=0.35)
    R = commanded_radii()
    tl, tr = steady_torques(R, 0.2, truth)
    for n in (3, 7, 31):
        res = identify(R, 0.2, tl, tr, P, n_experiments=n)  # starts from Table II
        assert res.success
        assert res.K == pytest.approx(0.0007, rel=0.01)
        assert res.mu_sa == pytest.approx(0.5, rel=0.01)
        assert res.mu_op == pytest.approx(0.35, rel=0.01)
        assert res.indices.size == n


def test_identification_rejects_nan() -> None:
    R = commanded_radii()[:5]
    with pytest.raises(ValueError, match=r"tau_r\[2\]"):
        identify(R, 0.2, np.ones(5), np.array([1, 1, np.nan, 1, 1.0]), P)


# ------------------------------------------------------------------------------------ closed loop
@pytest.mark.parametrize("current_term", [True, False])
def test_motor_stays_on_its_torque_speed_line_and_current_limit(table: ResistanceTable, current_term: bool) -> None:
    q = P.replace(vmax_current_term=current_term)
    v = 1.5
    wl, wr = inverse_kinematics(v, 0.3, q)
    w = v / q.r
    res = simulate_closed_loop([0, 2, 4], [w, wl, wl], [w, wr, wr], q, t_end=5.0, table=table)
    ng = q.n_motors * q.g_r
    tau_m = np.concatenate([res.tau_l, res.tau_r]) / ng  # per motor
    w_m = np.concatenate([res.wl, res.wr]) * q.g_r
    cur = np.concatenate([res.cur_l, res.cur_r])
    volt = np.concatenate([res.volt_l, res.volt_r])
    v_pwm = q.PWM * (q.V_CC - q.U_loss)
    R_a, K_B = q.V * q.K_T / q.tau_s, q.V / q.omega_n  # from the Table II motor line
    tau_s, w_s = v_pwm * q.K_T / R_a, v_pwm / K_B  # eq. (26) at the controller limit
    assert np.all(tau_m <= tau_s * (1 - w_m / w_s) + 1e-12)
    assert np.all(tau_m >= -tau_s * (1 + w_m / w_s) - 1e-12)
    assert np.all(np.abs(cur) <= q.I_max + 1e-12)
    assert np.max(np.abs(cur)) == pytest.approx(q.I_max)  # the current limit is reached
    limit = v_pwm - (R_a * np.abs(cur) if current_term else 0.0 * cur)  # eq. (27)
    unclipped = np.abs(cur) < q.I_max - 1e-9
    assert np.all(np.abs(volt[unclipped]) <= limit[unclipped] + 1e-9)
    assert np.max(np.abs(volt[unclipped]) - limit[unclipped]) == pytest.approx(0.0, abs=1e-9)  # and reached


@pytest.mark.parametrize("current_term", [True, False])
def test_saturation_speed_of_a_1p5_m_s_command(table: ResistanceTable, current_term: bool) -> None:
    q = P.replace(vmax_current_term=current_term)
    w = 1.5 / q.r
    res = simulate_closed_loop([0, 6], [w, w], [w, w], q, table=table)
    v_final = q.r * res.wl[-1]
    # closed form: motor at the controller limit carrying the rolling resistance; the armature drop
    # R_a I appears in (26) and, with the current term of (27), once more in the voltage limit
    i_motor = ROLL_TORQUE / (q.n_motors * q.g_r * q.K_T)
    v_pwm = q.PWM * (q.V_CC - q.U_loss)
    v_closed = q.r * (v_pwm - (2 if current_term else 1) * q.R_a * i_motor) * q.omega_n / q.V / q.g_r
    assert v_final == pytest.approx(v_closed, rel=1e-6)
    assert v_final < q.r * q.omega_n / q.g_r  # below the no-load speed
    assert v_final == pytest.approx(0.93, rel=0.06)  # Fig. 17: ~0.93 m/s (ours 0.954 / 0.976)


@pytest.mark.parametrize("load", [0.5, 2.0, 6.0])  # [N m] on one side, at the wheels
def test_the_model_reads_27_as_the_testbed_does_one_armature_drop(load: float) -> None:
    """By default the model counts (27)'s current term once, as the armature drop of (26), as the testbed's motor
    line does (bench.sim.drive, a second implementation): at the controller limit the side carrying ``load`` turns
    at the wheel speed where the testbed's line gives that torque.  The double reading turns slower."""
    import dataclasses

    from bench.sim.drive import MotorConstants, motor_law

    plat = load_platform("p3at_pneumatic_20psi")
    q = P.with_platform(plat)
    c = dataclasses.replace(MotorConstants.from_spec(plat.motor), eff=1.0, p_max=0.0, i_max=1e9)
    w = q.saturation_wheel_speed(load)
    tau, _cur, _slope = motor_law(c)(c.v_max, w)
    assert q.V_max == pytest.approx(c.v_max, rel=1e-12) and tau == pytest.approx(load, rel=1e-9)
    assert q.replace(vmax_current_term=True).saturation_wheel_speed(load) < w


def test_closed_loop_reaches_steady_state_of_the_resistance(table: ResistanceTable) -> None:
    wl, wr = inverse_kinematics(0.2, 4.0, P, alpha=1.0)  # Figs. 10-13: 0.2 m/s, R = 4 m
    res = simulate_closed_loop([0, 8], [wl, wl], [wr, wr], P, table=table)
    assert res.wl[-1] == pytest.approx(wl, rel=1e-5) and res.wr[-1] == pytest.approx(wr, rel=1e-5)
    el, er = resistance(wl, wr, P)
    assert res.tau_l[-1] == pytest.approx(el, rel=0.005) and res.tau_r[-1] == pytest.approx(er, rel=0.005)


def test_literal_motor_sign_mu_rule_reaches_the_same_steady_state() -> None:
    q = P.replace(mu_rule="motor")  # mu from the sign of the previous step's motor torque vs speed
    wl, wr = inverse_kinematics(0.3, 2.0, q, alpha=1.0)
    res = simulate_closed_loop([0, 8], [wl, wl], [wr, wr], q, table=ResistanceTable.build(q, 2048))
    el, er = resistance(wl, wr, P)  # consistent rule: at equilibrium the motor torque is C itself
    assert res.tau_l[-1] == pytest.approx(el, rel=0.005) and res.tau_r[-1] == pytest.approx(er, rel=0.005)


def test_ramp_starts_after_ramp_start_distance() -> None:
    beta = math.radians(10)
    q = P.replace(slope=beta, ramp_start=1.0)
    w = 0.5 / q.r
    res = simulate_closed_loop([0, 6], [w, w], [w, w], q, table=ResistanceTable.build(q, 1024), w0=(w, w))
    flat = res.dist < 0.9
    assert res.tau_l[flat][-1] == pytest.approx(ROLL_TORQUE, rel=1e-3)
    need = q.m * q.g * q.r * (math.sin(beta) + q.mu_roll * math.cos(beta)) / 2
    assert res.tau_l[-1] == pytest.approx(need, rel=1e-3)


def test_ramp_climb_needs_gravity_plus_rolling_torque() -> None:
    beta = math.radians(15)
    q = P.replace(slope=beta)
    w = 0.3 / q.r
    res = simulate_closed_loop([0, 5], [w, w], [w, w], q, table=ResistanceTable.build(q, 1024))
    need = q.m * q.g * q.r * (math.sin(beta) + q.mu_roll * math.cos(beta)) / 2
    assert res.wl[-1] == pytest.approx(w, rel=1e-5)
    assert res.tau_l[-1] == pytest.approx(need, rel=0.001) and res.tau_r[-1] == pytest.approx(need, rel=0.001)


def test_open_loop_constant_torque_acceleration(table: ResistanceTable) -> None:
    tau = 2.0  # stays inside the motor's torque-speed line over the 0.5 s
    res = simulate_open_loop([0, 0.5], [tau, tau], [tau, tau], P, table=table, w0=(2.0, 2.0))
    acc = (tau - ROLL_TORQUE) / (P.m * P.r**2 / 2)  # eq. (25), straight: (M11 + M12) w_dot = tau - r f_r
    slope = np.polyfit(res.t, res.wl, 1)[0]
    assert slope == pytest.approx(acc, rel=1e-9)
    assert np.all(res.tau_l == tau)


def test_open_loop_replaying_closed_loop_torque_reproduces_it(table: ResistanceTable) -> None:
    wl, wr = inverse_kinematics(0.4, 1.5, P)
    cl = simulate_closed_loop([0, 1, 3], [1.0, wl, wl], [1.0, wr, wr], P, table=table, w0=(1.0, 1.0))
    ol = simulate_open_loop(cl.t, cl.tau_l, cl.tau_r, P, table=table, w0=(1.0, 1.0))
    np.testing.assert_allclose(ol.wl, cl.wl, rtol=1e-9)
    np.testing.assert_allclose(ol.wr, cl.wr, rtol=1e-9)


# ------------------------------------------------------------------------------------ commands, Wang
def test_lemniscate_speed_radius_and_ramp() -> None:
    tau = np.linspace(0, 300, 601)
    h = 1e-4
    xp, yp = lemniscate_xy(tau + h)
    xm, ym = lemniscate_xy(tau - h)
    x0, y0 = lemniscate_xy(tau)
    dx, dy = (xp - xm) / (2 * h), (yp - ym) / (2 * h)
    ddx, ddy = (xp - 2 * x0 + xm) / h**2, (yp - 2 * y0 + ym) / h**2
    v, rho = lemniscate_v_radius(tau)
    np.testing.assert_allclose(v, np.hypot(dx, dy), rtol=1e-7)
    np.testing.assert_allclose(1 / rho, (dx * ddy - dy * ddx) / np.hypot(dx, dy) ** 3, atol=1e-4)
    t = np.arange(0, 22, 0.01)
    vc, rc = lemniscate_command(t)
    v0 = lemniscate_v_radius(LEMNISCATE_TAU0)[0]
    ramp = t < 3
    assert np.all(np.diff(vc[ramp]) <= 1.0 * 0.01 + 1e-12)  # 1 m/s^2
    assert vc[np.searchsorted(t, 2.99)] == pytest.approx(v0)  # reached within 3 s
    follow = (t >= 3) & (t <= 21)
    np.testing.assert_allclose(vc[follow], lemniscate_v_radius(LEMNISCATE_TAU0 + t[follow] - 3)[0])
    acc = np.diff(vc[follow]) / 0.01
    assert acc.min() >= -1e-9 and acc.max() <= 0.02  # Sec. V-C: accelerations in [0, 0.02] m/s^2
    assert vc[-1] == 0.0


def test_wang_chi_balances_forces_and_falls_with_curvature_ratio() -> None:
    q = wang2015_table1_params()
    lam = np.array([0.0, 1.0, 2.0, 3.0, 5.0, 7.0])
    st = wang_steady_state(q, lam, 0.1)
    assert np.all(st.residual < 1e-8)  # eq. (16) satisfied
    assert np.all(st.chi > 1.0)  # tread ICRs outside the treads (Wang eq. (15))
    assert np.all(np.diff(st.chi) < 0)  # Wang Fig. 5: chi decreases as lambda grows
    assert abs(st.vx[0]) < 1e-9 and abs(st.vy[0]) < 1e-9  # turning on the spot: symmetric, no drift
    assert np.all(st.wz > 0)  # v_r > v_l: counter-clockwise
    np.testing.assert_allclose(chi_vs_curvature_ratio(q, lam[:2], 0.1), st.chi[:2])


# ------------------------------------------------------------------------------------ plugin
def _circle_run(v=0.2, R=4.0, T=8.0, seed=0, alpha=1.5, torques=None, meta=None):
    rng = np.random.default_rng(seed)
    t = np.arange(0, T, 0.01)
    wl, wr = inverse_kinematics(v, R, P, alpha=1.0)
    cols = {"t": t, "cmd_wl": np.full_like(t, wl), "cmd_wr": np.full_like(t, wr)}
    if torques is not None:
        cols["tau_l"] = torques[0] + 0.005 * rng.normal(size=t.size)
        cols["tau_r"] = torques[1] + 0.005 * rng.normal(size=t.size)
        wz = P.r * (wr - wl) / (alpha * P.B)
        cols["ref_yaw"] = np.angle(np.exp(1j * (wz * t + 0.002 * rng.normal(size=t.size))))
    return from_arrays(cols, dict({"run_id": f"circle_R{R}_s{seed}"}, **(meta or {})))


def test_plugin_estimate_predicts_a_circle() -> None:
    m = Yu2010(PLUG)
    run = _circle_run(T=14.0)
    est = estimate(m, run)
    for c in ("t", "x", "y", "yaw", "vx", "wz", "wl", "wr", "tau_l", "tau_r"):
        assert c in est.data.columns
    wl, wr = inverse_kinematics(0.2, 4.0, P, alpha=1.0)
    wz = P.r * (wr - wl) / (P.alpha * P.B)  # eq. (1)
    tail = est.t > 10  # the PID integrator builds the turning torque slowly (friction-dominated mode)
    np.testing.assert_allclose(est["wz"][tail], wz, rtol=1e-4)
    np.testing.assert_allclose(est["vx"][tail], 0.2, rtol=1e-4)
    # the pose is eq. (1) integrated: it moves at vx along its heading (no lateral velocity)
    t, x, y, yaw = est.t[tail], est["x"][tail], est["y"][tail], est["yaw"][tail]
    dx, dy, dt = np.diff(x), np.diff(y), np.diff(t)
    np.testing.assert_allclose(np.hypot(dx, dy) / dt, 0.2, rtol=1e-3)
    mid = yaw[:-1] + np.diff(yaw) / 2
    np.testing.assert_allclose(np.arctan2(dy, dx), np.angle(np.exp(1j * mid)), atol=1e-6)
    np.testing.assert_allclose(np.diff(yaw) / dt, wz, rtol=1e-3)
    est2 = Yu2010(PLUG).estimate(run)
    assert est2.data.equals(est.data)  # deterministic, bit for bit


def test_plugin_uses_run_platform_geometry() -> None:
    run = _circle_run(meta={"platform": {"wheel_radius": 0.095, "track": 0.40, "mass": 30.6}})
    est = Yu2010(PLUG).estimate(run)
    wl, wr = inverse_kinematics(0.2, 4.0, P, alpha=1.0)
    assert est["vx"][-1] == pytest.approx(0.095 * (wl + wr) / 2, rel=1e-4)


def test_plugin_bad_input_names_channel() -> None:
    t = np.arange(0, 1, 0.01)
    run = from_arrays({"t": t, "cmd_wl": np.full_like(t, np.nan), "cmd_wr": np.ones_like(t)}, {"run_id": "bad"})
    with pytest.raises(RunError, match="cmd_wl"):
        Yu2010().estimate(run)
    run2 = from_arrays({"t": t, "cmd_wl": np.ones_like(t), "cmd_wr": np.ones_like(t)}, {"run_id": "bad2"})
    with pytest.raises(RunError, match="tau_l"):
        Yu2010OpenLoop().estimate(run2)


def test_plugin_calibrate_recovers_terrain() -> None:
    truth = P.replace(K=0.0008, mu_sa=0.52, mu_op=0.33, mu_roll=0.045, alpha=1.7)
    runs = []
    for i, R in enumerate([0.3, 0.6, 1.0, 3.0, 8.0, 25.0, 100.0]):
        wl, wr = inverse_kinematics(0.2, R, P, alpha=1.0)
        runs.append(_circle_run(R=R, T=4.0, seed=i, alpha=1.7, torques=resistance(wl, wr, truth)))
    straight = _circle_run(R=np.inf, T=4.0, seed=99, torques=resistance(2.0, 2.0, truth))
    m = calibrate(Yu2010(PLUG), runs + [straight])
    q = m.params
    assert q.mu_roll == pytest.approx(0.045, rel=0.01)
    assert q.alpha == pytest.approx(1.7, rel=0.01)
    assert q.K == pytest.approx(0.0008, rel=0.03)
    assert q.mu_sa == pytest.approx(0.52, rel=0.01)
    assert q.mu_op == pytest.approx(0.33, rel=0.01)


def test_open_loop_plugin_replays_measured_torque() -> None:
    wl, wr = inverse_kinematics(0.3, 2.0, P)
    tl, tr = resistance(wl, wr, P)
    t = np.arange(0, 3, 0.01)
    run = from_arrays({"t": t, "cmd_wl": np.full_like(t, wl), "cmd_wr": np.full_like(t, wr),
                       "tau_l": np.full_like(t, tl), "tau_r": np.full_like(t, tr),
                       "enc_wl": np.full_like(t, wl), "enc_wr": np.full_like(t, wr)}, {"run_id": "ol"})
    est = Yu2010OpenLoop(PLUG).estimate(run)
    # started in steady state with the steady torque: the wheels keep their speeds
    np.testing.assert_allclose(est["wl"], wl, rtol=2e-3)
    np.testing.assert_allclose(est["wr"], wr, rtol=2e-3)


def test_calibrate_rejects_a_run_without_steady_part() -> None:
    wl, wr = inverse_kinematics(0.2, 1.0, P, alpha=1.0)
    short = _circle_run(R=1.0, T=0.8, torques=resistance(wl, wr, P))
    with pytest.raises(RunError, match="cmd_wl.*no steady part"):
        Yu2010(PLUG).calibrate([short])
