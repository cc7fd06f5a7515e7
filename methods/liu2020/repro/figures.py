"""Figures of the Liu 2020 reproduction: per scenario the panels of Figs. 6-20 (XY, heading, position
error, v_x, v_y, yaw rate, ICR locations, slip), the ICR smoothness against the yaw rate, the heading
through the -pi/pi crossing (Fig. 17), the NEES and the GNSS outage (both beyond the paper).
"""
from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from bench.report.io import atomic_savefig
from bench.estimation.ukf import nees as nees_values
from methods.liu2020.repro.evaluation import (
    ALL_FILTERS,
    COLORS,
    FILTERS,
    LABELS,
    SETTINGS,
    Evaluation,
    ScenarioResult,
    _gnss_body_velocity,
    _heading_excess,
    _state_error,
)


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _scenario_figure(path: Any, sr: ScenarioResult, calib_icr: tuple[float, float, float], number: int) -> None:
    plt = _plt()
    run, est = sr.run0, sr.est0
    t = run.t
    fig, ax = plt.subplots(3, 3, figsize=(15, 12))
    fig.subplots_adjust(left=0.05, right=0.98, bottom=0.05, top=0.94, wspace=0.25, hspace=0.3)
    order = ("en_dr", "icr", "ukf_icr", "mi_ukf")
    # XY (Figs. 6, 11, 16)
    a = ax[0, 0]
    a.plot(run["truth_x"], run["truth_y"], color=COLORS["truth"], lw=2.5, label="truth")
    g = np.isfinite(run["gnss_x"])
    a.plot(run["gnss_x"][g], run["gnss_y"][g], ".", color=COLORS["gnss"], ms=2, label="GNSS")
    for m in order:
        a.plot(est[m]["x"], est[m]["y"], color=COLORS[m], lw=1.2, label=LABELS[m])
    a.plot(run["truth_x"][0], run["truth_y"][0], "o", color="r")
    if number != 1:  # the straight path is ~120 m long and a few cm wide: equal axes would flatten it
        a.set_aspect("equal", adjustable="datalim")
    a.set(xlabel="X [m]", ylabel="Y [m]", title="XY position")
    a.legend(fontsize=7)
    # heading (Figs. 7, 12, 17)
    a = ax[0, 1]
    a.plot(t, run["truth_yaw"], ".", color=COLORS["truth"], ms=2, label="truth")
    for m in order:
        a.plot(t, est[m]["yaw"], ".", color=COLORS[m], ms=1, label=LABELS[m])
    a.set(xlabel="t [s]", ylabel="yaw [rad]", title="orientation (wrapped to [-pi, pi))", ylim=(-3.3, 3.3))
    # position error
    a = ax[0, 2]
    for m in order:
        a.semilogy(t, np.hypot(est[m]["x"] - run["truth_x"], est[m]["y"] - run["truth_y"]) + 1e-4, color=COLORS[m], label=LABELS[m])
    a.set(xlabel="t [s]", ylabel="|p - p_truth| [m]", title="position error vs truth")
    a.legend(fontsize=7)
    # velocities (Figs. 8, 13, 18)
    tg, gvx, gvy = _gnss_body_velocity(run)
    for j, (c, lab) in enumerate((("vx", "v_x [m/s]"), ("vy", "v_y [m/s]"), ("wz", "yaw rate [rad/s]"))):
        a = ax[1, j]
        a.plot(t, run[f"truth_{c}"], color=COLORS["truth"], lw=2.5, label="truth")
        if c != "wz":
            a.plot(tg, gvx if c == "vx" else gvy, ".", color=COLORS["gnss"], ms=2, label="GNSS")
        for m in order:
            a.plot(t, est[m][c], color=COLORS[m], lw=0.8, label=LABELS[m])
        a.set(xlabel="t [s]", ylabel=lab, title=lab.split(" [")[0])
    ax[1, 0].legend(fontsize=7)
    # ICR (Figs. 9, 14, 19)
    a = ax[2, 0]
    for c, ls in (("y_l", "-"), ("y_r", "--")):
        a.plot(t, run[f"truth_{c}"], ls, color=COLORS["truth"], lw=2, label=f"truth {c}")
        for m in FILTERS:
            a.plot(t, est[m][c], ls, color=COLORS[m], lw=0.8, label=f"{LABELS[m]} {c}")
    a.axhline(calib_icr[0], color=COLORS["icr"], lw=1, label="ICR (calibrated) y_l, y_r")
    a.axhline(calib_icr[1], color=COLORS["icr"], lw=1, ls="--")
    a.set(xlabel="t [s]", ylabel="[m]", title="ICR lateral locations y_l, y_r", ylim=(-21, 21) if number == 1 else (-3, 3))
    a.legend(fontsize=6)
    a = ax[2, 1]
    a.plot(t, run["truth_x_icr"], color=COLORS["truth"], lw=2, label="truth")
    for m in FILTERS:
        a.plot(t, est[m]["x_icr"], color=COLORS[m], lw=0.8, label=LABELS[m])
    a.axhline(calib_icr[2], color=COLORS["icr"], lw=1, label="ICR (calibrated)")
    a.set(xlabel="t [s]", ylabel="x [m]", title="ICR longitudinal location x", ylim=(-21, 21) if number == 1 else (-3, 3))
    # slip (Figs. 10, 15, 20)
    a = ax[2, 2]
    for c, ls in (("slip_l", "-"), ("slip_r", "--")):
        a.plot(t, run[f"truth_{c}"], ls, color=COLORS["truth"], lw=2, label=f"truth {c}")
        a.plot(t, est["mi_ukf"][c], ls, color=COLORS["mi_ukf"], lw=0.8, label=f"MI-UKF {c}")
    a.set(xlabel="t [s]", ylabel="slip [-]", title="longitudinal slip (r w - v_wheel)/(r w)", ylim=(-1, 1))
    a.legend(fontsize=7)
    fig.suptitle(f"Liu 2020 scenario {number} ({run.meta.get('scenario', '')}, seed {run.meta.get('seed', '')})")
    atomic_savefig(fig, path, dpi=80)
    plt.close(fig)


