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

Quantised channels (:func:`quantisation_step`): when every sample of a channel sits on a lattice
``n q`` (encoder speeds are count differences times ``q = 2 pi / (counts_per_rev T)``), the MAD of
second differences is the MAD of a few discrete values and says little: at a constant speed of
``n + f`` counts per sample the count difference is the same on most samples, the MAD is 0 and the
noise scale collapsed to its floor, while the residual against the noise-free model is the
quantisation error, of variance ``f (1 - f) q^2`` (up to ``q^2 / 4``).  So the noise scale of a
quantised channel is at least the quantisation's: ``q / 2`` for a difference of two quantised
samples (the largest ``f (1 - f) q^2``; ``q^2 / 6``, two independent ``q^2 / 12``, on average over
speeds, where the MAD estimate, 0.6 q, is the larger), ``q / sqrt(12)`` for a channel quantised
once.

Sensors that did not report: a reference pose logged at a higher rate than the sensor's (held
between reports, as the DRIVE Husky table does) repeats the previous pose exactly; those rows are
not samples and are left out (:func:`reported_rows`), so noise scales, the pose alignment and
sample counts see only the poses the sensor reported.  Float (not quantised) wheel speeds held by the
logger are left out the same way (:func:`held_encoder_rows`; the Husky's 10 Hz wheel speeds in its 20 Hz
rows); the model's wheel speed at a reported sample is then the mean since the previous reported one, the
sensor's own period.

The cost of a model is ``J = sum_c w_c mean_k (r_ck / sigma_c)^2``: about
``J_noise = sum_c w_c (sigma_hat_c / sigma_c)^2`` when the model is right and only sensor noise
remains.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Mapping

import numpy as np

from bench.run import Run, RunError

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
POSE_CHANNELS = ("ref_x", "ref_y", "ref_yaw")
DIFFERENCED_CHANNELS = ("enc_wl", "enc_wr")  # a sample is a difference of two quantised counts
HELD_SHARE = 0.4  # share of repeated wheel-speed rows from which repeats are a logger's (held_encoder_rows)
ALIGN_WINDOW = 1.0  # s at the start of the run on which the initial-pose correction is estimated
ALIGN_MIN_SAMPLES = 20  # ... extended until it holds this many pose samples (a 5 Hz DGPS: 4 s)
ALIGN_RESOLUTION = 0.5  # rotation fitted only if its error moves the pose by <= this x sigma over the run
# pose residuals accumulate earlier errors: they would point "where" analyses at the end of a run
CUMULATIVE_CHANNELS = ("ref_x", "ref_y", "ref_yaw")


def _heading(run: Run) -> tuple[np.ndarray, np.ndarray] | None:
    if run.has("ref_yaw"):
        m = reported_rows(run, POSE_CHANNELS) & np.isfinite(run["ref_yaw"])
        return run.t[m], np.unwrap(run["ref_yaw"][m])
    if run.has("gnss_yaw"):
        t, v = run.samples("gnss_yaw")
        return t, np.unwrap(v)
    return None


def reported_rows(run: Run, names: tuple[str, ...]) -> np.ndarray:
    """Row mask of the samples a sensor logging the channels ``names`` together actually reported:
    finite, and not an exact repeat of the previous sample of every one of them (a pose held
    between reports).  Channels of ``names`` the run lacks are ignored."""
    present = [n for n in names if n in run.data.columns and run.has(n)]
    if not present:
        return np.zeros(run.t.size, bool)
    vals = np.column_stack([run[n] for n in present])
    finite = np.isfinite(vals).all(axis=1)
    idx = np.flatnonzero(finite)
    keep = np.zeros(run.t.size, bool)
    if idx.size:
        v = vals[idx]
        fresh = np.r_[True, np.any(v[1:] != v[:-1], axis=1)]
        keep[idx[fresh]] = True
    return keep


