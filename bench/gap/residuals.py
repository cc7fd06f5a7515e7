"""Residual channels, noise scales, normalised residual vectors and the gap tables.

Channels (measured - model, at the measured sample times):

=============  ==============  =======================================================  ======
channel        group           measured                                                 weight
=============  ==============  =======================================================  ======
enc_wl/wr      wheel speed     encoder speeds [rad/s]                                   1/2
tau_l/r        drive           motor torque at the wheels [N m]                         1/4
i_l/r          drive           motor current [A]                                        1/4
imu_gz         yaw rate        gyro z [rad/s]                                           1
imu_ax/ay      acceleration    accelerometer x/y (specific force) [m/s^2]                1/2
body_vx/vy     body velocity   GNSS velocity rotated into the body by the ref heading    1/2
ref_x/y/yaw    pose            external reference pose [m, rad]                         1/3
=============  ==============  =======================================================  ======

Every group carries the same total weight (torque and current are one group: they carry the
same information unless the motor saturates).

Normalisation: each channel's residual is divided by a noise scale
``sigma_c = max(sigma_hat_c, floor_c)``.  ``sigma_hat_c`` is estimated from the *measured* channel
alone, from its sample-to-sample roughness: ``1.4826 MAD(second difference) / sqrt(6)`` (exact for
white noise on a smooth signal, robust to steps).  ``floor_c`` is a resolution below which a
residual is not considered meaningful (table ``FLOORS``); it matters for channels the testbed logs
without noise (torques, currents).  A channel whose measured samples are missing or all NaN is
left out and named in the report.

The cost of a model is ``J = sum_c w_c mean_k (r_ck / sigma_c)^2``: about
``J_noise = sum_c w_c (sigma_hat_c / sigma_c)^2`` when the model is right and only sensor noise
remains.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

import numpy as np

from bench.run import Run

CHANNELS: dict[str, tuple[str, float]] = {
    "enc_wl": ("wheel speed", 0.5),
    "enc_wr": ("wheel speed", 0.5),
    "tau_l": ("drive", 0.25),
    "tau_r": ("drive", 0.25),
    "i_l": ("drive", 0.25),
    "i_r": ("drive", 0.25),
    "imu_gz": ("yaw rate", 1.0),
    "imu_ax": ("acceleration", 0.5),
    "imu_ay": ("acceleration", 0.5),
    "body_vx": ("body velocity", 0.5),
    "body_vy": ("body velocity", 0.5),
    "ref_x": ("pose", 1.0 / 3.0),
    "ref_y": ("pose", 1.0 / 3.0),
    "ref_yaw": ("pose", 1.0 / 3.0),
}
UNITS = {"enc_wl": "rad/s", "enc_wr": "rad/s", "tau_l": "N m", "tau_r": "N m", "i_l": "A", "i_r": "A",
         "imu_gz": "rad/s", "imu_ax": "m/s^2", "imu_ay": "m/s^2", "body_vx": "m/s", "body_vy": "m/s",
         "ref_x": "m", "ref_y": "m", "ref_yaw": "rad"}
FLOORS = {  # resolution floors of the noise scale (SI)
    "enc_wl": 0.005, "enc_wr": 0.005, "tau_l": 0.01, "tau_r": 0.01, "i_l": 0.005, "i_r": 0.005,
    "imu_gz": 5e-4, "imu_ax": 0.005, "imu_ay": 0.005, "body_vx": 0.005, "body_vy": 0.005,
    "ref_x": 0.002, "ref_y": 0.002, "ref_yaw": 0.001,
}
ANGLE_CHANNELS = ("ref_yaw",)
ALIGN_WINDOW = 1.0  # s at the start of the run on which the initial-pose correction is estimated
# pose residuals accumulate earlier errors: they would point "where" analyses at the end of a run
CUMULATIVE_CHANNELS = ("ref_x", "ref_y", "ref_yaw")


def _heading(run: Run) -> tuple[np.ndarray, np.ndarray] | None:
    for name in ("ref_yaw", "gnss_yaw"):
        if run.has(name):
            t, v = run.samples(name)
            return t, np.unwrap(v)
    return None


def measured_channels(run: Run) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """(t, value) of every residual channel the measured run has (finite samples only)."""
    out: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for c in CHANNELS:
        if c.startswith("body_"):
            continue
        if c in run.data.columns and run.has(c):
            out[c] = run.samples(c)
    hdg = _heading(run)
    if hdg is not None and run.has("gnss_vx") and run.has("gnss_vy"):
        t = run.t
        vx, vy = run["gnss_vx"], run["gnss_vy"]
        m = np.isfinite(vx) & np.isfinite(vy)
        tt = t[m]
        yaw = np.interp(tt, hdg[0], hdg[1])
        cy, sy = np.cos(yaw), np.sin(yaw)
        out["body_vx"] = (tt, cy * vx[m] + sy * vy[m])
        out["body_vy"] = (tt, -sy * vx[m] + cy * vy[m])
    return out


def noise_scale(values: np.ndarray) -> float:
    """Robust white-noise std of a channel from its second differences (0 when < 5 samples)."""
    v = np.asarray(values, float)
    if v.size < 5:
        return 0.0
    d2 = v[2:] - 2.0 * v[1:-1] + v[:-2]
    mad = np.median(np.abs(d2 - np.median(d2)))
    return float(1.4826 * mad / np.sqrt(6.0))


def angle_diff(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return (a - b + np.pi) % (2 * np.pi) - np.pi


@dataclass(frozen=True)
class ResidualSpace:
    """The measured side of the comparison: channels, noise scales, weights, folds, regimes."""

    channels: tuple[str, ...]
    t: Mapping[str, np.ndarray]
    meas: Mapping[str, np.ndarray]
    sigma_hat: Mapping[str, float]
    sigma: Mapping[str, float]
    weight: Mapping[str, float]
    regime: Mapping[str, np.ndarray]  # regime index of each sample
    regime_names: tuple[str, ...]
    missing: tuple[str, ...]
    block: float = 2.0  # [s] length of the time blocks of the folds and of the jackknife (bench.gap.fit)

    @property
    def j_noise(self) -> float:
        """Expected cost of a correct model (sensor noise only)."""
        return float(sum(self.weight[c] * (self.sigma_hat[c] / self.sigma[c]) ** 2 for c in self.channels))

    def align_pose(self, model: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        """The model's pose channels after the weighted least-squares SE(2) correction of its
        initial pose (translation + rotation about its first pose sample), estimated on the
        first ``ALIGN_WINDOW`` s of the run.

        The measured initial pose the replay starts from is itself noisy (a few reference
        samples); the correction treats it as a nuisance parameter.  Only the start of the run
        is used, so a drift that a missing effect builds up later stays in the residual (a
        whole-trajectory alignment would hide part of it).  Other channels are frame-invariant
        and unchanged."""
        if not all(c in self.channels and c in model for c in ("ref_x", "ref_y")):
            return dict(model)
        mx, my = np.asarray(model["ref_x"], float), np.asarray(model["ref_y"], float)
        if mx.size != self.meas["ref_x"].size or my.size != self.meas["ref_y"].size or mx.size < 3:
            return dict(model)
        px, py = mx[0], my[0]
        rows, rhs, wts = [], [], []
        n = mx.size
        rows.append(np.column_stack([np.ones(n), np.zeros(n), -(my - py)]))
        rhs.append(self.meas["ref_x"] - mx)
        wts.append(np.full(n, 1.0 / self.sigma["ref_x"]))
        rows.append(np.column_stack([np.zeros(n), np.ones(n), mx - px]))
        rhs.append(self.meas["ref_y"] - my)
        wts.append(np.full(n, 1.0 / self.sigma["ref_y"]))
        has_yaw = "ref_yaw" in self.channels and "ref_yaw" in model
        if has_yaw:
            k = self.meas["ref_yaw"].size
            rows.append(np.column_stack([np.zeros(k), np.zeros(k), np.ones(k)]))
            rhs.append(angle_diff(self.meas["ref_yaw"], np.asarray(model["ref_yaw"], float)))
            wts.append(np.full(k, 1.0 / self.sigma["ref_yaw"]))
        A = np.vstack(rows) * np.concatenate(wts)[:, None]
        b = np.concatenate(rhs) * np.concatenate(wts)
        tt = [self.t["ref_x"], self.t["ref_y"]] + ([self.t["ref_yaw"]] if has_yaw else [])
        t0 = min(float(x[0]) for x in tt)
        early = np.concatenate(tt) <= t0 + ALIGN_WINDOW
        ok = np.isfinite(b) & np.isfinite(A).all(axis=1) & early
        if ok.sum() < 3:
            return dict(model)
        dx, dy, dpsi = np.linalg.lstsq(A[ok], b[ok], rcond=None)[0]
        c, s = np.cos(dpsi), np.sin(dpsi)
        out = dict(model)
        out["ref_x"] = px + dx + c * (mx - px) - s * (my - py)
        out["ref_y"] = py + dy + s * (mx - px) + c * (my - py)
        if has_yaw:
            out["ref_yaw"] = np.asarray(model["ref_yaw"], float) + dpsi
        return out

    def raw(self, model: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Residual measured - model per channel (angles wrapped; pose after :meth:`align_pose`);
        NaN where the model has none."""
        model = self.align_pose(model)
        out = {}
        for c in self.channels:
            m = model.get(c)
            if m is None:
                out[c] = np.full(self.meas[c].size, np.nan)
            elif c in ANGLE_CHANNELS:
                out[c] = angle_diff(self.meas[c], m)
            else:
                out[c] = self.meas[c] - m
        return out

    def zvec(self, model: Mapping[str, np.ndarray]) -> np.ndarray:
        """Stacked weighted normalised residual: sum of squares = cost J."""
        r = self.raw(model)
        parts = []
        for c in self.channels:
            z = r[c] / self.sigma[c]
            z = np.where(np.isfinite(z), z, 0.0)
            parts.append(z * np.sqrt(self.weight[c] / z.size))
        return np.concatenate(parts)

    def row_channel(self) -> np.ndarray:
        return np.concatenate([np.full(self.meas[c].size, i) for i, c in enumerate(self.channels)])

    def row_fold(self) -> np.ndarray:
        """0/1 fold of each row of :meth:`zvec`: the ``block``-s time blocks alternate."""
        return self.row_block() % 2

    def row_block(self) -> np.ndarray:
        """Index of the ``block``-s time block of each row of :meth:`zvec` (the folds alternate these blocks)."""
        return np.concatenate([np.floor(self.t[c] / self.block).astype(int) for c in self.channels])

    def row_scale(self) -> np.ndarray:
        """Factor from a weighted row of :meth:`zvec` back to its unit-variance residual."""
        return np.concatenate([np.full(self.meas[c].size, np.sqrt(self.meas[c].size / self.weight[c]))
                               for c in self.channels])

    def cost(self, model: Mapping[str, np.ndarray]) -> float:
        z = self.zvec(model)
        return float(z @ z)

    def channel_costs(self, model: Mapping[str, np.ndarray]) -> dict[str, float]:
        r = self.raw(model)
        return {c: float(np.nanmean((r[c] / self.sigma[c]) ** 2)) for c in self.channels}


