"""Mandow 2007 eqs. (6)-(10): the ICR kinematic matrix, the indexes and dead reckoning (synthetic runs)."""
from __future__ import annotations

import numpy as np
import pytest

from bench.run import from_arrays
from methods import mandow2007 as M
from methods.baselines import IdealDD
from tests.methods.mandow2007.synthetic import PLATFORM, joystick_run


def test_reduces_to_ideal_differential_drive():
    run = joystick_run(M.TABLE_I["pneumatic_50psi"], duration=15.0, seed=4)
    b = PLATFORM["track"]
    ideal = M.dead_reckoning(M.IcrParams(-b / 2, b / 2, 0.0, 1.0, 1.0), run)
    base = IdealDD().estimate(run)
    for c in ("x", "y", "yaw", "vx", "vy", "wz", "y_l", "y_r", "x_icr", "chi"):
        np.testing.assert_allclose(ideal[c], base[c], atol=1e-12, err_msg=c)
    assert M.IcrParams.ideal(b) == M.IcrParams(-b / 2, b / 2, 0.0, 1.0, 1.0)


def test_eq7_matrix_in_mandow_axes_matches_body_velocities():
    """A of eq. (7) gives (v_x lateral-right, v_y forward, omega): our vx = v_y, vy = -v_x."""
    rng = np.random.default_rng(3)
    for p in list(M.TABLE_I.values()) + list(M.TABLE_II.values()):
        vl, vr = rng.uniform(-0.7, 0.7, (2, 50))
        mv = M.kinematic_matrix(p) @ np.vstack([vl, vr])
        vx, vy, wz = M.body_velocities(p, vl, vr)
        np.testing.assert_allclose(vx, mv[1], atol=1e-14)
        np.testing.assert_allclose(vy, -mv[0], atol=1e-14)
        np.testing.assert_allclose(wz, mv[2], atol=1e-14)
        # tread ICRs, eqs. (3)-(5): x_ICR = (alpha V - v_y)/omega, y_ICRv = v_x/omega (Mandow axes)
        np.testing.assert_allclose((p.alpha_l * vl - mv[1]) / mv[2], p.x_icr_l, rtol=1e-9)
        np.testing.assert_allclose((p.alpha_r * vr - mv[1]) / mv[2], p.x_icr_r, rtol=1e-9)
        np.testing.assert_allclose(mv[0] / mv[2], p.y_icr_v, rtol=1e-9, atol=1e-12)


TABLE_INDEXES = {  # published (chi, e) of Tables I and II
    ("I", "pneumatic_50psi"): (0.6949, 0.0417), ("I", "pneumatic_20psi"): (0.7112, 0.0921),
    ("I", "solid_rubber"): (0.7612, -0.0150), ("II", "pneumatic_50psi"): (0.7098, -0.0213),
    ("II", "pneumatic_20psi"): (0.7053, 0.0224), ("II", "solid_rubber"): (0.7460, 0.0082),
}


@pytest.mark.parametrize("table,tire", list(TABLE_INDEXES))
def test_indexes_match_tables(table, tire):
    p = (M.TABLE_I if table == "I" else M.TABLE_II)[tire]
    chi, e = TABLE_INDEXES[(table, tire)]
    # published to 4 decimals from parameters also rounded to 4 decimals: agree within 1e-4
    assert p.steering_efficiency(0.4) == pytest.approx(chi, abs=1e-4)
    assert p.eccentricity() == pytest.approx(e, abs=1e-4)


def test_indexes_hand_computed():
    assert M.steering_efficiency(-0.2758, 0.2998, 0.4) == pytest.approx(0.4 / (0.2998 + 0.2758), rel=1e-15)
    assert float(M.steering_efficiency(-0.2758, 0.2998, 0.4)) == pytest.approx(0.6949, abs=5e-5)
    assert float(M.eccentricity(-0.2758, 0.2998)) == pytest.approx(0.0240 / 0.5756, rel=1e-12)
    assert float(M.eccentricity(-0.3, 0.3)) == 0.0
    assert float(M.steering_efficiency(-0.2, 0.2, 0.4)) == 1.0  # ideal differential drive


def test_constant_speed_circle_closes_to_the_analytic_circle():
    """Known asymmetric ICRs, constant wheel speeds: the origin circles the vehicle ICR at body
    coordinates (x_icr, vx/omega) (our axes) and returns to its start after 2 pi / omega."""
    p = M.TABLE_I["pneumatic_20psi"]
    r, rate = PLATFORM["wheel_radius"], 100.0
    vl, vr = 0.25, 0.45
    # closed form of eq. (7), written out: omega, forward and lateral velocity
    d = p.x_icr_r - p.x_icr_l
    w = (p.alpha_r * vr - p.alpha_l * vl) / d
    v_fwd = (p.x_icr_r * p.alpha_l * vl - p.x_icr_l * p.alpha_r * vr) / d
    period = 2 * np.pi / w
    t = np.linspace(0.0, period, int(period * rate) + 1)
    pose0 = (0.5, -1.0, 0.4)
    run = from_arrays({"t": t, "enc_wl": np.full(t.size, vl / r), "enc_wr": np.full(t.size, vr / r),
                       "ref_x": np.r_[pose0[0], np.full(t.size - 1, np.nan)],
                       "ref_y": np.r_[pose0[1], np.full(t.size - 1, np.nan)],
                       "ref_yaw": np.r_[pose0[2], np.full(t.size - 1, np.nan)]},
                      {"platform": PLATFORM, "run_id": "circle"})
    est = M.dead_reckoning(p, run)
    c_body = np.array([p.y_icr_v, v_fwd / w])  # ICR in body coordinates (x forward, y left)
    rot = lambda a: np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])  # noqa: E731
    centre = np.array(pose0[:2]) + rot(pose0[2]) @ c_body
    yaw = pose0[2] + w * t
    expect = centre[:, None] - np.einsum("ijn,j->in", rot(yaw), c_body)
    np.testing.assert_allclose(est["x"], expect[0], atol=1e-10)
    np.testing.assert_allclose(est["y"], expect[1], atol=1e-10)
    np.testing.assert_allclose([est["x"][-1], est["y"][-1]], pose0[:2], atol=1e-10)  # closes
    np.testing.assert_allclose(np.hypot(est["x"] - centre[0], est["y"] - centre[1]), np.hypot(*c_body), rtol=1e-10)
