"""Beyond the paper: the GNSS position error as two first-order Gauss-Markov bias states (b_x, b_y)
appended to Liu's six states, for the consistent configuration (:mod:`methods.liu2020.consistent`).

Liu fuses the GNSS position as white noise (Appendix); with ``LiuUkfParams.gnss_bias_tau`` set,
:func:`methods.liu2020.ukf.run_liu_filter` runs these two model functions instead of
:func:`methods.liu2020.model.liu_fx` / :func:`methods.liu2020.model.liu_hx`.
"""
from __future__ import annotations

import numpy as np

from methods.liu2020.model import _H_IDX, liu_fx


def liu_fx_gnss_bias(sig: np.ndarray, dt: float, u: tuple[float, float, bool, float]) -> np.ndarray:
    """:func:`liu_fx` on the six navigation states, and the Gauss-Markov decay ``b <- b exp(-dT/tau)``
    of the two GNSS bias states (columns 6, 7); ``u = (a_x, a_y, transport, exp(-dT/tau))``."""
    out = liu_fx(sig, dt, u[:3])
    out[:, 6:8] *= u[3]
    return out


def liu_hx_gnss_bias(sig: np.ndarray) -> np.ndarray:
    """:func:`liu_hx` with the GNSS bias added to the GNSS position: (X + b_x, Y + b_y, phi, ...)."""
    out = sig[:, _H_IDX]
    out[:, 0] += sig[:, 6]
    out[:, 1] += sig[:, 7]
    return out
