"""Wang 2015 Fig. 5 from Yu's model: chi vs curvature ratio in steady state (Wang eqs. (16)-(23), Wang's
Table 1 parameters, :func:`methods.yu2010.steady.wang_steady_state`).

T. Wang, Y. Wu, J. Liang, C. Han, J. Chen, Q. Zhao, "Analysis and Experimental Kinematics of a Skid-Steering
Wheeled Robot Based on a Laser Scanner Sensor," Sensors 15(5), pp. 9681-9702, 2015, doi:10.3390/s150509681
(Sec. 2.2, built on Yu 2010's model).
"""
from __future__ import annotations

from typing import Any

import numpy as np

from methods.yu2010.repro.figures import _new_figure, _save
from methods.yu2010.repro.runs import monotone
from methods.yu2010.steady import wang2015_table1_params, wang_steady_state

WANG_RATIOS = tuple(float(k) for k in range(8))  # Wang eq. (24): lambda = 0..7
WANG_SPEEDS = (0.1, 0.2, 0.5)  # [m/s]; Wang's Fig. 5 speed is not given: his experiments span 0.1-0.5


def _tag(x: float) -> str:
    """0.1 -> '0p1' for metric ids."""
    return f"{x:g}".replace(".", "p")


# ----------------------------------------------------------------------------------- Wang Fig. 5
def wang_fig5(ctx: Any) -> dict[str, float]:
    """Wang 2015 Fig. 5: chi vs curvature ratio 0..7 from Yu's model in steady state (Wang eqs.
    (16)-(23), Table 1 parameters), at 0.1, 0.2 and 0.5 m/s."""
    q = wang2015_table1_params()
    out: dict[str, float] = {}
    series = {}
    for v in WANG_SPEEDS:
        st = wang_steady_state(q, np.array(WANG_RATIOS), v)
        series[v] = st.chi
        for lam, c in zip(WANG_RATIOS, st.chi):
            out[f"chi_v{_tag(v)}_l{int(lam)}"] = float(c)
        out[f"decreasing_v{_tag(v)}"] = float(monotone(st.chi, False, 0.0))
        out[f"max_residual_v{_tag(v)}"] = float(np.max(st.residual))
    ctx.note("wang_fig5", (
        "Belongs to Wang 2015 Sec. 2.2 (Fig. 5), computed with this package's Yu model (methods/yu2010/steady.py): "
        "force and moment balance of Wang eq. (16) with Yu's shear-stress friction, Wang's Table 1 parameters. "
        "Fig. 5 is a plot without numbers or speed; the claim uses 0.1 m/s (the slowest speed of Wang's "
        "experiments, closest to his constant-velocity assumption). At higher speed the centripetal term bends "
        f"the curve: at 0.2 m/s chi falls to {out['chi_v0p2_l2']:.4f} at curvature ratio 2 and then stays flat within "
        f"{np.ptp(series[0.2][2:]):.4f} (a rise of {np.max(np.diff(series[0.2])):.4f}, below the quadrature's "
        "accuracy, "
        f"so 'decreasing' is {bool(out['decreasing_v0p2'])}); at 0.5 m/s it dips to {out['chi_v0p5_l1']:.3f} at "
        f"curvature ratio 1 and rises to {out['chi_v0p5_l7']:.3f} at 7."
    ))
    fig = _new_figure(6, 3.8)
    ax = fig.add_subplot(1, 1, 1)
    for v, chi in series.items():
        ax.plot(WANG_RATIOS, chi, "o-", label=f"v = {v} m/s")
    ax.set_xlabel("curvature ratio (v_l + v_r)/(v_r - v_l)")
    ax.set_ylabel("chi = (y_l - y_r)/B")
    ax.legend(fontsize=8)
    ax.grid(True, alpha=0.3)
    _save(ctx, fig, "wang_fig5.png", "Wang 2015 Fig. 5: chi vs curvature ratio from Yu's steady-state model")
    return out
