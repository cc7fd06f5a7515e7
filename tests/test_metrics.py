"""bench.metrics: parity with evo (the reference implementation, GPLv3, used here only as a
test-time tool), closed-form checks of the skid-steer metrics, kinematics properties.

Parity: trajectories are exported with ``bench.formats.write_tum``; evo reads the same files
(``file_interface.read_tum_trajectory_file``), synchronises them (``sync.associate_trajectories``,
max_diff 0.01 s as its CLI default) and computes APE/RPE through ``evo.main_ape.ape`` /
``evo.main_rpe.rpe``; one pair also goes through the ``evo_ape`` / ``evo_rpe`` command line with
``--save_results``.  Every statistic and every per-pose error must agree to 1e-9 (relative to
the magnitude for values above 1, e.g. an sse in deg^2).
"""
from __future__ import annotations

import copy
import json
import os
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bench import metrics as M
from bench.formats import read_tum, write_tum
from bench.kinematics import icr_forward, ideal_dd, integrate_se2
from bench.registry import make_estimate
from bench.run import from_arrays

TOL = 1e-9
N_PAIRS = 24


def close(a: float | np.ndarray, b: float | np.ndarray) -> bool:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return a.shape == b.shape and bool(np.all(np.abs(a - b) <= TOL * np.maximum(1.0, np.abs(b))))


