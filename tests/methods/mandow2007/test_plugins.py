"""Mandow 2007 plugins through the registry (synthetic runs)."""
from __future__ import annotations

import numpy as np
import pytest

from bench import registry
from methods import mandow2007 as M
from tests.methods.mandow2007.synthetic import joystick_run


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
