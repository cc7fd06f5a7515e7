"""Every scenario file loads, and its first second simulates to finite numbers with the commanded
wheel speeds (units of the papers converted at the file boundary)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from bench.sim import simulate
from bench.sim.commands import RPM_TO_RAD_S, lemniscate_v_radius, wheel_reference
from bench.spec import list_scenarios, load_scenario


@pytest.mark.parametrize("name", list_scenarios())
def test_scenario_loads_and_simulates(name):
    scn = load_scenario(name, {"duration": 1.0})
    run = simulate(scn, 0)
    truth = run.data[[c for c in run.data.columns if c.startswith("truth_") and c not in
                      ("truth_slip_l", "truth_slip_r", "truth_y_l", "truth_y_r", "truth_x_icr")]]
    assert np.isfinite(truth.to_numpy()).all()
    assert np.isfinite(run.data[["cmd_wl", "cmd_wr"]].to_numpy()).all()


def test_yi_rpm_converted_at_the_boundary():
    scn = load_scenario("yi_circle")
    wl, wr = wheel_reference(np.array([1.0]), scn.command, scn.platform)
    assert wl[0] == pytest.approx(80 * 2 * math.pi / 60) and wr[0] == pytest.approx(40 * RPM_TO_RAD_S)


def test_wang_validation_path_tread_speeds():
    scn = load_scenario("wang_validation_path")
    wl, wr = wheel_reference(np.array([0.5, 3.5, 6.5]), scn.command, scn.platform)
    r = scn.platform.wheel_radius
    assert np.allclose(wl * r, [0.2, 0.4, 0.0]) and np.allclose(wr * r, [0.15, 0.0, 0.0])


def test_curvature_ratio_command_matches_definition():
    scn = load_scenario("wang_circle_grid")
    for lam in (0.0, 1.0, 3.0, 7.0):
        cmd = scn.command.__class__(kind="v_curvature_ratio", segments=(type(scn.command.segments[0])(1.0, 0.4, lam),))
        wl, wr = wheel_reference(np.array([0.5]), cmd, scn.platform)
        vl, vr = wl[0], wr[0]
        assert max(abs(vl), abs(vr)) * scn.platform.wheel_radius == pytest.approx(0.4)
        assert (vl + vr) / (vr - vl) == pytest.approx(lam, abs=1e-12)


def test_lemniscate_speed_matches_finite_difference_of_eqs_29_30():
    t = np.linspace(0, 100, 2001)
    s = t / 50
    X = 9 * np.cos(s) / (1 + np.sin(s) ** 2)
    Y = 27 * np.sin(s) * np.cos(s) / (1 + np.sin(s) ** 2)
    v_fd = np.hypot(np.gradient(X, t), np.gradient(Y, t))
    v, _ = lemniscate_v_radius(t)
    assert np.allclose(v[5:-5], v_fd[5:-5], rtol=1e-3)
