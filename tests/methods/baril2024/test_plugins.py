"""The plugin ``baril2024.blr_slip``: registered, satisfies the method protocol, falls in the wheel-odometry group
of the league, and on Runs learns a known slip from the calibration run's reference poses and dead-reckons a
held-out run with it."""
from __future__ import annotations

import numpy as np
import pytest

from bench import registry
from bench.run import RunError, from_arrays
from methods.baril2024 import BlrSlip, NotCalibratedError
from tests.fixtures.encoders import readings
from tests.methods.baril2024.synthetic import B, R, TRUE_SLIP, arcs, true_velocities


def _run(seed: int, n: int = 400, ref_every: int = 1):
    """A run of random wheel-speed levels held 1 s each, 20 Hz encoders, reference every ``ref_every`` sample."""
    rng = np.random.default_rng(seed)
    lv = np.repeat(rng.uniform(-5, 5, (n // 20 + 1, 2)), 20, axis=0)[:n]
    wl, wr = lv[:, 0], lv[:, 1]
    x, y, h = arcs(*true_velocities(wl, wr), 0.5, -0.3, 1.0)
    ref = np.full(n, np.nan)
    keep = np.arange(n) % ref_every == 0
    enc_l, enc_r = readings(wl), readings(wr)
    cols = {"t": 0.05 * np.arange(n), "enc_wl": enc_l, "enc_wr": enc_r, "ref_x": np.where(keep, x, ref),
            "ref_y": np.where(keep, y, ref), "ref_yaw": np.where(keep, h, ref)}
    return from_arrays(cols, {"run_id": f"synthetic{seed}", "platform": {"wheel_radius": R, "track": B}}).validate()


def test_registered_with_the_protocol_and_in_the_wheel_odometry_group():
    from bench.reproduce.league_table import group_of

    assert "baril2024.blr_slip" in registry.discover()
    m = registry.get("baril2024.blr_slip")
    assert isinstance(m, BlrSlip) and isinstance(m, registry.Method)
    assert m.name == "baril2024.blr_slip" and m.paper.startswith("Baril") and m.requires == {"enc_wl", "enc_wr"}
    assert m.calibration_requires == {"ref_x", "ref_y", "ref_yaw"}
    assert group_of("baril2024.blr_slip").title == "Wheel odometry"
    assert [w.name for w in m.window_models(R, B)] == ["baril2024_blr_slip", "baril2024_blr_slip_cmd"]


@pytest.mark.parametrize("ref_every", [1, 4])
def test_run_calibration_learns_the_slip_and_estimate_follows_the_truth(ref_every):
    """Reference every sample or every 4th: the slip over a reference interval is the interval mean of a linear
    function of the held IDD velocity, exact when the wheel speeds are constant over it (levels change on a
    multiple of 4 samples here)."""
    cal, scored = _run(0, ref_every=ref_every), _run(1)
    with pytest.raises(NotCalibratedError):
        registry.get("baril2024.blr_slip").estimate(scored)
    m = registry.calibrate(registry.get("baril2024.blr_slip"), [cal])
    p = m.slip.params()
    assert p["s_x[v]"] == pytest.approx(TRUE_SLIP["x"][0], abs=1e-8)
    assert p["s_y[vw]"] == pytest.approx(TRUE_SLIP["y"][0], abs=1e-8)
    assert (p["s_yaw[vw]"], p["s_yaw[v]"], p["s_yaw[w]"]) == pytest.approx(TRUE_SLIP["yaw"], abs=1e-8)
    est = registry.estimate(m, scored)
    ideal = registry.estimate(registry.calibrate(registry.get("baseline.ideal_dd"), [cal]), scored)
    err = np.hypot(est["x"] - scored["ref_x"], est["y"] - scored["ref_y"])
    err_idd = np.hypot(ideal["x"] - scored["ref_x"], ideal["y"] - scored["ref_y"])
    assert err.max() < 1e-8 and err_idd.max() > 0.5
    assert {"vx", "vy", "wz"} <= set(est.data.columns) and est.info["s_yaw[w]"] == pytest.approx(-0.5)


def test_calibration_without_reference_is_a_clear_error():
    run = _run(2)
    bare = from_arrays({c: run[c] for c in ("t", "enc_wl", "enc_wr")} | {"t": run.t},
                       {"run_id": "bare", "platform": {"wheel_radius": R, "track": B}})
    with pytest.raises(RunError, match="reference poses"):
        BlrSlip().calibrate([bare])