def build_space(run: Run, regimes_fn, block: float = 2.0, channels: tuple[str, ...] | None = None,
                model_channels: frozenset[str] | None = None) -> ResidualSpace:
    """Measured channels, their noise scales, folds (alternating ``block``-s time blocks) and regimes."""
    meas = measured_channels(run)
    wanted = tuple(channels) if channels else tuple(CHANNELS)
    missing = tuple(c for c in wanted if c not in meas or (model_channels is not None and c not in model_channels))
    chans = tuple(c for c in wanted if c not in missing)
    t = {c: meas[c][0] for c in chans}
    vals = {c: meas[c][1] for c in chans}
    sh = {c: noise_scale(vals[c]) for c in chans}
    sig = {c: max(sh[c], FLOORS[c]) for c in chans}
    w = {c: CHANNELS[c][1] for c in chans}
    names, label_fn = regimes_fn(run)
    reg = {c: label_fn(t[c]) for c in chans}
    return ResidualSpace(chans, t, vals, sh, sig, w, reg, tuple(names), missing, block)


def gap_table(space: ResidualSpace, model: Mapping[str, np.ndarray]) -> dict[str, dict[str, float]]:
    """Per channel: RMS of the residual [SI], percent of the measured signal's RMS, the noise scale,
    and the normalised RMS (residual / noise scale)."""
    r = space.raw(model)
    out = {}
    for c in space.channels:
        rc = r[c]
        rms = float(np.sqrt(np.nanmean(rc**2)))
        sig = space.meas[c]
        if c in ANGLE_CHANNELS:
            sig = sig - np.angle(np.mean(np.exp(1j * sig)))
        elif c.startswith("ref_"):
            sig = sig - np.mean(sig)
        srms = float(np.sqrt(np.mean(sig**2)))
        out[c] = {"rms": rms, "percent": 100.0 * rms / srms if srms > 0 else float("nan"),
                  "noise": float(space.sigma_hat[c]), "sigma": float(space.sigma[c]),
                  "normalised_rms": rms / space.sigma[c], "unit": UNITS[c]}
    return out


