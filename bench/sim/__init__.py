"""The pybullet testbed: ``simulate(scenario, seed) -> Run``.

``bench.sim`` never imports ``methods`` (DESIGN.md data flow).
"""
from __future__ import annotations

import hashlib
import json
import math
from typing import Callable, Sequence

import numpy as np
import pandas as pd
from scipy.spatial.transform import Rotation

from bench.kinematics import icr_inverse
from bench.run import Run
from bench.sim import sensors as S
from bench.sim.commands import SEEDED_COMMANDS, wheel_reference
from bench.sim.startup import initial_wheel_speeds
from bench.sim.testbed import GRAVITY, PhysicsTrace, run_physics
from bench.spec import Scenario, to_dict

TESTBED_VERSION = "3"  # bump when the physics or the truth and sensor synthesis change (recorded in each run)


def scenario_hash(scn: Scenario) -> str:
    d = to_dict(scn)
    d.pop("source_file", None)
    return hashlib.sha256(json.dumps(d, sort_keys=True, default=str).encode()).hexdigest()[:16]


def pose_time_aligned(tr: PhysicsTrace) -> dict[str, np.ndarray]:
    """The trace's rate columns moved onto the time of its pose (row k: time t_k = k dt).

    Bullet integrates semi-implicitly (velocity first, then x_(k+1) = x_k + v_(k+1) dt), and the loop logs
    the base pose and velocity read before step k: the velocity of row k is the one that moved the pose
    from t_(k-1) to t_k, i.e. the mean over that step (time t_k - dt/2).  The wheel update of row k runs
    after that read: its speed is the mean over [t_k, t_(k+1)] (time t_k + dt/2) and its angle the one at
    t_(k+1).  Taken at face value the chassis rates lag the pose by dt/2 (the integrated gyro then lags the
    yaw by w dt/2: 2 mrad at 0.5 rad/s and dt = 1/120 s) and the wheel angles lead it by dt.  Here each
    rate is the mean of its two step means around t_k and each wheel angle the one at t_k (exact for the
    piecewise-constant step velocities), so that integrating the logged rates gives the logged pose.  Row 0 has
    no step before it: its rate is the initial one, v[0] (the state at t_0; 0 for a run from rest), not the mean
    0.5 (v[0] + v[1]), which put half of the first step's velocity at t_0 of a run at rest (0.024 m/s on
    yi_circle) where the IMU's specific force, the gradient of these velocities, never saw it (a strapdown
    integral of the IMU then lagged the truth speed by 0.02 m/s for the whole run; testbed version 2).
    Returns the columns vx, vy, vz, wx, wy, wz, wl, wr, th_l, th_r."""
    t = tr["t"]
    dt = float(t[1] - t[0]) if t.size > 1 else 0.0
    out: dict[str, np.ndarray] = {}
    for c in ("vx", "vy", "vz", "wx", "wy", "wz"):  # step means over [t_(k-1), t_k] -> value at t_k
        v = tr[c]
        out[c] = 0.5 * (v + np.concatenate((v[1:], v[-1:])))
        out[c][:1] = v[:1]  # the initial state at t_0 (no step before it)
    for s in ("l", "r"):  # step means over [t_k, t_(k+1)] -> value at t_k; angle at t_(k+1) -> at t_k
        w = tr[f"w{s}"]
        out[f"w{s}"] = 0.5 * (w + np.concatenate((w[:1], w[:-1])))
        out[f"th_{s}"] = tr[f"th_{s}"] - w * dt
    return out


