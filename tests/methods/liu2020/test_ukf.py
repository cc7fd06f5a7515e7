"""methods/liu2020/ukf.py: the UKF+ICR and MI-UKF runs on synthetic skid-steer runs
(tests/methods/liu2020/synthetic.py): parity with FilterPy, no heading chattering, a 20 s GNSS outage,
the covariance positive definite over long runs.
"""
from __future__ import annotations

import numpy as np
import pytest

from bench.run import Run
from bench.estimation.ukf import nees
from methods.liu2020 import EnDr, MiUkf, UkfIcr, run_liu_filter
from tests.methods.liu2020.filterpy_twin import FilterPyUkf
from tests.methods.liu2020.synthetic import make_run, pos_rms, yaw_err


def test_ukf_icr_parity_with_filterpy_on_liu_model():
    """The whole UKF+ICR run (encoder-ICR pseudo-measurements, GNSS at 10 Hz with NaN rows dropped,
    heading wraps) on our core and on FilterPy: same states and covariances to 1e-9."""
    run = make_run(31, duration=8.0, kind="circle")
    p = UkfIcr().params
    ours = run_liu_filter(run, p, "ours")
    fp = run_liu_filter(run, p, "filterpy", make_filter=FilterPyUkf)
    assert np.sum(np.abs(np.diff(run["truth_yaw"])) > np.pi) >= 1
    dstate = max(float(np.max(np.abs(ours[c] - fp[c]))) for c in ("x", "y", "vx", "vy", "wz", "y_l", "y_r"))
    dyaw = float(np.max(np.abs((ours["yaw"] - fp["yaw"] + np.pi) % (2 * np.pi) - np.pi)))
    dP = float(np.max(np.abs(ours.info["P"] - fp.info["P"])))
    print(f"parity over {run.t.size} steps: state {dstate:.2e}, yaw {dyaw:.2e}, P {dP:.2e}")
    assert dstate < 1e-9 and dyaw < 1e-9 and dP < 1e-9


def _yaw_steps(est) -> np.ndarray:
    return np.abs((np.diff(est["yaw"]) + np.pi) % (2 * np.pi) - np.pi)


@pytest.mark.parametrize("cls", [UkfIcr, MiUkf])
def test_no_heading_chattering_on_small_circle(cls):
    """Liu Figs. 16-17: small-radius backwards circle, heading crosses -pi/pi many times.  Every
    step-to-step yaw change stays within |true yaw rate| * dt + a noise margin."""
    run = make_run(7, duration=40.0, kind="circle", icr_var=0.1)
    truth_yaw = run["truth_yaw"]
    crossings = int(np.sum(np.abs(np.diff(truth_yaw)) > np.pi))
    assert crossings >= 8
    est = cls().estimate(run)
    dt = np.diff(run.t)
    bound = np.abs(run["truth_wz"][1:]) * dt + 0.02
    steps = _yaw_steps(est)
    assert np.all(steps <= bound), (float(np.max(steps - bound)), int(np.argmax(steps - bound)))
    assert np.max(np.abs(yaw_err(est, run))[run.t > 2.0]) < 0.05


def test_gnss_outage_20s():
    """20 s without GNSS: no NaN, covariance PD, position error bounded and recovered afterwards."""
    run = make_run(9, duration=60.0, kind="mixed", outage=(20.0, 40.0))
    dr = EnDr().estimate(run)
    for cls in (UkfIcr, MiUkf):
        est = cls().estimate(run)
        for c in ("x", "y", "yaw", "vx", "vy", "wz", "y_l", "y_r", "x_icr"):
            assert np.all(np.isfinite(est[c])), c
        P = est.info["P"]
        np.linalg.cholesky(P)  # raises if any step is not positive definite
        e = np.hypot(est["x"] - run["truth_x"], est["y"] - run["truth_y"])
        e_dr = np.hypot(dr["x"] - run["truth_x"], dr["y"] - run["truth_y"])
        t = run.t
        end = np.searchsorted(t, 40.0) - 1
        travelled = np.sum(np.hypot(np.diff(run["truth_x"]), np.diff(run["truth_y"]))[(t[1:] > 20) & (t[1:] <= 40)])
        assert travelled > 20.0
        assert e[end] < e_dr[end]
        assert e[end] < 0.05 * travelled  # IMU + encoder-ICR carry the GNSS-calibrated slip
        assert np.max(e[(t > 5) & (t < 20)]) < 0.1
        assert np.max(e[t > 55.0]) < e[end]  # GNSS back: the error shrinks again


def _check_consistency(run: Run) -> dict:
    est = UkfIcr().estimate(run)
    P = est.info["P"]
    assert np.array_equal(P, np.swapaxes(P, 1, 2))
    assert np.all(np.linalg.eigvalsh(P)[:, 0] > 0)
    err = np.column_stack((est["x"] - run["truth_x"], est["y"] - run["truth_y"], yaw_err(est, run),
                           est["vx"] - run["truth_vx"], est["vy"] - run["truth_vy"], est["wz"] - run["truth_wz"]))
    v = nees(err, P)
    assert np.all(np.isfinite(v))
    return {"nees_mean": float(v.mean()), "pos_rms": pos_rms(est, run)}


def test_covariance_pd_long_run_default():
    """2 minutes at 100 Hz (12000 steps): P symmetric positive definite at every step."""
    out = _check_consistency(make_run(12, duration=120.0, kind="mixed"))
    print("2 min run:", out)
    assert out["pos_rms"] < 0.1


@pytest.mark.slow
def test_covariance_pd_one_hour_reduced_rate():
    """1 hour at a 20 Hz log rate (72000 steps): P symmetric positive definite at every step."""
    out = _check_consistency(make_run(13, duration=3600.0, kind="mixed", rate=20.0, gnss_rate=5.0))
    print("1 h run:", out)
    assert out["pos_rms"] < 0.2
