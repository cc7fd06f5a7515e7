"""Mandow 2007: ICR kinematic matrix, indexes, symmetric and GA/DE identification (synthetic runs).

The synthetic runs are built here from the paper's own relations, not from methods.mandow2007:
joystick-like body velocities (v, omega), lateral velocity from eq. (5) (v_x = y_ICRv omega, Mandow's
X to the right), tread speeds from the inverse kinematics of eqs. (16)-(17), poses from the exact SE(2)
integration of bench.kinematics.  Encoder speeds change only at encoder instants, so a model with
the true parameters reproduces the reference exactly.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import lfilter

from bench import registry
from bench.kinematics import integrate_se2
from bench.run import from_arrays
from methods import mandow2007 as M
from methods.baselines import IdealDD

PLATFORM = {"name": "p3at", "track": 0.4, "wheel_radius": 0.11, "wheelbase": 0.27}


def joystick(duration: float, rate: float, seed: int, v_max: float = 0.5, w_max: float = 1.0, hold: float = 2.0,
             tau: float = 0.4) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Random (v, omega) set points every ``hold`` s through a first-order lag: a joystick-driven path."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(round(duration * rate)) + 1) / rate
    k = np.floor(t / hold).astype(int)
    v_set = rng.uniform(-0.3 * v_max, v_max, k.max() + 1)
    w_set = rng.uniform(-w_max, w_max, k.max() + 1)
    a = 1 - np.exp(-1 / (rate * tau))
    return t, lfilter([a], [1, a - 1], v_set[k]), lfilter([a], [1, a - 1], w_set[k])


def simulate_icr_run(x_l: float, x_r: float, y_v: float, a_l: float, a_r: float, t: np.ndarray, vx: np.ndarray,
                     wz: np.ndarray, ref_rate: float = 5.0, pose0=(1.0, 2.0, 0.3), run_id: str = "synth",
                     meta: dict | None = None):
    """Run of a robot that moves exactly as Mandow's model with K = (x_l, x_r, y_v, a_l, a_r)."""
    rate = 1.0 / (t[1] - t[0])
    r = PLATFORM["wheel_radius"]
    v_l = (vx + x_l * wz) / a_l  # eq. (16)
    v_r = (vx + x_r * wz) / a_r  # eq. (17)
    vy = -y_v * wz  # eq. (5): Mandow's lateral v_x = y_ICRv omega, X to the right = our -y
    x, y, yaw = integrate_se2(t, vx, vy, wz, *pose0)
    ref = np.zeros(t.size, bool)
    ref[:: int(round(rate / ref_rate))] = True
    cols = {"t": t, "cmd_wl": v_l / r, "cmd_wr": v_r / r, "enc_wl": v_l / r, "enc_wr": v_r / r,
            "ref_x": np.where(ref, x, np.nan), "ref_y": np.where(ref, y, np.nan),
            "ref_yaw": np.where(ref, yaw, np.nan), "truth_x": x, "truth_y": y, "truth_yaw": yaw}
    return from_arrays(cols, {"platform": dict(PLATFORM), "run_id": run_id, **(meta or {})})


def joystick_run(p: M.IcrParams, duration: float = 20.0, seed: int = 1, ref_rate: float = 5.0):
    t, v, w = joystick(duration, 100.0, seed)
    return simulate_icr_run(*p.as_array(), t, v, w, ref_rate=ref_rate, run_id=f"joystick{seed}")


def on_grid(p: M.IcrParams, ranges: M.GeneRanges) -> M.IcrParams:
    """Parameters rounded to the 8-bit gene grid (so the discretised problem's optimum is the truth)."""
    b, q = ranges.bounds(), ranges.quantum()
    return M.IcrParams.from_array(b[:, 0] + np.round((p.as_array() - b[:, 0]) / q) * q)


# ------------------------------------------------------------------------------------------------ model
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


def test_default_p3at_model():
    """Sec. IV-B: alpha = 1 and x_ICR = 0.3 m: omega = (V_r - V_l)/0.6, v = (V_l + V_r)/2."""
    r = PLATFORM["wheel_radius"]
    t = np.arange(501) / 100.0
    run = from_arrays({"t": t, "enc_wl": np.full(t.size, 1.0), "enc_wr": np.full(t.size, 3.0)},
                      {"platform": PLATFORM, "run_id": "p3at"})
    est = M.DefaultP3at().estimate(run)
    np.testing.assert_allclose(est["wz"], r * 2.0 / 0.6)
    np.testing.assert_allclose(est["vx"], r * 2.0)
    np.testing.assert_allclose(est["yaw"][-1], 5.0 * r * 2.0 / 0.6, rtol=1e-12)
    assert est.info["steering_efficiency"] == pytest.approx(0.4 / 0.6)


