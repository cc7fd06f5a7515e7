"""Yu 2010 reproduction: figures (Agg canvas, no pyplot global state; saved atomically and registered with
``ctx.figure``) and the four-panel dynamic figure of Figs. 10-13 and 24-29 (wheel speeds, torques, path,
X/Y errors: :func:`_figure_dynamic`).
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from bench.report.io import atomic_savefig
from bench.run import Run


def _new_figure(w: float, h: float) -> Any:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(w, h))
    FigureCanvasAgg(fig)  # Agg canvas, no pyplot global state
    return fig


def _save(ctx: Any, fig: Any, name: str, caption: str) -> None:
    path = Path(ctx.out_dir) / name
    fig.tight_layout()
    atomic_savefig(fig, path, dpi=110, metadata={"Software": None})
    ctx.figure(path, caption)


def _figure_dynamic(ctx: Any, run: Run, est: Any, name: str, caption: str) -> None:
    t = run.t
    enc = np.isfinite(run["enc_wl"])
    tq = np.isfinite(run["tau_l"])
    fig = _new_figure(11, 7)
    ax = fig.add_subplot(2, 2, 1)
    kern = np.ones(5) / 5.0  # 50 ms mean of the quantised encoder speed (display only)
    te = t[enc][2:-2]
    for side, color in (("l", "C0"), ("r", "C3")):
        ax.plot(te, np.convolve(run[f"enc_w{side}"][enc], kern, "valid"), color=color, lw=1,
                label=f"testbed {'left' if side == 'l' else 'right'} (encoder, 50 ms mean)")
    ax.plot(est.t, est["wl"], "--", color="C0", label="model left")
    ax.plot(est.t, est["wr"], "--", color="C3", label="model right")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("wheel speed [rad/s]")
    ax.legend(fontsize=7)
    ax.grid(True, alpha=0.3)
    ax = fig.add_subplot(2, 2, 2)
    ax.plot(t[tq], run["tau_l"][tq], color="C0", lw=1, label="testbed left")
    ax.plot(t[tq], run["tau_r"][tq], color="C3", lw=1, label="testbed right")
    ax.plot(est.t, est["tau_l"], "--", color="C0", label="model left")
    ax.plot(est.t, est["tau_r"], "--", color="C3", label="model right")
    later = t >= t[0] + 1.0  # the start-up transient may peak far above the rest: clip it
    vals = np.concatenate([run["tau_l"][tq & later], run["tau_r"][tq & later],
                           est["tau_l"][later], est["tau_r"][later]])
    lo, hi = float(np.min(vals)), float(np.max(vals))
    pad = 0.3 * max(hi - lo, 0.5)
    ax.set_ylim(lo - pad, hi + pad)
    peak = max(float(np.nanmax(np.abs(run["tau_l"]))), float(np.nanmax(np.abs(run["tau_r"]))))
    if peak > hi + pad:
        ax.set_title(f"start-up peak {peak:.1f} N m (testbed) clipped", fontsize=8)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("wheel torque per side [N m]")
    ax.legend(fontsize=7)
    ax.grid(True, alpha=0.3)
    ax = fig.add_subplot(2, 2, 3)
    ax.plot(run["truth_x"], run["truth_y"], label="testbed")
    ax.plot(est["x"], est["y"], "--", label="model")
    ax.set_xlabel("X [m]")
    ax.set_ylabel("Y [m]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(fontsize=7)
    ax.grid(True, alpha=0.3)
    ax = fig.add_subplot(2, 2, 4)
    ax.plot(t, run["truth_x"] - est["x"], label="X error (testbed - model)")
    ax.plot(t, run["truth_y"] - est["y"], label="Y error (testbed - model)")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("[m]")
    ax.legend(fontsize=7)
    ax.grid(True, alpha=0.3)
    _save(ctx, fig, name, caption)