def truth_from_trace(tr: PhysicsTrace, scn: Scenario) -> dict[str, np.ndarray]:
    """Physics-rate truth: geometric-centre pose, body velocities, slips, ICRs, specific force (rates and wheel
    angles at the pose's time, :func:`pose_time_aligned`)."""
    plat = scn.platform
    t = tr["t"]
    al = pose_time_aligned(tr)
    rot = Rotation.from_quat(np.column_stack([tr["qx"], tr["qy"], tr["qz"], tr["qw"]]))
    Rm = rot.as_matrix()
    cg_world = rot.apply(np.array(tr.cg_offset))
    p_com = np.column_stack([tr["px"], tr["py"], tr["pz"]])
    v_com = np.column_stack([al["vx"], al["vy"], al["vz"]])
    omega = np.column_stack([al["wx"], al["wy"], al["wz"]])
    p_c = p_com - cg_world
    v_c = v_com - np.cross(omega, cg_world)
    v_b = np.einsum("nji,nj->ni", Rm, v_c)
    w_b = np.einsum("nji,nj->ni", Rm, omega)
    yaw, pitch, roll = rot.as_euler("ZYX").T
    a_com = np.gradient(v_com, t, axis=0) if t.size > 2 else np.zeros_like(v_com)
    f_b = np.einsum("nji,nj->ni", Rm, a_com + np.array([0.0, 0.0, GRAVITY]))
    r_l = plat.wheel_radius * plat.wheel_radius_scale_l
    r_r = plat.wheel_radius * plat.wheel_radius_scale_r
    v_l, v_r = r_l * al["wl"], r_r * al["wr"]
    vx, vy, wz = v_b[:, 0], v_b[:, 1], w_b[:, 2]
    half = plat.track / 2
    with np.errstate(divide="ignore", invalid="ignore"):
        slip_l = np.where(np.abs(v_l) > 1e-3, (v_l - (vx - half * wz)) / v_l, np.nan)
        slip_r = np.where(np.abs(v_r) > 1e-3, (v_r - (vx + half * wz)) / v_r, np.nan)
    y_l, y_r, x_icr = icr_inverse(v_l, v_r, vx, vy, wz, min_wz=1e-3)
    return {
        "x": p_c[:, 0], "y": p_c[:, 1], "z": p_c[:, 2], "yaw": np.unwrap(yaw), "pitch": pitch, "roll": roll,
        "vx": vx, "vy": vy, "vz": v_b[:, 2], "wx": w_b[:, 0], "wy": w_b[:, 1], "wz": wz,
        "wl": al["wl"], "wr": al["wr"], "th_l": al["th_l"], "th_r": al["th_r"],
        "slip_l": slip_l, "slip_r": slip_r, "y_l": y_l, "y_r": y_r, "x_icr": x_icr,
        "fx_b": f_b[:, 0], "fy_b": f_b[:, 1], "fz_b": f_b[:, 2],
        "com_x": p_com[:, 0], "com_y": p_com[:, 1], "vcom_x": v_com[:, 0], "vcom_y": v_com[:, 1],
        "tau_l": tr["tau_l"], "tau_r": tr["tau_r"], "i_l": tr["i_l"], "i_r": tr["i_r"],
        "n_fl": tr["n_fl"], "n_rl": tr["n_rl"], "n_fr": tr["n_fr"], "n_rr": tr["n_rr"],
    }


TRUTH_COLUMNS = ("x", "y", "z", "yaw", "pitch", "roll", "vx", "vy", "wz", "wl", "wr",
                 "slip_l", "slip_r", "y_l", "y_r", "x_icr", "n_fl", "n_rl", "n_fr", "n_rr")


