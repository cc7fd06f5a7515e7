"""Uneven ground (bench/sim/ground.py): the ISO 8608 heightfield against its class's closed form, the
pybullet body against the grid it was built from, and the robot's support on it."""
from __future__ import annotations

import math

import numpy as np
import pytest

from bench.sim import run_physics
from bench.sim.ground import (ISO8608_CLASS_GD0, build_heightfield, field_heights, grid_variance, height_at,
                              iso8608_psd, profile_psd, road_heights)
from bench.sim.testbed import COL, GRAVITY, p
from bench.spec import SpecError, load_scenario


def test_iso8608_class_means():
    # ISO 8608 Table: class A..E geometric means of G_d(n0) = 16, 64, 256, 1024, 4096 x 1e-6 m^3
    assert [ISO8608_CLASS_GD0[c] * 1e6 for c in "ABCDE"] == pytest.approx([16, 64, 256, 1024, 4096])


def test_profile_psd_matches_class_per_octave():
    gd0, sp = ISO8608_CLASS_GD0["D"], 0.1
    psds = [profile_psd(road_heights(gd0, sp, 1024, 64, seed), sp) for seed in range(32)]
    n = psds[0][0]
    psd = np.mean([q for _, q in psds], axis=0)
    for lo in (0.1, 0.2, 0.4, 0.8, 1.6, 3.2):
        m = (n >= lo) & (n < 2 * lo) & (n < 5.0)
        assert np.mean(psd[m] / iso8608_psd(n[m], gd0)) == pytest.approx(1.0, abs=0.12), lo


def test_height_variance_is_the_psd_integral():
    gd0, sp, n_x = ISO8608_CLASS_GD0["C"], 0.1, 512
    var = np.mean([road_heights(gd0, sp, n_x, 128, seed).var(axis=0).mean() for seed in range(16)])
    assert var == pytest.approx(grid_variance(gd0, sp, n_x), rel=0.12)
    # the grid sum tends to the integral from dn: G_d(n0) n0^2 / dn (pi^2 / 6 for the 1/k^2 sum)
    assert grid_variance(gd0, sp, n_x) == pytest.approx(gd0 * 0.01 * n_x * sp * math.pi**2 / 6, rel=0.01)


def test_same_seed_same_ground_other_seed_other_ground():
    a = field_heights(256e-6, 0.1, 12.8, 6.4, 3)
    assert np.array_equal(a, field_heights(256e-6, 0.1, 12.8, 6.4, 3))
    assert not np.allclose(a, field_heights(256e-6, 0.1, 12.8, 6.4, 4))
    assert np.array_equal(a[-1], a[0]) and np.array_equal(a[:, -1], a[:, 0])  # periodic: wrap row / column


def test_pybullet_body_has_the_grid_heights():
    sp, corner = 0.1, (-3.0, -2.0)
    h = field_heights(ISO8608_CLASS_GD0["E"], sp, 9.6, 6.4, 1)
    cid = p.connect(p.DIRECT)
    try:
        build_heightfield(p, cid, h, sp, corner)
        rng = np.random.default_rng(0)
        for i, j in zip(rng.integers(1, h.shape[0] - 1, 40), rng.integers(1, h.shape[1] - 1, 40)):
            x, y = corner[0] + i * sp, corner[1] + j * sp
            z = p.rayTest((x, y, 5.0), (x, y, -5.0), physicsClientId=cid)[0][3][2]
            assert z == pytest.approx(h[i, j], abs=1e-5)  # exact at the nodes
        for x, y in zip(rng.uniform(-2.9, 6.5, 40), rng.uniform(-1.9, 4.3, 40)):
            z = p.rayTest((x, y, 5.0), (x, y, -5.0), physicsClientId=cid)[0][3][2]
            assert z == pytest.approx(height_at(h, sp, corner, x, y), abs=0.01 * h.std() + 2e-3)
    finally:
        p.disconnect(cid)


def test_robot_is_carried_by_the_rough_ground():
    # vertical balance: over a run the mean total normal load is the weight (the ground slopes of a class C
    # field are a few per cent, cos ~ 1), and the chassis height follows the ground
    scn = load_scenario("straight_0p2_vinyl", {"duration": 4.0, "terrain.roughness_gd0": ISO8608_CLASS_GD0["C"],
                                               "terrain.roughness_length_x": 12.8, "terrain.roughness_length_y": 6.4})
    d = run_physics(scn, 0).data
    loads = d[:, [COL["n_fl"], COL["n_rl"], COL["n_fr"], COL["n_rr"]]].sum(axis=1)
    assert loads[len(loads) // 4:].mean() == pytest.approx(scn.platform.total_mass * GRAVITY, rel=0.03)
    assert np.ptp(d[:, COL["pz"]]) > 1e-3
    flat = run_physics(load_scenario("straight_0p2_vinyl", {"duration": 4.0}), 0).data
    assert np.ptp(flat[flat.shape[0] // 4:, COL["pz"]]) < 1e-4


def test_bad_roughness_is_one_line_error():
    with pytest.raises(SpecError, match="roughness_gd0"):
        load_scenario("straight_0p2_vinyl", {"terrain.roughness_gd0": -1.0})
    scn = load_scenario("ramp_wood_15", {"terrain.roughness_gd0": 1e-4, "duration": 0.1})
    with pytest.raises(ValueError, match="rough ramp"):
        run_physics(scn, 0)


def test_psd_check_fails_on_a_field_of_another_class(monkeypatch):
    from bench.sim import validate as V

    assert V._heightfield_psd().passed
    real = V.field_heights
    monkeypatch.setattr(V, "field_heights", lambda gd0, *a: real(4.0 * gd0, *a))  # one class rougher
    assert not V._heightfield_psd().passed
