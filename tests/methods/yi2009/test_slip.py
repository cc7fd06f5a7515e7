"""Yi 2009 slip (6) and its sign constraint (14): methods.yi2009.slip.
"""
from __future__ import annotations

import numpy as np

from methods.yi2009.slip import constrained_slip, slip_ratio
from tests.methods.yi2009.synthetic import R_WHEEL


def test_slip_ratio_definition_and_clipping():
    """Eq. (6) and the [-1, 1] bound of Sec. III-A; 0 at standstill."""
    lam = slip_ratio([10.0, 10.0, 10.0, 10.0, 0.0], [0.9 * R_WHEEL * 10, R_WHEEL * 10 * 1.2, -1.0, 50.0, 0.3], R_WHEEL)
    np.testing.assert_allclose(lam, [0.1, -0.2, 1.0, -1.0, 0.0], atol=1e-12)


def test_constrained_slip_follows_turn_direction():
    """Eq. (14): the faster side keeps only lambda >= 0, the slower only lambda <= 0; straight: both >= 0."""
    lam_l = np.array([0.2, -0.2, 0.2, -0.2, 0.1, -0.1])
    lam_r = np.array([-0.1, 0.1, 0.3, -0.3, 0.1, -0.1])
    w_l = np.array([8.0, 8.0, 4.0, 4.0, 5.0, 5.0])
    w_r = np.array([4.0, 4.0, 8.0, 8.0, 5.0, 5.0])
    pl, pr = constrained_slip(lam_l, lam_r, w_l, w_r)
    np.testing.assert_array_equal(pl, [0.2, 0.0, 0.0, -0.2, 0.1, 0.0])
    np.testing.assert_array_equal(pr, [-0.1, 0.0, 0.3, 0.0, 0.1, 0.0])