def _smoothness_figure(path: Any, ev: Evaluation, out: Mapping[str, float]) -> None:
    plt = _plt()
    fig, a = plt.subplots(figsize=(6, 4.5))
    fig.subplots_adjust(left=0.14, right=0.97, bottom=0.12, top=0.92)
    rs = (17.0, *SETTINGS.sweep_radii)
    wz = np.array([out[f"sweep_r{r:g}.abs_wz"] for r in rs])
    sd = np.array([out[f"sweep_r{r:g}.icr_std"] for r in rs])
    a.loglog(wz, sd, "o-", color=COLORS["mi_ukf"], label="sweep: scenario 2 at R 17, 8, 4, 2 m")
    for k, mk in (("s1_liu", "D"), ("s2", "s"), ("s3", "^")):
        a.loglog(out[f"{k}.abs_wz"], out[f"{k}.icr_std"], mk, ms=10, mfc="none", color="k",
                 label="s1 as Liu drove it (R 63 m)" if k == "s1_liu" else k)
    a.loglog(wz, sd[0] * wz[0] / wz, ":", color="0.5", label="~ 1/|yaw rate|")
    a.set(xlabel="mean |yaw rate| [rad/s]", ylabel="std of y_l, y_r [m]", title="MI-UKF ICR smoothness")
    a.legend(fontsize=8)
    atomic_savefig(fig, path, dpi=90)
    plt.close(fig)


def _heading_figure(path: Any, ev: Evaluation) -> None:
    plt = _plt()
    run = ev.heading_runs[0]
    t = run.t
    fig, ax = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    fig.subplots_adjust(left=0.12, right=0.97, bottom=0.09, top=0.94, hspace=0.25)
    ax[0].plot(t, run["truth_yaw"], ".", color="k", ms=3, label="truth")
    for f in FILTERS:
        e = ev.heading_est[f][0]
        ax[0].plot(t, e["yaw"], ".", color=COLORS[f], ms=1.5, label=LABELS[f])
        ax[1].plot(t[1:], _heading_excess(run, e, SETTINGS.heading_margin), color=COLORS[f], lw=0.8, label=LABELS[f])
    ax[1].axhline(0.0, color="k", lw=0.8)
    ax[0].set(ylabel="yaw [rad]", title="heading through the -pi/pi crossing")
    ax[1].set(xlabel="t [s]", ylabel="step excess [rad]", title="|yaw step| - (|yaw rate| dt + margin) (<= 0: no chattering)")
    ax[0].legend(fontsize=8)
    atomic_savefig(fig, path, dpi=90)
    plt.close(fig)


def _nees_figure(path: Any, ev: Evaluation, b6: tuple[float, float], b3: tuple[float, float]) -> None:
    plt = _plt()
    fig, ax = plt.subplots(len(ev.scenarios), 2, figsize=(12, 9))
    fig.subplots_adjust(left=0.07, right=0.98, bottom=0.06, top=0.95, wspace=0.2, hspace=0.4)
    for i, (k, sr) in enumerate(ev.scenarios.items()):
        t = sr.run0.t[1:]
        for j, (arr, band, dof) in enumerate(((sr.nees6, b6, 6), (sr.nees3, b3, 3))):
            a = ax[i, j]
            for f in ALL_FILTERS:
                a.semilogy(t, arr[f].mean(axis=0), color=COLORS[f], lw=0.8, label=LABELS[f])
            a.axhspan(*band, color="0.85", label="95% band")
            a.axhline(dof, color="k", lw=0.6)
            a.set(title=f"{k}: {'6-state' if dof == 6 else 'pose'} NEES (N = {len(ev.seeds)})", xlabel="t [s]")
    ax[0, 0].legend(fontsize=8)
    atomic_savefig(fig, path, dpi=80)
    plt.close(fig)


def _outage_figure(path: Any, ev: Evaluation, b3: tuple[float, float]) -> None:
    plt = _plt()
    t = ev.outage_runs[0].t
    t0, t1 = SETTINGS.outage
    fig, ax = plt.subplots(1, 2, figsize=(12, 4.5))
    fig.subplots_adjust(left=0.07, right=0.98, bottom=0.12, top=0.92, wspace=0.2)
    for m, ests in ev.outage_est.items():
        err = np.mean([np.hypot(e["x"] - r["truth_x"], e["y"] - r["truth_y"]) for r, e in zip(ev.outage_runs, ests)], axis=0)
        ax[0].semilogy(t, err + 1e-4, color=COLORS[m], label=LABELS[m])
        if m in ALL_FILTERS:
            a3 = np.mean([nees_values(_state_error(r, e)[:, :3], e.info["P"][:, :3, :3]) for r, e in zip(ev.outage_runs, ests)], axis=0)
            ax[1].semilogy(t, a3, color=COLORS[m], lw=0.8, label=LABELS[m])
    for a in ax:
        a.axvspan(t0, t1, color="0.9", label="GNSS outage")
        a.set(xlabel="t [s]")
    ax[1].axhspan(*b3, color="tab:cyan", alpha=0.3, label="95% band")
    ax[0].set(ylabel="position error [m] (seed mean)", title="position error, GNSS outage 8-28 s")
    ax[1].set(ylabel="pose NEES (seed mean)", title="pose NEES")
    ax[0].legend(fontsize=8)
    ax[1].legend(fontsize=8)
    atomic_savefig(fig, path, dpi=90)
    plt.close(fig)