def assemble_run(tr: PhysicsTrace, scn: Scenario, seed: int) -> Run:
    """Sample every sensor at its own rate and merge on one time axis (NaN between samples)."""
    plat, sen = scn.platform, scn.platform.sensors
    truth = truth_from_trace(tr, scn)
    t_phys = tr["t"]
    dur = float(t_phys[-1])
    rng = S.streams(seed)
    times = {
        "log": S.sample_times(scn.log_rate_hz, dur),
        "enc": S.sample_times(sen.encoder.rate_hz, dur),
        "imu": S.sample_times(sen.imu.rate_hz, dur),
        "gnss": S.sample_times(sen.gnss.rate_hz, dur),
        "ref": S.sample_times(sen.reference.rate_hz, dur),
    }
    rows_us = np.unique(np.concatenate(list(times.values())))
    t = rows_us / 1e6
    n = t.size

    def at(name: str, tt: np.ndarray) -> np.ndarray:
        return np.interp(tt, t_phys, truth[name])

    def place(tt_us: np.ndarray, values: np.ndarray) -> np.ndarray:
        col = np.full(n, np.nan)
        col[np.searchsorted(rows_us, tt_us)] = values
        return col

    cols: dict[str, np.ndarray] = {"t": t}
    cmd_l, cmd_r = wheel_reference(t, scn.command, plat, seed)
    cols["cmd_wl"], cols["cmd_wr"] = cmd_l, cmd_r
    te = times["enc"] / 1e6
    lat, (w0_l, w0_r) = sen.encoder.latency, initial_wheel_speeds(scn)  # before t = 0: the start's wheel speeds
    enc_l, enc_r = S.encoders(te, S.encoder_angles(te, t_phys, truth["th_l"], w0_l, lat),
                              S.encoder_angles(te, t_phys, truth["th_r"], w0_r, lat), scn, rng["encoder"])
    cols["enc_wl"], cols["enc_wr"] = place(times["enc"], enc_l), place(times["enc"], enc_r)
    tl = times["log"] / 1e6
    step_idx = np.minimum(np.searchsorted(t_phys, tl, side="right") - 1, t_phys.size - 1)
    for name in ("tau_l", "tau_r", "i_l", "i_r"):  # drive signals: the value of the step in force
        cols[name] = place(times["log"], truth[name][step_idx])
    ti = times["imu"] / 1e6
    f_b = np.column_stack([at(c, ti) for c in ("fx_b", "fy_b", "fz_b")])
    w_b = np.column_stack([at(c, ti) for c in ("wx", "wy", "wz")])
    lever = sen.imu.lever_x or sen.imu.lever_y
    alpha = S.yaw_acceleration(ti, t_phys, truth["wz"]) if lever else None  # the lever arm's tangential term
    acc, gyr = S.imu(ti, f_b, w_b, scn, rng["imu"], alpha)
    for j, ax in enumerate("xyz"):
        cols[f"imu_a{ax}"] = place(times["imu"], acc[:, j])
    for j, ax in enumerate("xyz"):
        cols[f"imu_g{ax}"] = place(times["imu"], gyr[:, j])
    tg = times["gnss"] / 1e6
    g = S.gnss(tg, np.column_stack([at("com_x", tg), at("com_y", tg)]),
               np.column_stack([at("vcom_x", tg), at("vcom_y", tg)]), at("yaw", tg), scn, rng["gnss"])
    for k, v in g.items():
        cols[k] = place(times["gnss"], v)
    tr_ = times["ref"] / 1e6
    ref = S.reference(tr_, np.column_stack([at("x", tr_), at("y", tr_)]), at("yaw", tr_), scn, rng["reference"])
    for k, v in ref.items():
        cols[k] = place(times["ref"], v)
    for name in TRUTH_COLUMNS:
        cols[f"truth_{name}"] = at(name, t)
    cols["truth_yaw"] = np.angle(np.exp(1j * cols["truth_yaw"]))
    meta = {
        "run_id": f"{scn.id}-s{seed}",
        "scenario": scn.id,
        "scenario_hash": scenario_hash(scn),
        "scenario_kind": scn.command.kind,
        "paper": scn.paper,
        "seed": int(seed),
        "platform": to_dict(plat),
        "terrain": to_dict(scn.terrain),
        "dt": scn.dt,
        "testbed_version": TESTBED_VERSION,
    }
    meta = json.loads(json.dumps(meta))  # plain JSON types, as a Parquet round trip gives back
    return Run(pd.DataFrame(cols), meta)


def physics_seed(scn: Scenario, seed: int) -> int:
    """The part of ``seed`` the physics sees: the seed for a command whose wheel references it draws
    (:data:`bench.sim.commands.SEEDED_COMMANDS`), else 0.  The physics loop has no other random input (the seed
    draws the sensor noise in :func:`assemble_run`), so runs with equal ``(scenario_hash, physics_seed)`` share one
    :func:`run_physics` trace, bit for bit (tested)."""
    return int(seed) if scn.command.kind in SEEDED_COMMANDS else 0


def simulate_seeds(scn: Scenario, seeds: Sequence[int]) -> list[Run]:
    """``[simulate(scn, s) for s in seeds]`` with the physics stepped once per distinct :func:`physics_seed`
    (identical runs: the sensors of each seed are drawn from the shared trace)."""
    traces: dict[int, PhysicsTrace] = {}
    runs = []
    for seed in seeds:
        ps = physics_seed(scn, seed)
        if ps not in traces:
            if not math.isfinite(scn.duration) or scn.duration <= 0:
                raise ValueError(f"{scn.source_file}: duration {scn.duration} must be > 0")
            traces[ps] = run_physics(scn, ps)
        runs.append(assemble_run(traces[ps], scn, seed))
    return runs


def simulate(scn: Scenario, seed: int = 0, progress: Callable[[float], None] | None = None) -> Run:
    """Simulate a scenario with a seed. Deterministic: same (scenario, seed) -> identical Run."""
    if not math.isfinite(scn.duration) or scn.duration <= 0:
        raise ValueError(f"{scn.source_file}: duration {scn.duration} must be > 0")
    trace = run_physics(scn, physics_seed(scn, seed), progress)
    return assemble_run(trace, scn, seed)


__all__ = ["simulate", "simulate_seeds", "physics_seed", "run_physics", "assemble_run", "truth_from_trace", "scenario_hash", "TESTBED_VERSION"]