def test_p3at_server_parameters_eqs_14_15():
    """Default model (alpha = 1, x_ICR = 300 mm) with 110 mm wheels: Ticksmm = round(110 * 138/110)
    = 138, Revcount = round(2 pi 300 * 138 / 8) = round(32515.48) = 32515."""
    assert M.p3at_server_parameters(1.0, 0.3, 0.11) == (138, 32515)
    back = M.p3at_symmetric_model(138, 32515, 0.11)
    assert back.alpha_l == back.alpha_r == pytest.approx(1.0, rel=1e-15)
    assert back.x_icr_r == pytest.approx(0.3, abs=8 / (2 * np.pi * 138) / 1000)  # one Revcount step
    ticks, rev = M.p3at_server_parameters(0.91, 0.275, 0.11)  # Sec. IV-D symmetric model
    assert ticks == round(0.91 * 138) and rev == round(2 * np.pi * 275 * ticks / 8)


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


# ------------------------------------------------------------------------------------------------ eq. (13)
def test_segment_increments_match_integrate_se2_per_segment():
    """The batched segment dead reckoning equals bench.kinematics.integrate_se2 restarted at each
    segment's reference pose (second implementation)."""
    truth = M.TABLE_I["pneumatic_50psi"]
    run = joystick_run(truth, duration=10.0, seed=7)
    seg = M.build_segments([run])
    assert seg.n_segments == 50 and seg.n_intervals == 1000
    p = M.IcrParams(-0.31, 0.27, 0.02, 0.95, 0.9)
    dx, dy, dphi = (a[0] for a in M.segment_increments(seg, p.as_array()))
    t = run.t
    vx, vy, wz = M.body_velocities(p, run["enc_wl"] * 0.11, run["enc_wr"] * 0.11)
    ends = np.flatnonzero(np.isfinite(run["ref_x"]))
    for i, (a, b) in enumerate(zip(ends[:-1], ends[1:], strict=True)):
        x, y, yaw = integrate_se2(t[a:b + 1], vx[a:b + 1], vy[a:b + 1], wz[a:b + 1])
        assert (dx[i], dy[i], dphi[i]) == pytest.approx((x[-1], y[-1], yaw[-1]), abs=1e-14)
    # the reference increments are expressed in the frame of the segment's start pose
    rx, ry, ryaw = run["ref_x"][ends], run["ref_y"][ends], run["ref_yaw"][ends]
    c, s = np.cos(ryaw[:-1]), np.sin(ryaw[:-1])
    np.testing.assert_allclose(seg.ref_dx, c * np.diff(rx) + s * np.diff(ry), atol=1e-15)
    np.testing.assert_allclose(seg.ref_dy, -s * np.diff(rx) + c * np.diff(ry), atol=1e-15)


def test_cost_is_zero_at_truth_and_errors_are_world_frame():
    truth = M.TABLE_II["solid_rubber"]
    seg = M.build_segments([joystick_run(truth, duration=10.0, seed=2)])
    pop = np.vstack([truth.as_array(), truth.as_array() + [0.01, 0, 0, 0, 0], [0.3, -0.3, 0, 1, 1]])
    j = M.segment_cost(seg, pop)
    assert j[0] < 1e-24 and j[1] > 1e-6 and j[2] == np.inf  # last row: x_ICRr < x_ICRl, degenerate
    assert float(M.segment_cost(seg, truth.as_array())) == pytest.approx(j[0], abs=1e-30)
    wrong = M.IcrParams.symmetric(1.0, 0.3)
    err = M.segment_errors(seg, wrong)
    total = np.sum(err["ex"] ** 2 + err["ey"] ** 2 + err["ephi"] ** 2)
    assert total == pytest.approx(float(M.segment_cost(seg, wrong.as_array())), rel=1e-12)