# ------------------------------------------------------------------------------------------
# random trajectory pairs
# ------------------------------------------------------------------------------------------
def make_pair(seed: int) -> dict[str, np.ndarray]:
    """A planar skid-steer-like reference path (ZOH SE(2) integration of smooth random body
    velocities) and an estimate with drift and noise; seed % 4 selects: 0 plain, 1 rigid
    offset, 2 offset + 8 % scale error, 3 rigid offset with the estimate at a different rate."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(90, 170))
    t = 1000.0 * rng.random() + np.arange(n) * 0.1
    k = np.arange(n)
    vx = 0.3 + 0.4 * rng.random() + 0.15 * np.sin(k / (5 + 10 * rng.random()))
    wz = np.clip(np.cumsum(rng.normal(0, 0.06, n)), -0.8, 0.8)
    vy = -0.05 * wz
    x, y, yaw = integrate_se2(t, vx, vy, wz, *rng.normal(0, 5, 2), rng.uniform(-np.pi, np.pi))
    # estimate: biased velocities (slip not modelled) + measurement noise
    ex, ey, eyaw = integrate_se2(t, vx * (1 + rng.normal(0, 0.03)), 0 * vy, wz + rng.normal(0, 0.02),
                                 x[0], y[0], yaw[0])
    ex = ex + rng.normal(0, 0.02, n)
    ey = ey + rng.normal(0, 0.02, n)
    eyaw = eyaw + rng.normal(0, 0.01, n)
    te = t + rng.uniform(-0.004, 0.004, n)
    keep = rng.random(n) > 0.05  # some estimate poses missing
    kind = seed % 4
    if kind in (1, 2, 3):
        a = rng.uniform(-np.pi, np.pi)
        c, s = np.cos(a), np.sin(a)
        sc = 1.08 if kind == 2 else 1.0
        ox, oy = rng.normal(0, 10, 2)
        ex, ey = sc * (c * ex - s * ey) + ox, sc * (s * ex + c * ey) + oy
        eyaw = eyaw + a
    if kind == 3:
        keep &= k % 3 != 1  # a sparser estimate
    return dict(t=t, x=x, y=y, yaw=yaw, te=te[keep], ex=ex[keep], ey=ey[keep], eyaw=eyaw[keep])


def write_pair(tmp: Path, p: dict[str, np.ndarray]) -> tuple[Path, Path]:
    return (write_tum(tmp / "ref.tum", p["t"], p["x"], p["y"], p["yaw"]),
            write_tum(tmp / "est.tum", p["te"], p["ex"], p["ey"], p["eyaw"]))


# (kind, relation ours, relation evo, align ours, kwargs)
APE_CASES = [
    ("translation", "translation_part", "none"),
    ("translation", "translation_part", "se3"),
    ("translation", "translation_part", "sim3"),
    ("rotation_angle_rad", "rotation_angle_rad", "none"),
    ("rotation_angle_deg", "rotation_angle_deg", "se3"),
    ("rotation_part", "rotation_part", "none"),
]
RPE_CASES = [
    ("translation", "translation_part", 1, "frames", False, "none"),
    ("rotation_angle_deg", "rotation_angle_deg", 1, "frames", False, "none"),
    ("translation", "translation_part", 1.0, "m", False, "none"),
    ("rotation_angle_rad", "rotation_angle_rad", 1.0, "m", False, "se3"),
    ("translation", "translation_part", 2.0, "m", True, "sim3"),
    ("translation", "translation_part", 5, "frames", True, "none"),
]
_ALIGN_EVO = {"none": (False, False), "se3": (True, False), "sim3": (True, True)}


def _evo_pair(ref_p: Path, est_p: Path, sync_method: str = "nearest_time"):
    from evo.core import sync
    from evo.core.sync_method import SyncMethod
    from evo.tools import file_interface

    r = file_interface.read_tum_trajectory_file(str(ref_p))
    e = file_interface.read_tum_trajectory_file(str(est_p))
    return sync.associate_trajectories(r, e, max_diff=0.01, sync_method=SyncMethod(sync_method))


def _compare(res_evo, mine: M.ErrorResult, label: str) -> float:
    ours = mine.stats.as_dict()
    worst = 0.0
    for key, val in res_evo.stats.items():
        assert close(ours[key], val), f"{label}: {key} ours {ours[key]!r} evo {val!r}"
        worst = max(worst, abs(ours[key] - val) / max(1.0, abs(val)))
    ev = res_evo.np_arrays["error_array"]
    assert close(mine.errors, ev), f"{label}: per-pose errors differ"
    return max(worst, float(np.max(np.abs(mine.errors - ev) / np.maximum(1.0, np.abs(ev)))))


@pytest.mark.parametrize("seed", range(N_PAIRS))
def test_parity_with_evo_api(tmp_path: Path, seed: int) -> None:
    from evo import main_ape, main_rpe
    from evo.core.metrics import PoseRelation, Unit

    p = make_pair(seed)
    ref_p, est_p = write_pair(tmp_path, p)
    er, ee = _evo_pair(ref_p, est_p)
    ref, est = read_tum(ref_p), read_tum(est_p)
    for rel, erel, al in APE_CASES:
        a, s = _ALIGN_EVO[al]
        res = main_ape.ape(copy.deepcopy(er), copy.deepcopy(ee), PoseRelation[erel], align=a, correct_scale=s)
        _compare(res, M.ape(ref, est, rel, al, max_diff=0.01), f"seed {seed} APE {rel} {al}")
    for rel, erel, delta, unit, allp, al in RPE_CASES:
        a, s = _ALIGN_EVO[al]
        res = main_rpe.rpe(copy.deepcopy(er), copy.deepcopy(ee), PoseRelation[erel], delta=delta,
                           delta_unit=Unit.frames if unit == "frames" else Unit.meters, all_pairs=allp,
                           align=a, correct_scale=s)
        mine = M.rpe(ref, est, rel, delta, unit, al, all_pairs=allp, max_diff=0.01)
        _compare(res, mine, f"seed {seed} RPE {rel} {delta}{unit} all_pairs={allp} {al}")
        assert np.array_equal(mine.t, res.np_arrays["timestamps"])


@pytest.mark.parametrize("seed", [0, 3, 6])
def test_parity_with_evo_interpolation_sync(tmp_path: Path, seed: int) -> None:
    from evo import main_ape
    from evo.core.metrics import PoseRelation

    p = make_pair(seed)
    ref_p, est_p = write_pair(tmp_path, p)
    er, ee = _evo_pair(ref_p, est_p, "interpolation")
    ref, est = read_tum(ref_p), read_tum(est_p)
    for rel, erel in (("translation", "translation_part"), ("rotation_angle_rad", "rotation_angle_rad")):
        res = main_ape.ape(copy.deepcopy(er), copy.deepcopy(ee), PoseRelation[erel], align=True)
        _compare(res, M.ape(ref, est, rel, "se3", max_diff=0.01, sync="interpolate"), f"interp {rel}")


def _evo_cli(tool: str, args: list[str], home: Path) -> dict[str, float]:
    exe = Path(sys.executable).parent / tool
    if not exe.exists():
        pytest.skip(f"{tool} not installed beside {sys.executable}")
    home.mkdir(exist_ok=True)
    out = home / f"{tool}_{len(list(home.glob('*.zip')))}.zip"
    env = dict(os.environ, HOME=str(home), MPLBACKEND="Agg")
    proc = subprocess.run([str(exe), "tum", *args, "--save_results", str(out), "--no_warnings"],
                          capture_output=True, text=True, env=env, timeout=120)
    assert proc.returncode == 0, proc.stderr
    with zipfile.ZipFile(out) as z:
        return json.loads(z.read("stats.json"))


def test_parity_with_evo_cli(tmp_path: Path) -> None:
    """``evo_ape`` / ``evo_rpe`` on the command line give the same numbers."""
    p = make_pair(2)  # rotated, translated and scaled estimate
    ref_p, est_p = write_pair(tmp_path, p)
    ref, est = read_tum(ref_p), read_tum(est_p)
    home = tmp_path / "home"
    files = [str(ref_p), str(est_p)]
    cases = [  # each CLI start costs ~2 s: two calls cover alignment, sync, both metrics
        ("evo_ape", ["-as"], M.ape(ref, est, "translation", "sim3")),
        ("evo_rpe", ["-r", "angle_deg", "-d", "1", "-u", "m"], M.rpe(ref, est, "rotation_angle_deg", 1.0, "m")),
    ]
    for tool, opts, mine in cases:
        stats = _evo_cli(tool, files + opts, home)
        ours = mine.stats.as_dict()
        for key, val in stats.items():
            assert close(ours[key], val), f"{tool} {opts}: {key} ours {ours[key]!r} evo {val!r}"


# ------------------------------------------------------------------------------------------
# closed-form checks (no evo)
# ------------------------------------------------------------------------------------------
def _circle(n: int = 200, dt: float = 0.05) -> M.Trajectory:
    t = np.arange(n) * dt
    x, y, yaw = integrate_se2(t, np.full(n, 0.5), np.zeros(n), np.full(n, 0.25))
    return M.Trajectory.planar(t, x, y, yaw, name="circle")


def _transform(tr: M.Trajectory, a: float, tx: float, ty: float, s: float = 1.0) -> M.Trajectory:
    c, sn = np.cos(a), np.sin(a)
    return M.Trajectory.planar(tr.t, s * (c * tr.x - sn * tr.y) + tx, s * (sn * tr.x + c * tr.y) + ty, tr.yaw + a)


def test_umeyama_recovers_known_similarity() -> None:
    rng = np.random.default_rng(0)
    src = rng.normal(0, 3, (50, 3))
    r_true = M.Rotation.from_rotvec([0.3, -0.2, 1.1]).as_matrix()
    dst = 1.7 * src @ r_true.T + [1.0, -2.0, 0.5]
    r, t, c = M.umeyama(src, dst, with_scale=True)
    assert np.allclose(r, r_true, atol=1e-12) and np.isclose(c, 1.7) and np.allclose(t, [1.0, -2.0, 0.5])
    with pytest.raises(M.MetricError, match="degenerate"):
        M.umeyama(np.zeros((5, 3)), np.zeros((5, 3)))


def test_ape_alignment_removes_a_rigid_offset() -> None:
    ref = _circle()
    est = _transform(ref, 0.8, 3.0, -4.0)
    for mode in ("se2", "se3", "sim3", "origin"):
        assert M.ape(ref, est, "translation", mode).stats.max < 1e-9
        assert M.ape(ref, est, "rotation_angle_rad", mode).stats.max < 1e-9
    # unaligned: a pure translation (no rotation) gives a constant error |(3, -4)| = 5
    shifted = _transform(ref, 0.0, 3.0, -4.0)
    res = M.ape(ref, shifted)
    assert np.allclose(res.errors, 5.0) and np.isclose(res.stats.std, 0.0, atol=1e-12)
    # a constant heading offset of 0.3 rad: APE angle 0.3 rad = 17.19 deg everywhere
    turned = M.Trajectory.planar(ref.t, ref.x, ref.y, ref.yaw + 0.3)
    assert np.allclose(M.ape(ref, turned, "rotation_angle_deg").errors, np.rad2deg(0.3))
    # sim3 recovers a scale error exactly, se3 does not
    scaled = _transform(ref, 0.4, 1.0, 2.0, 1.25)
    assert M.ape(ref, scaled, align_mode="sim3").stats.max < 1e-9
    assert M.ape(ref, scaled, align_mode="se3").stats.rmse > 0.1
    assert np.isclose(M.align(ref, scaled, "sim3").scale, 1 / 1.25)


def test_rpe_is_invariant_to_a_rigid_offset_and_sees_scale() -> None:
    ref = _circle()
    est = _transform(ref, -1.2, 10.0, 5.0)
    for unit, delta in (("frames", 1), ("frames", 7), ("m", 0.5)):
        assert M.rpe(ref, est, "translation", delta, unit).stats.max < 1e-9
        assert M.rpe(ref, est, "rotation_angle_rad", delta, unit).stats.max < 1e-9
    scaled = _transform(ref, 0.0, 0.0, 0.0, 1.1)  # every step 10 % longer
    chord = 0.5 * 0.05 * np.sinc(0.25 * 0.05 / 2 / np.pi)  # 2 R sin(w dt / 2) of one step
    res = M.rpe(ref, scaled, "translation", 1, "frames")
    assert np.allclose(res.errors, 0.1 * chord, rtol=1e-9)


def test_rpe_pairs_by_frames_and_path() -> None:
    t = np.arange(41) * 0.1
    line = M.Trajectory.planar(t, 0.25 * np.arange(41), np.zeros(41), np.zeros(41))  # 0.25 m a step
    assert M.rpe_pairs(line, 10, "frames").tolist() == [[0, 10], [10, 20], [20, 30], [30, 40]]
    assert M.rpe_pairs(line, 38, "frames", all_pairs=True).tolist() == [[0, 38], [1, 39], [2, 40]]
    assert M.rpe_pairs(line, 1.0, "m").tolist() == [[i, i + 4] for i in range(0, 40, 4)]
    ap = M.rpe_pairs(line, 1.0, "m", all_pairs=True)
    assert ap.tolist() == [[i, i + 4] for i in range(37)]
    with pytest.raises(M.MetricError, match="empty index list"):
        M.rpe_pairs(line, 100.0, "m")
    with pytest.raises(M.MetricError, match="integer"):
        M.rpe_pairs(line, 1.5, "frames")


def test_associate_nearest_matches_within_max_diff() -> None:
    z = np.zeros
    ref = M.Trajectory.planar([0.0, 0.1, 0.2, 0.3, 0.4, 0.5], z(6), z(6), z(6))
    est = M.Trajectory.planar([0.005, 0.104, 0.25, 0.395], z(4), z(4), z(4))
    r, e = M.associate(ref, est, max_diff=0.01)
    assert np.array_equal(r.t, [0.0, 0.1, 0.4]) and np.array_equal(e.t, [0.005, 0.104, 0.395])
    r, e = M.associate(ref, est, max_diff=0.05)  # 0.25 is equidistant: the earlier stamp wins
    assert np.array_equal(r.t, [0.0, 0.1, 0.2, 0.4])
    with pytest.raises(M.MetricError, match="no matching timestamps"):
        M.associate(ref, est.with_t(est.t + 100), max_diff=0.01)


def test_rotation_angle_is_accurate_near_zero_and_pi() -> None:
    angles = np.array([1e-12, 1e-8, 1e-4, 1.0, np.pi - 1e-6, np.pi])
    r = M.Rotation.from_rotvec(angles[:, None] * np.array([[0.6, 0.0, 0.8]])).as_matrix()
    assert np.allclose(M._so3_angle(r), angles, rtol=1e-9, atol=1e-15)


def test_statistics_match_definitions() -> None:
    e = np.array([1.0, 2.0, 2.0, 4.0])
    s = M.statistics(e)
    assert (s.rmse, s.mean, s.median, s.min, s.max, s.sse) == (np.sqrt(25 / 4), 2.25, 2.0, 1.0, 4.0, 25.0)
    assert np.isclose(s.std, np.sqrt(np.mean((e - 2.25) ** 2)))


# ------------------------------------------------------------------------------------------
# skid-steer metrics
# ------------------------------------------------------------------------------------------
def test_position_rms_final_error_with_slower_reference() -> None:
    t = np.arange(0, 10.0001, 0.01)
    x, y, yaw = integrate_se2(t, np.full(t.size, 1.0), np.zeros(t.size), np.full(t.size, 0.1))
    est = M.Trajectory.planar(t, x + 3.0, y + 4.0 * t / 10, yaw)  # error grows from 3 to 5 m
    sel = slice(None, None, 20)  # 5 Hz reference (GNSS in Liu et al.)
    ref = M.Trajectory.planar(t[sel], x[sel], y[sel], yaw[sel])
    tr = t[sel]
    expected = np.sqrt(np.mean(9.0 + (0.4 * tr) ** 2))
    assert np.isclose(M.position_rms(ref, est), expected, rtol=1e-12)
    assert np.isclose(M.final_position_error(ref, est), 5.0)


def test_velocity_rms_per_channel() -> None:
    t = np.arange(0, 5, 0.01)
    truth = {"vx": np.sin(t), "vy": 0.1 * np.cos(t), "wz": np.full(t.size, 0.3)}
    te = t[::2]
    est = {"vx": np.sin(te) + 0.05, "vy": 0.1 * np.cos(te) - 0.02, "wz": np.full(te.size, 0.3)}
    out = M.velocity_rms(t[: -1], {k: v[:-1] for k, v in truth.items()}, te, est)
    # the estimate is interpolated linearly at the truth stamps: error of interpolating a sine
    assert abs(out["vx"] - 0.05) < 1e-4 and abs(out["vy"] - 0.02) < 1e-5 and out["wz"] < 1e-12


def _segment_errors_bruteforce(ref: M.Trajectory, tv: np.ndarray, vel: tuple[np.ndarray, ...], every: int):
    """A second implementation: integrate every segment separately from its reference pose."""
    yaw_u = np.unwrap(ref.yaw)
    errs = []
    for s in range(0, len(ref) - every, every):
        i0, i1 = np.searchsorted(tv, ref.t[s]), np.searchsorted(tv, ref.t[s + every])
        sl = slice(i0, i1 + 1)
        x, y, yaw = integrate_se2(tv[sl], *(v[sl] for v in vel), ref.x[s], ref.y[s], yaw_u[s])
        errs.append([(ref.x[s + every] - ref.x[s]) - (x[-1] - ref.x[s]),
                     (ref.y[s + every] - ref.y[s]) - (y[-1] - ref.y[s]),
                     np.angle(np.exp(1j * ((yaw_u[s + every] - yaw_u[s]) - (yaw[-1] - yaw_u[s]))))])
    return np.array(errs)


def _skid_run(seed: int = 0):
    """Closed-form skid-steer motion: ICR model (y_l, y_r, x_icr) driven by wheel speeds."""
    rng = np.random.default_rng(seed)
    t = np.arange(0, 30, 0.01)
    wl = 3.0 + 1.5 * np.sin(t / 3) + rng.normal(0, 0.05, t.size)
    wr = 3.0 + 1.5 * np.cos(t / 4) + rng.normal(0, 0.05, t.size)
    r, y_l, y_r, x_icr = 0.1, 0.3, -0.32, 0.02
    vx, vy, wz = icr_forward(r * wl, r * wr, y_l, y_r, x_icr)
    x, y, yaw = integrate_se2(t, vx, vy, wz, 1.0, -2.0, 0.4)
    return t, (wl, wr), (vx, vy, wz), (x, y, yaw), r


def test_mandow_segments_true_model_is_exact_and_wrong_model_matches_bruteforce() -> None:
    t, (wl, wr), vel, (x, y, yaw), r = _skid_run()
    sel = slice(None, None, 10)  # external sensor at 10 Hz
    ref = M.Trajectory.planar(t[sel], x[sel], y[sel], yaw[sel])
    exact = M.segment_errors(ref, M.velocity_reckoner(t, *vel))
    assert exact.n == len(ref) - 1 and exact.J < 1e-20
    # ideal differential drive (B = 0.4) as the method's model: errors match the brute force
    dd = ideal_dd(r * wl, r * wr, 0.4)
    for every in (1, 5):
        got = M.segment_errors(ref, M.velocity_reckoner(t, *dd), every=every, frame="world")
        want = _segment_errors_bruteforce(ref, t, dd, every)
        assert np.allclose(np.column_stack([got.dx, got.dy, got.dphi]), want, atol=1e-10)
        assert np.isclose(got.J, np.mean(np.sum(want ** 2, axis=1)), rtol=1e-9)
        assert got.J > 1e-8
    # the 'start' frame only rotates (dx, dy): the summed squared position error is unchanged
    st_ = M.segment_errors(ref, M.velocity_reckoner(t, *dd), every=5, frame="start")
    assert np.isclose(st_.ms_dx + st_.ms_dy, got.ms_dx + got.ms_dy, rtol=1e-12)


def test_window_end_errors_closed_form_yaw_rate_bias() -> None:
    """Reference: straight line at v; estimate: the same speed with a yaw-rate bias b.  After
    re-anchoring, the end-of-window error is |(v/b)(sin bT, 1 - cos bT) - (vT, 0)|."""
    v, b, T = 0.8, 0.05, 2.0
    t = np.arange(0, 20.0001, 0.01)
    ref = M.Trajectory.planar(t, v * t, np.zeros(t.size), np.zeros(t.size))
    ex, ey, eyaw = integrate_se2(t, np.full(t.size, v), np.zeros(t.size), np.full(t.size, b))
    expected = np.hypot(v / b * np.sin(b * T) - v * T, v / b * (1 - np.cos(b * T)))
    for est in (M.Trajectory.planar(t, ex, ey, eyaw),
                M.velocity_reckoner(t, np.full(t.size, v), np.zeros(t.size), np.full(t.size, b))):
        w = M.window_end_errors(ref, est, window=T)
        assert w.position.size == 10
        assert np.allclose(w.position, expected, rtol=1e-6) and np.allclose(w.heading, b * T, rtol=1e-6)
        d = w.as_dict()
        assert np.isclose(d["pos_p95"], expected, rtol=1e-6) and np.isclose(d["pos_median"], expected, rtol=1e-6)
    assert M.window_end_errors(ref, M.Trajectory.planar(t, ex, ey, eyaw), T, step=0.5).position.size == 37


def test_summary_on_a_synthetic_run() -> None:
    t, (wl, wr), (vx, vy, wz), (x, y, yaw), r = _skid_run(1)
    run = from_arrays({"t": t, "enc_wl": wl, "enc_wr": wr, "truth_x": x, "truth_y": y, "truth_yaw": yaw,
                       "truth_vx": vx, "truth_vy": vy, "truth_wz": wz}, {"run_id": "s"})
    evx, evy, ewz = ideal_dd(r * wl, r * wr, 0.4)
    ex, ey, eyaw = integrate_se2(t, evx, evy, ewz, x[0], y[0], yaw[0])
    est = make_estimate("dd", t=t, x=ex, y=ey, yaw=eyaw, vx=evx, vy=evy, wz=ewz)
    s = M.summary(run, est)
    assert np.isclose(s["position_rms"], np.sqrt(np.mean((ex - x) ** 2 + (ey - y) ** 2)), rtol=1e-12)
    assert np.isclose(s["ape_rmse"], s["position_rms"], rtol=1e-12)
    assert np.isclose(s["final_position_error"], np.hypot(ex[-1] - x[-1], ey[-1] - y[-1]))
    assert np.isclose(s["vy_rms"], np.sqrt(np.mean(vy ** 2))) and s["ape_se2_rmse"] <= s["ape_rmse"]
    assert np.isclose(s["wz_rms"], np.sqrt(np.mean((ewz - wz) ** 2)), rtol=1e-9)
    perfect = make_estimate("p", t=t, x=x, y=y, yaw=yaw, vx=vx, vy=vy, wz=wz)
    assert max(abs(v) for v in M.summary(run, perfect).values()) < 1e-9


# ------------------------------------------------------------------------------------------
# kinematics properties (bench.kinematics)
# ------------------------------------------------------------------------------------------
speeds = st.lists(st.tuples(st.floats(-2, 2), st.floats(-2, 2)), min_size=2, max_size=40)


@settings(max_examples=60, deadline=None)
@given(speeds, st.floats(-np.pi, np.pi), st.floats(-50, 50), st.floats(-50, 50),
       st.floats(0.2, 1.0), st.floats(-0.3, 0.3))
def test_rotating_the_initial_pose_rotates_the_trajectory(ws, yaw0, x0, y0, track, x_icr) -> None:
    w = np.array(ws)
    t = np.arange(w.shape[0]) * 0.05
    vx, vy, wz = icr_forward(0.1 * w[:, 0], 0.1 * w[:, 1], 0.55 * track, -0.6 * track, x_icr)
    bx, by, byaw = integrate_se2(t, vx, vy, wz)
    x, y, yaw = integrate_se2(t, vx, vy, wz, x0, y0, yaw0)
    c, s = np.cos(yaw0), np.sin(yaw0)
    assert np.allclose(x, x0 + c * bx - s * by, atol=1e-9) and np.allclose(y, y0 + s * bx + c * by, atol=1e-9)
    assert np.allclose(yaw, byaw + yaw0, atol=1e-12)
    # and the metrics see it: SE(2) alignment removes it exactly
    a = M.Trajectory.planar(t, bx, by, byaw)
    b = M.Trajectory.planar(t, x, y, yaw)
    if np.ptp(bx) + np.ptp(by) > 1e-3:
        assert M.ape(a, b, align_mode="se2", max_diff=None).stats.max < 1e-7


@settings(max_examples=60, deadline=None)
@given(speeds, st.floats(0.2, 1.0))
def test_reversing_wheel_speeds_retraces_the_path(ws, track) -> None:
    w = np.array(ws)
    n = w.shape[0]
    dt = np.linspace(0.02, 0.07, n - 1)
    t = np.concatenate(([0.0], np.cumsum(dt)))
    vx, vy, wz = icr_forward(0.1 * w[:, 0], 0.1 * w[:, 1], 0.6 * track, -0.55 * track, 0.03)
    x, y, yaw = integrate_se2(t, vx, vy, wz, 1.0, 2.0, 0.3)
    # play the wheel speeds backwards in time with opposite sign, from the end pose
    rl, rr = -w[-2::-1, 0], -w[-2::-1, 1]
    bvx, bvy, bwz = icr_forward(0.1 * np.append(rl, 0.0), 0.1 * np.append(rr, 0.0), 0.6 * track, -0.55 * track, 0.03)
    tb = np.concatenate(([0.0], np.cumsum(dt[::-1])))
    bx, by, byaw = integrate_se2(tb, bvx, bvy, bwz, x[-1], y[-1], yaw[-1])
    assert np.allclose(bx, x[::-1], atol=1e-9) and np.allclose(by, y[::-1], atol=1e-9)
    assert np.allclose(byaw, yaw[::-1], atol=1e-9)