def held_encoder_rows(run: Run) -> np.ndarray:
    """Row mask of wheel-speed samples that only hold the previous report: both encoder channels exactly
    equal to the previous finite row, not both zero, in a run where at least ``HELD_SHARE`` of the rows
    repeat so (a logger faster than the sensor: the DRIVE Husky table's 20 Hz rows hold its 10 Hz wheel
    speeds, every other row a repeat) and whose speeds are not quantised (speed x sample interval, the count
    difference, off any lattice: :func:`quantisation_step`).  A noisy float wheel speed repeats exactly only
    when the logger wrote the last value again; a quantised count difference repeats whenever the count per
    period does, and a wheel at rest reads 0 sample after sample: those are samples."""
    names = [n for n in DIFFERENCED_CHANNELS if n in run.data.columns and run.has(n)]
    held = np.zeros(run.t.size, bool)
    if not names:
        return held
    vals = np.column_stack([run[n] for n in names])
    idx = np.flatnonzero(np.isfinite(vals).all(axis=1))
    if idx.size < 3:
        return held
    v = vals[idx]
    rep = np.all(v[1:] == v[:-1], axis=1) & np.any(v[1:] != 0.0, axis=1)
    if rep.mean() < HELD_SHARE:  # no logger pattern: a repeat is a sample (a quantised speed, a wheel at rest)
        return held
    dt = np.diff(run.t[idx])
    counts = v[1:] * dt[:, None]  # a count difference times q: on a lattice whatever the sample interval
    if any(quantisation_step(counts[:, j]) > 0 for j in range(len(names))):
        return held
    held[idx[1:]] = rep
    return held