def test_segments_at_the_reference_rate_and_merged():
    truth = M.TABLE_I["pneumatic_50psi"]
    run = joystick_run(truth, duration=10.0, seed=1, ref_rate=20.0)
    assert M.build_segments([run]).n_segments == 200
    merged = M.build_segments([run], segment_period=0.5)
    assert merged.n_segments == 20 and np.allclose(merged.duration, 0.5)
    two = M.build_segments([run, joystick_run(truth, duration=5.0, seed=2)])
    assert two.n_segments == 200 + 25 and two.run_ids == ("joystick1", "joystick2")
    assert float(M.segment_cost(two, truth.as_array())) < 1e-24


# ------------------------------------------------------------------------------------------------ optimisers
def test_ga_recovers_parameters_within_one_gene_quantum():
    """40-bit GA on a 12 s joystick path, noise-free reference at the published 5 Hz (DGPS)."""
    ranges = M.GeneRanges.for_track(PLATFORM["track"])
    truth = on_grid(M.TABLE_I["pneumatic_50psi"], ranges)
    seg = M.build_segments([joystick_run(truth, duration=12.0, seed=1)])
    ident = M.identify_ga(seg, ranges)
    q = ranges.quantum()
    assert np.all(np.abs(ident.params.as_array() - truth.as_array()) <= q * (1 + 1e-9)), (
        (ident.params.as_array() - truth.as_array()) / q)
    assert ident.quantum == pytest.approx(tuple(q))
    assert ident.n_evaluations > 0 and ident.cost == pytest.approx(float(M.segment_cost(seg, ident.params.as_array())))


def test_de_recovers_parameters_within_one_gene_quantum():
    truth = M.TABLE_I["solid_rubber"]  # off the gene grid: DE works on continuous K
    ranges = M.GeneRanges.for_track(PLATFORM["track"])
    seg = M.build_segments([joystick_run(truth, duration=20.0, seed=2)])
    ident = M.identify_de(seg, ranges, M.DeSettings(maxiter=150))
    assert np.all(np.abs(ident.params.as_array() - truth.as_array()) <= ranges.quantum())
    assert ident.cost < 1e-10


def test_optimisers_are_deterministic_and_seeded():
    truth = M.TABLE_I["pneumatic_20psi"]
    seg = M.build_segments([joystick_run(truth, duration=5.0, seed=3)])
    st = M.GaSettings(population=20, parents_mating=10, generations=15, stop_saturate=None)
    a, b = M.identify_ga(seg, settings=st), M.identify_ga(seg, settings=st)
    assert a == b and a.cost_history == b.cost_history and len(a.cost_history) == 15
    other = M.identify_ga(seg, settings=M.GaSettings(population=20, parents_mating=10, generations=15,
                                                     stop_saturate=None, seed=99))
    assert other.cost_history != a.cost_history
    assert list(a.cost_history) == sorted(a.cost_history, reverse=True)  # elitism: never worse
    de = M.DeSettings(maxiter=10, popsize=5, polish=False)
    assert M.identify_de(seg, settings=de) == M.identify_de(seg, settings=de)


def test_decode_chromosomes_gray_and_binary():
    ranges = M.GeneRanges((-1.0, 0.0), (0.0, 1.0), (-1.0, 1.0), (0.5, 1.5), (0.5, 1.5))
    codes = np.array([0, 255, 128, 1, 170])
    bits = ((codes[:, None] >> np.arange(7, -1, -1)) & 1).ravel()
    b = ranges.bounds()
    np.testing.assert_allclose(M.decode_chromosomes(bits, ranges, gray_code=False)[0],
                               b[:, 0] + codes * (b[:, 1] - b[:, 0]) / 255)
    gray = codes ^ (codes >> 1)  # Gray encoding of the same codes decodes to the same values
    gbits = ((gray[:, None] >> np.arange(7, -1, -1)) & 1).ravel()
    np.testing.assert_allclose(M.decode_chromosomes(gbits, ranges, gray_code=True)[0],
                               b[:, 0] + codes * (b[:, 1] - b[:, 0]) / 255)


# ------------------------------------------------------------------------------------------------ symmetric
def _steady_run(kind: str, alpha: float, x_icr: float, speed: float, duration: float, run_id: str, meta=None):
    t = np.arange(int(duration * 100) + 1) / 100.0
    ramp = np.minimum(1.0, t / 0.5)  # start from rest
    if kind == "rotation":
        vx, wz = np.zeros_like(t), ramp * speed
    else:
        vx, wz = ramp * speed, np.zeros_like(t)
    return simulate_icr_run(-x_icr, x_icr, 0.0, alpha, alpha, t, vx, wz, ref_rate=10.0, run_id=run_id, meta=meta)


