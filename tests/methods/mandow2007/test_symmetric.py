"""Mandow 2007 eqs. (11)-(12): the symmetric identification from a pure rotation and a straight line."""
from __future__ import annotations

import numpy as np
import pytest

from methods import mandow2007 as M
from tests.methods.mandow2007.synthetic import joystick_run, simulate_icr_run


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
