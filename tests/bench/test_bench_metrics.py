"""Speed of bench.metrics on a 100k-pose trajectory (pytest-benchmark; run by `make bench`)."""
from __future__ import annotations

import numpy as np
import pytest

from bench import metrics as M
from bench.kinematics import integrate_se2

N = 100_000


@pytest.fixture(scope="module")
def pair() -> tuple[M.Trajectory, M.Trajectory]:
    rng = np.random.default_rng(0)
    t = np.arange(N) * 0.01
    vx = 0.8 + 0.2 * np.sin(t / 7)
    wz = 0.4 * np.sin(t / 13) + rng.normal(0, 0.02, N)
    x, y, yaw = integrate_se2(t, vx, -0.03 * wz, wz)
    ex, ey, eyaw = integrate_se2(t, 1.02 * vx, 0 * vx, wz + 0.002)
    ref = M.Trajectory.planar(t, x, y, yaw, name="ref")
    est = M.Trajectory.planar(t + rng.uniform(-0.003, 0.003, N), ex + rng.normal(0, 0.01, N),
                              ey + rng.normal(0, 0.01, N), eyaw, name="est")
    return ref, est


def test_ape_translation_se3(benchmark, pair) -> None:
    res = benchmark(M.ape, *pair, "translation", "se3")
    assert res.errors.size == N


def test_ape_rotation_angle(benchmark, pair) -> None:
    res = benchmark(M.ape, *pair, "rotation_angle_rad", "none")
    assert res.errors.size == N


def test_rpe_translation_1_frame(benchmark, pair) -> None:
    res = benchmark(M.rpe, *pair, "translation", 1, "frames")
    assert res.errors.size == N - 1


def test_rpe_rotation_1_m(benchmark, pair) -> None:
    res = benchmark(M.rpe, *pair, "rotation_angle_rad", 1.0, "m")
    assert res.errors.size > 500


def test_rpe_translation_1_m_all_pairs(benchmark, pair) -> None:
    res = benchmark(M.rpe, *pair, "translation", 1.0, "m", all_pairs=True)
    assert res.errors.size > N // 2


def test_associate_nearest(benchmark, pair) -> None:
    r, e = benchmark(M.associate, *pair, 0.01)
    assert len(r) == len(e) == N


def test_window_end_errors(benchmark, pair) -> None:
    res = benchmark(M.window_end_errors, *pair, 2.0, 0.1)
    assert res.position.size > 9000