def encoder_samples(run: Run, name: str, held: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(t, values) of a wheel-speed channel's own samples: its finite rows less those the logger only held
    (:func:`held_encoder_rows`, or the mask ``held`` already computed from it).  A logger's copies of a zero
    reading stay: they cannot be told from a wheel at rest reporting 0 at the sensor's rate."""
    v = run[name]
    m = np.isfinite(v) & ~(held_encoder_rows(run) if held is None else held)
    return run.t[m], v[m]


def measured_channels(run: Run) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """(t, value) of every residual channel the measured run has (finite samples only; pose rows
    where the reference sensor did not report, :func:`reported_rows`, and wheel speeds held by the logger,
    :func:`held_encoder_rows`, are left out)."""
    out: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    pose_rows = reported_rows(run, POSE_CHANNELS)
    held_enc = held_encoder_rows(run)
    for c in CHANNELS:
        if c.startswith("body_"):
            continue
        if c in run.data.columns and run.has(c):
            t, v = run.samples(c)
            if c in POSE_CHANNELS:
                m = pose_rows & np.isfinite(run[c])
                t, v = run.t[m], run[c][m]
            elif c in DIFFERENCED_CHANNELS and held_enc.any():
                t, v = encoder_samples(run, c, held_enc)
            out[c] = (t, v)
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


def quantisation_step(values: np.ndarray, rtol: float = 1e-3) -> float:
    """The step ``q`` of a channel whose samples all sit on a lattice ``v0 + n q`` (a quantised
    signal), 0 when they do not: fewer than 10 samples, more distinct values than a quarter of the
    samples, or a sample more than ``rtol`` q off the lattice.  ``q`` is the smallest gap between
    distinct values (values within 1e-9 of the largest are one value: rounding)."""
    v = np.asarray(values, float)
    v = v[np.isfinite(v)]
    if v.size < 10:
        return 0.0
    u = np.unique(v)
    gaps = np.diff(u)
    gaps = gaps[gaps > 1e-9 * max(float(np.max(np.abs(u))), 1e-300)]  # rounding of n q / T is no gap
    if gaps.size < 1 or gaps.size + 1 > v.size // 4:
        return 0.0
    q = float(np.min(gaps))
    k = (v - u[0]) / q
    return q if float(np.max(np.abs(k - np.rint(k)))) <= rtol else 0.0


def quantisation_noise(channel: str, values: np.ndarray) -> float:
    """Noise scale a quantised channel has at least (module docstring): ``q / 2`` for a difference
    of two quantised samples (encoders), ``q / sqrt(12)`` otherwise; 0 when not quantised."""
    q = quantisation_step(values)
    return 0.5 * q if channel in DIFFERENCED_CHANNELS else q / math.sqrt(12.0)


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
    align_until: float = ALIGN_WINDOW  # [s] pose samples up to this time fit the initial-pose correction
    align_rotation: bool = True  # the correction includes a rotation (alignment_plan)

    @property
    def j_noise(self) -> float:
        """Expected cost of a correct model (sensor noise only)."""
        return float(sum(self.weight[c] * (self.sigma_hat[c] / self.sigma[c]) ** 2 for c in self.channels))

    def align_pose(self, model: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        """The model's pose channels after the weighted least-squares SE(2) correction of its
        initial pose (translation + rotation about its first pose sample), estimated on the
        first ``align_until`` s of the run (``ALIGN_WINDOW``, longer when that holds fewer than
        ``ALIGN_MIN_SAMPLES`` pose samples: :func:`alignment_plan`); the rotation only when
        ``align_rotation`` (the window determines it well enough for the whole run).

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
        has_yaw = "ref_yaw" in self.channels and "ref_yaw" in model
        A, b = _alignment_system(self, mx, my, np.asarray(model["ref_yaw"], float) if has_yaw else None)
        if not self.align_rotation:
            A, b = A[:, :2], b
        ok = np.isfinite(b) & np.isfinite(A).all(axis=1) & (np.abs(A).sum(axis=1) > 0)
        if ok.sum() < 3:
            return dict(model)
        sol = np.linalg.lstsq(A[ok], b[ok], rcond=None)[0]
        dx, dy = sol[0], sol[1]
        dpsi = sol[2] if self.align_rotation else 0.0
        px, py = mx[0], my[0]
        c, s = np.cos(dpsi), np.sin(dpsi)
        out = dict(model)
        out["ref_x"] = px + dx + c * (mx - px) - s * (my - py)
        out["ref_y"] = py + dy + s * (mx - px) + c * (my - py)
        if has_yaw:
            out["ref_yaw"] = np.asarray(model["ref_yaw"], float) + dpsi
        return out

    def run_starts(self, channel: str) -> tuple[int, ...]:
        """Index of the first sample of each measured run in ``channel`` (one run: ``(0,)``;
        :class:`bench.gap.segments.SegmentSpace` concatenates several)."""
        return (0,)

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


def _alignment_system(space: "ResidualSpace", mx: np.ndarray, my: np.ndarray, myaw: np.ndarray | None
                      ) -> tuple[np.ndarray, np.ndarray]:
    """Weighted linearised SE(2) system ``A (dx, dy, dpsi) = b`` of the pose samples up to
    ``space.align_until`` (rows of later samples zero), for model poses ``mx, my, myaw``."""
    px, py = mx[0], my[0]
    n = mx.size
    rows = [np.column_stack([np.ones(n), np.zeros(n), -(my - py)]),
            np.column_stack([np.zeros(n), np.ones(n), mx - px])]
    rhs = [space.meas["ref_x"] - mx, space.meas["ref_y"] - my]
    wts = [np.full(n, 1.0 / space.sigma["ref_x"]), np.full(n, 1.0 / space.sigma["ref_y"])]
    tt = [space.t["ref_x"], space.t["ref_y"]]
    if myaw is not None:
        k = space.meas["ref_yaw"].size
        rows.append(np.column_stack([np.zeros(k), np.zeros(k), np.ones(k)]))
        rhs.append(angle_diff(space.meas["ref_yaw"], myaw))
        wts.append(np.full(k, 1.0 / space.sigma["ref_yaw"]))
        tt.append(space.t["ref_yaw"])
    early = (np.concatenate(tt) <= space.align_until)[:, None]
    w = np.concatenate(wts)
    return np.vstack(rows) * w[:, None] * early, np.concatenate(rhs) * w * early[:, 0]


def alignment_plan(t: Mapping[str, np.ndarray], meas: Mapping[str, np.ndarray], sigma: Mapping[str, float]
                   ) -> tuple[float, bool]:
    """(``align_until``, ``align_rotation``) of the initial-pose correction, from the measured poses.

    Window: the first ``ALIGN_WINDOW`` s, extended until it holds ``ALIGN_MIN_SAMPLES`` samples of
    ``ref_x`` (a 5 Hz DGPS has 6 in the first second: an offset fitted on them is off by 0.4 of its
    noise for the rest of the run).  Rotation: fitted only when the window determines it: its
    standard error times the largest distance the run travels from its first pose is at most
    ``ALIGN_RESOLUTION`` x the position noise.  Otherwise a rotation fitted on a few heading samples
    turns the whole trajectory by its error (5 Hz DGPS, 0.005 rad heading noise, 50 m: a false
    pose gap of several sigma) and the model keeps the initial heading of the replay
    (:func:`bench.gap.model.initial_state`)."""
    if "ref_x" not in t or "ref_y" not in t or t["ref_x"].size < 3:
        return ALIGN_WINDOW, True
    tx = t["ref_x"]
    t0 = float(min(tx[0], t["ref_y"][0]))
    k = min(ALIGN_MIN_SAMPLES, tx.size) - 1
    until = max(t0 + ALIGN_WINDOW, float(tx[k]))
    space = ResidualSpace(tuple(c for c in ("ref_x", "ref_y", "ref_yaw") if c in t), t, meas, sigma, sigma,
                          {}, {}, (), (), align_until=until)
    mx, my = np.asarray(meas["ref_x"], float), np.asarray(meas["ref_y"], float)
    if mx.size != my.size:
        return until, True
    A, _ = _alignment_system(space, mx, my, np.asarray(meas["ref_yaw"], float) if "ref_yaw" in t else None)
    A = A[np.isfinite(A).all(axis=1)]
    try:
        cov = np.linalg.inv(A.T @ A)
        sd_psi = math.sqrt(max(float(cov[2, 2]), 0.0))
    except np.linalg.LinAlgError:
        sd_psi = math.inf
    lever = float(np.nanmax(np.hypot(mx - mx[0], my - my[0])))
    pos_sigma = min(sigma["ref_x"], sigma["ref_y"])
    return until, bool(lever * sd_psi <= ALIGN_RESOLUTION * pos_sigma)


def build_space(run: Run, regimes_fn, block: float = 2.0, channels: tuple[str, ...] | None = None,
                model_channels: frozenset[str] | None = None, required: bool = False) -> ResidualSpace:
    """Measured channels, their noise scales, folds (alternating ``block``-s time blocks) and regimes;
    ``required``: a run with none of the residual channels is a one-line :class:`~bench.run.RunError`."""
    meas = measured_channels(run)
    wanted = tuple(channels) if channels else tuple(CHANNELS)
    missing = tuple(c for c in wanted if c not in meas or (model_channels is not None and c not in model_channels))
    chans = tuple(c for c in wanted if c not in missing)
    if required and not chans:
        raise RunError(run.where, "<channels>", sorted(run.data.columns), f"no residual channel of {list(CHANNELS)}")
    t = {c: meas[c][0] for c in chans}
    vals = {c: meas[c][1] for c in chans}
    sh = {c: max(noise_scale(vals[c]), quantisation_noise(c, vals[c])) for c in chans}
    sig = {c: max(sh[c], FLOORS[c]) for c in chans}
    w = {c: CHANNELS[c][1] for c in chans}
    names, label_fn = regimes_fn(run)
    reg = {c: label_fn(t[c]) for c in chans}
    until, rotation = alignment_plan(t, vals, sig)
    return ResidualSpace(chans, t, vals, sh, sig, w, reg, tuple(names), missing, block, until, rotation)


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


def local_terms(space: ResidualSpace, raw: Mapping[str, np.ndarray]
                ) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray, float]]:
    """Per channel the terms the "where" analysis sums: ``(t, regime index, z2, noise2)``.

    A local channel's term is its squared normalised residual ``(r / sigma)^2`` at each sample, with
    the sensor noise's expectation ``noise2 = (sigma_hat / sigma)^2``.  A pose channel's residual is
    cumulative (an error made at one time stays in every later sample), so its term is the growth of
    the error between consecutive samples: ``(r_k - r_(k-1))^2 / (2 sigma^2)`` at sample ``k`` (angles
    wrapped), whose noise expectation is the same ``noise2`` (the difference of two independent noise
    samples has twice their variance).  The pose channels then point at the samples where the pose
    error is made, as the local channels do, and a drift that the local channels miss (the reference
    yaw of a turn the model takes too fast) shows where it happens.  Across the start of a run
    (:meth:`ResidualSpace.run_starts`: several runs fitted together) there is no growth term (NaN)."""
    out = {}
    for c in space.channels:
        r = np.asarray(raw[c], float)
        t, reg = np.asarray(space.t[c]), np.asarray(space.regime[c])
        if c in CUMULATIVE_CHANNELS:
            d = np.diff(r)
            if c in ANGLE_CHANNELS:
                d = np.angle(np.exp(1j * d))
            z2, t, reg = d**2 / (2.0 * space.sigma[c] ** 2), t[1:], reg[1:]
            for k in space.run_starts(c)[1:]:  # no growth from one run's end to the next run's start
                z2[k - 1] = np.nan
        else:
            z2 = (r / space.sigma[c]) ** 2
        out[c] = (t, reg, z2, float((space.sigma_hat[c] / space.sigma[c]) ** 2))
    return out


def regime_table(space: ResidualSpace, model: Mapping[str, np.ndarray]) -> dict[str, dict]:
    """Per regime: share of time, weighted mean excess cost over every channel's local term
    (:func:`local_terms`: the pose channels by the growth of their error), the normalised RMS of each
    channel's residual and the RMS of its local term (``local_rms``; equal for local channels)."""
    r = space.raw(model)
    terms = local_terms(space, r)
    out: dict[str, dict] = {}
    for i, name in enumerate(space.regime_names):
        per, local = {}, {}
        cost = 0.0
        present = False
        for c in space.channels:
            m = space.regime[c] == i
            if not m.any():
                continue
            present = True
            per[c] = float(np.sqrt(np.nanmean((r[c][m] / space.sigma[c]) ** 2)))
            _, reg, z2, noise2 = terms[c]
            k = (reg == i) & np.isfinite(z2)
            if not k.any():
                continue
            mean = float(np.mean(z2[k]))
            local[c] = float(np.sqrt(mean))
            cost += space.weight[c] * max(mean - noise2, 0.0)
        if present:
            share = float(np.mean(np.concatenate([space.regime[c] == i for c in space.channels])))
            out[name] = {"time_share": share, "excess_cost": float(cost), "normalised_rms": per, "local_rms": local}
    return out


def time_profile(space: ResidualSpace, model: Mapping[str, np.ndarray], bin_s: float = 0.5
                 ) -> tuple[np.ndarray, np.ndarray]:
    """(bin centres, weighted excess cost per time bin over every channel's local term
    (:func:`local_terms`)): where in time the disagreement sits."""
    terms = local_terms(space, space.raw(model))
    t_end = max(float(space.t[c][-1]) for c in space.channels)
    nb = max(1, int(np.ceil(t_end / bin_s + 1e-9)))
    acc = np.zeros(nb)
    for c, (t, _, z2, noise2) in terms.items():
        k = np.minimum((t / bin_s).astype(int), nb - 1)
        s = np.bincount(k, weights=np.nan_to_num(z2), minlength=nb)
        n = np.bincount(k, weights=np.isfinite(z2).astype(float), minlength=nb)
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = np.where(n > 0, s / np.maximum(n, 1), 0.0)
        acc += space.weight[c] * np.maximum(mean - noise2, 0.0)
    centres = (np.arange(nb) + 0.5) * bin_s
    return centres, acc


__all__ = ["CHANNELS", "UNITS", "FLOORS", "measured_channels", "noise_scale", "ResidualSpace", "build_space",
           "gap_table", "local_terms", "regime_table", "time_profile", "angle_diff"]
