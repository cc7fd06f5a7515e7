"""The four Liu 2020 plugins (methods/liu2020/: En-DR, ICR, UKF+ICR, MI-UKF) on synthetic skid-steer runs
(tests/methods/liu2020/synthetic.py): the plugin protocol, the paper's orderings where they must hold
(constant-ICR DR beats no-slip DR on slipping data; GNSS-aided filters beat DR), the online ICR and slip
against the truth, determinism and truth blindness, bad input.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from bench import registry
from bench.registry import Method
from bench.run import Run, RunError
from bench.estimation.ukf import FilterError
from methods.liu2020 import EnDr, IcrDr, LiuUkfParams, MiUkf, UkfIcr
from tests.methods.liu2020.synthetic import make_run, pos_rms, yaw_err

# ----------------------------------------------------------------------------- fixtures
@pytest.fixture(scope="module")
def calib_run() -> Run:
    return make_run(101, duration=40.0, kind="mixed")


@pytest.fixture(scope="module")
def score_run() -> Run:
    return make_run(202, duration=60.0, kind="mixed")


@pytest.fixture(scope="module")
def estimates(calib_run, score_run):
    icr = registry.calibrate(IcrDr(), [calib_run])
    out = {}
    for m in (EnDr(), icr, UkfIcr(), MiUkf()):
        out[m.name] = registry.estimate(m, score_run)
    return out


def test_plugins_satisfy_protocol():
    for m in (EnDr(), IcrDr(), UkfIcr(), MiUkf()):
        assert isinstance(m, Method)
        assert m.name.startswith("liu2020.") and m.paper == "Liu et al. 2020"
        assert not any(c.startswith("truth_") for c in m.requires)
    assert MiUkf().params.innovation_length == 2 and MiUkf().params.mi_a == 0.5
    assert UkfIcr().params.innovation_length == 1
    assert LiuUkfParams().icr_clamp == 20.0


def test_paper_orderings_on_slipping_data(estimates, score_run):
    """Liu Table 2 orderings where they must hold: ICR DR < En-DR, and both GNSS-aided UKFs < ICR DR
    (position RMS against the truth); the filters also beat DR on heading and velocity."""
    rms = {k: pos_rms(e, score_run) for k, e in estimates.items()}
    print("position RMS [m]:", {k: round(v, 4) for k, v in rms.items()})
    assert rms["liu2020.icr"] < 0.5 * rms["liu2020.en_dr"]
    for k in ("liu2020.ukf_icr", "liu2020.mi_ukf"):
        assert rms[k] < 0.25 * rms["liu2020.icr"]
        assert rms[k] < 0.1  # GNSS at 2 cm, 10 Hz
        yaw_rms = float(np.sqrt(np.mean(yaw_err(estimates[k], score_run) ** 2)))
        assert yaw_rms < 0.02
        ev = np.hypot(estimates[k]["vx"] - score_run["truth_vx"], estimates[k]["vy"] - score_run["truth_vy"])
        assert float(np.sqrt(np.mean(ev**2))) < 0.1


def test_online_icr_and_slip_track_truth(estimates, score_run):
    """The filters' ICR (eqs. (2), (3), (5)) and slip outputs follow the truth while turning."""
    est = estimates["liu2020.mi_ukf"]
    turning = (np.abs(score_run["truth_wz"]) > 0.4) & (score_run.t > 5.0)
    assert turning.sum() > 500
    for col in ("y_l", "y_r"):
        err = np.abs(est[col][turning] - score_run[f"truth_{col}"][turning])
        assert np.median(err) < 0.1, (col, np.median(err))
    for col in ("slip_l", "slip_r"):
        e, tr = est[col][turning], score_run[f"truth_{col}"][turning]
        ok = np.isfinite(e) & np.isfinite(tr) & (np.abs(tr) < 2)
        assert np.median(np.abs(e[ok] - tr[ok])) < 0.05
    assert np.all(np.abs(est["y_l"]) <= 20) and np.all(np.abs(est["x_icr"]) <= 20)


def test_deterministic_and_truth_blind():
    run = make_run(17, duration=10.0)
    a = MiUkf().estimate(run)
    b = MiUkf().estimate(make_run(17, duration=10.0).without_truth())
    for c in a.data.columns:
        assert np.array_equal(a[c], b[c], equal_nan=True), c


def test_bad_input_errors():
    score_run = make_run(18, duration=20.0)
    no_imu = Run(score_run.data.drop(columns=["imu_ax"]), score_run.meta)
    with pytest.raises(RunError, match="imu_ax"):
        MiUkf().estimate(no_imu)
    no_geom = Run(score_run.data, {"run_id": "x"})
    with pytest.raises(RunError, match="platform"):
        EnDr().estimate(no_geom)
    with pytest.raises(RuntimeError, match="calibrate"):
        IcrDr().estimate(score_run)
    # a NaN burst in the IMU and encoders is held/dropped, not fused
    d = score_run.data.copy()
    d.loc[1000:1100, ["imu_ax", "imu_ay", "imu_gz", "enc_wl", "enc_wr"]] = np.nan
    est = UkfIcr().estimate(Run(d, score_run.meta))
    assert np.all(np.isfinite(est["x"])) and pos_rms(est, score_run) < 0.1
    # a corrupt (infinite) value is a RunError naming channel and row
    d = score_run.data.copy()
    d.loc[500, "imu_ay"] = np.inf
    with pytest.raises(RunError, match=r"imu_ay.*row 500"):
        MiUkf().estimate(Run(d, score_run.meta))
    with pytest.raises(ValueError, match="q_vel"):
        LiuUkfParams(q_vel=float("nan"))
    # a covariance that cannot be factored is a FilterError naming step, run and time, not a NaN
    bad = UkfIcr(replace(UkfIcr().params, p0_yaw=0.0))
    with pytest.raises(FilterError, match=r"step 1 \(predict\).*positive definite.*run synthetic-mixed-18, t = 0.010"):
        bad.estimate(score_run)