def regime_table(space: ResidualSpace, model: Mapping[str, np.ndarray]) -> dict[str, dict]:
    """Per regime: share of time, weighted mean excess cost over the local (non-cumulative)
    channels, and normalised RMS per channel (all channels)."""
    r = space.raw(model)
    out: dict[str, dict] = {}
    for i, name in enumerate(space.regime_names):
        per = {}
        cost = 0.0
        present = False
        for c in space.channels:
            m = space.regime[c] == i
            if not m.any():
                continue
            present = True
            z2 = np.nanmean((r[c][m] / space.sigma[c]) ** 2)
            per[c] = float(np.sqrt(z2))
            if c in CUMULATIVE_CHANNELS:
                continue
            noise2 = (space.sigma_hat[c] / space.sigma[c]) ** 2
            cost += space.weight[c] * max(z2 - noise2, 0.0)
        if present:
            share = float(np.mean(np.concatenate([space.regime[c] == i for c in space.channels])))
            out[name] = {"time_share": share, "excess_cost": float(cost), "normalised_rms": per}
    return out


def time_profile(space: ResidualSpace, model: Mapping[str, np.ndarray], bin_s: float = 0.5
                 ) -> tuple[np.ndarray, np.ndarray]:
    """(bin centres, weighted excess cost per time bin over the local channels): where in time
    the disagreement sits."""
    r = space.raw(model)
    t_end = max(float(space.t[c][-1]) for c in space.channels)
    nb = max(1, int(np.ceil(t_end / bin_s + 1e-9)))
    acc = np.zeros(nb)
    for c in space.channels:
        if c in CUMULATIVE_CHANNELS:
            continue
        k = np.minimum((space.t[c] / bin_s).astype(int), nb - 1)
        z2 = np.nan_to_num((r[c] / space.sigma[c]) ** 2)
        noise2 = (space.sigma_hat[c] / space.sigma[c]) ** 2
        s = np.bincount(k, weights=z2, minlength=nb)
        n = np.bincount(k, minlength=nb)
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = np.where(n > 0, s / np.maximum(n, 1), 0.0)
        acc += space.weight[c] * np.maximum(mean - noise2, 0.0)
    centres = (np.arange(nb) + 0.5) * bin_s
    return centres, acc


__all__ = ["CHANNELS", "UNITS", "FLOORS", "measured_channels", "noise_scale", "ResidualSpace", "build_space",
           "gap_table", "regime_table", "time_profile", "angle_diff"]