def test_symmetric_identification_recovers_alpha_and_x_icr():
    """Eqs. (11)-(12) on a pure rotation and a straight line made with alpha = 0.91, x_ICR = 0.275 m
    (the paper's experimental symmetric model, Sec. IV-D)."""
    runs = [_steady_run("rotation", 0.91, 0.275, 1.2, 8.0, "spin"),
            _steady_run("rotation", 0.91, 0.275, -0.8, 6.0, "spin_cw"),
            _steady_run("straight", 0.91, 0.275, 0.4, 6.0, "line"),
            joystick_run(M.TABLE_I["pneumatic_20psi"], duration=5.0)]  # ignored: neither kind
    assert [M.run_kind(r) for r in runs] == ["rotation", "rotation", "straight", "other"]
    ident = M.identify_symmetric(runs)
    assert ident.alpha == pytest.approx(0.91, rel=1e-12)
    assert ident.x_icr == pytest.approx(0.275, rel=1e-12)
    assert [s.run_id for s in ident.rotation] == ["spin", "spin_cw"]
    literal = M.identify_symmetric(runs, alpha_in_eq11=False)
    assert literal.x_icr == pytest.approx(0.275 / 0.91, rel=1e-12)
    sym = M.Symmetric().calibrate(runs)
    assert sym.params == M.IcrParams.symmetric(ident.alpha, ident.x_icr)
    est = sym.estimate(_steady_run("rotation", 0.91, 0.275, 0.5, 4.0, "other_spin"))
    assert est.info["identification"]["rotation_runs"] == ["spin", "spin_cw"]


def test_run_kind_from_metadata_and_missing_experiments():
    spin = _steady_run("rotation", 1.0, 0.3, 1.0, 3.0, "s", meta={"scenario_kind": "straight"})
    assert M.run_kind(spin) == "straight"  # metadata wins over the command heuristics
    with pytest.raises(M.CalibrationDataError, match="pure-rotation.*line=straight"):
        M.identify_symmetric([_steady_run("straight", 1.0, 0.3, 0.4, 3.0, "line")])
    with pytest.raises(M.CalibrationDataError, match="straight-line"):
        M.identify_symmetric([_steady_run("rotation", 1.0, 0.3, 1.0, 3.0, "spin")])


# ------------------------------------------------------------------------------------------------ plugins
def test_plugins_through_the_registry():
    truth = M.TABLE_I["pneumatic_50psi"]
    calib, other = joystick_run(truth, duration=15.0, seed=11), joystick_run(truth, duration=15.0, seed=12)
    de = registry.calibrate(M.AsymmetricDe(settings=M.DeSettings(maxiter=60, popsize=8)), [calib])
    with pytest.raises(registry.CalibrationLeak):
        registry.estimate(de, calib)
    est = registry.estimate(de, other)
    np.testing.assert_allclose(est["x"], other["truth_x"], atol=2e-3)
    np.testing.assert_allclose(est["y"], other["truth_y"], atol=2e-3)
    ident = est.info["identification"]
    assert ident["optimiser"] == "scipy.optimize.differential_evolution" and ident["runs"] == ("joystick11",)
    assert est.info["steering_efficiency"] == pytest.approx(0.4 / (ident["params"]["x_icr_r"]
                                                                  - ident["params"]["x_icr_l"]))
    for cls in (M.Symmetric, M.AsymmetricGa, M.AsymmetricDe):
        with pytest.raises(M.NotCalibratedError, match="calibrate"):
            cls().estimate(other)
    short = joystick_run(truth, duration=6.0, seed=13)
    ga = M.AsymmetricGa(settings=M.GaSettings(population=30, parents_mating=15, generations=20),
                        cross_check=True).calibrate([short])
    info = ga.estimate(other).info
    assert info["identification"]["optimiser"] == "pygad.GA" and len(info["identification"]["quantum"]) == 5
    assert info["cross_check"]["optimiser"] == "scipy.optimize.differential_evolution"
    assert info["cross_check"]["cost"] <= info["identification"]["cost"]
    published = M.AsymmetricGa(params=truth).estimate(other)  # Table I parameters as published
    np.testing.assert_allclose(published["yaw"], other["truth_yaw"], atol=1e-9)
    with pytest.raises(M.CalibrationDataError, match="reference"):
        M.AsymmetricGa().calibrate([type(calib)(calib.data.drop(columns=["ref_x"]), calib.meta)])
