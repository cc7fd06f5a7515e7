"""Yi's kinematics on real-data windows (methods.yi2009.windows): the plugins' window models are the original ones.

The window models that ``Yi2009Ekf.window_models`` offers (rows ``yi2009_s_gamma`` and ``yi2009_s_gamma_gyro``)
were moved from bench/real/benchmark.py; the original classes (commit c1fd38c) are copied below, verbatim, as the
reference: on small synthetic DriveWindows (forward and backward turns, straight and stopped windows, a transitory
one) the moved models must fit the same parameters and predict the same end poses, bit for bit.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import pytest
from scipy.optimize import least_squares

from bench import registry
from bench.kinematics import icr_forward
from bench.real.drive import DRIVE_DT, DriveWindows
from bench.real.windows import MIN_TURN, Pose, VelocityWindowModel, fit_end_poses, tread_speeds, window_twist
from methods.yi2009 import windows as W
from tests.methods.wang2015.original_windows import OriginalSymmetricChi as SymmetricChi  # the original start model

R, B, N = 0.165, 0.55, 40  # Husky-like wheel radius and track [m], samples per window


# ------------------------------------------------------------------------------------------
# the original models (bench/real/benchmark.py at commit c1fd38c), verbatim
# ------------------------------------------------------------------------------------------
def yi_s_points(w: DriveWindows, track: float, min_turn: float = MIN_TURN
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Yi 2009 Sec. V-B data points (gamma, S [m]) per window, from the reference (as Yi does with
    his vision system): S = -v_Gy / psi_dot (eq. (7)) and gamma = (v_Lx - v_Rx)/(v_Lx + v_Rx)
    (eq. (40)) with v_Lx, v_Rx = v_Gx -+ W psi_dot / 2 (eqs. (3)-(4)), i.e. gamma = -W phi / (2 u),
    for the window's constant twist (:func:`window_twist`).  Returns (gamma, S, usable); usable =
    steady, turning at least ``min_turn`` rad, both finite."""
    u, v, phi = window_twist(w)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = -v / phi
        gam = -track * phi / (2.0 * u)
    usable = w.steady & (np.abs(phi) >= min_turn) & np.isfinite(s) & np.isfinite(gam)
    return gam, s, usable


def s_of_gamma(gamma: np.ndarray, a1: float, a2: float, a3: float) -> np.ndarray:
    """Yi eq. (41) S = a1 / (a2 |gamma| + a3), with its limits: S -> 0 for |gamma| -> inf (a2 > 0),
    S = a1/a3 where gamma is undefined (0/0: wheels stopped, where psi_dot = 0 and S is not used)."""
    g = np.abs(np.asarray(gamma, float))
    with np.errstate(invalid="ignore", over="ignore"):
        s = a1 / (a2 * np.where(np.isfinite(g), g, 0.0) + a3)
    s = np.where(np.isinf(g), 0.0 if a2 > 0 else a1 / a3, s)
    return np.where(np.isnan(g), a1 / a3, s)


MIN_S_POINTS_PER_DIRECTION = 10  # S(gamma) points per travel direction needed to fit x_M as well


@dataclass(frozen=True)
class YiSGamma(VelocityWindowModel):
    """Yi 2009 kinematics (Sec. III-A, III-C, V-B) as a window model (Yi's EKF itself cannot run on
    DRIVE data: it needs the roll and pitch gyro rates, absent there; see :data:`YI_MISSING`).

    * Treads: wheel-centre speeds with slip, eq. (6) ``v_ix = (1 - lambda_i) r w_i``, where the slip
      is a common traction slip ``slip`` (lambda_0, both sides) plus the turning slip of eq. (8),
      ``Delta v_Lx = (y_lc - W/2) psi_dot``, ``Delta v_Rx = (y_rc + W/2) psi_dot`` with constant
      lateral tread-ICR positions ``y_l``, ``y_r`` (eq. (9a)).
    * ``yaw_rate="wheels"``: psi_dot and v_Gx from eqs. (3)-(4) closed with those speeds:
      ``psi_dot = (1-lambda_0) r (w_R - w_L) / (y_l - y_r)``, ``v_Gx`` = mean tread speed (eq. (13)
      with x_M = y_M = 0) -- inputs: wheel speeds only.
    * ``yaw_rate="gyro"``: psi_dot is the measured gyro z rate (``imu_gz``; eq. (10e) with roll and
      pitch taken as 0: they are not measured), the turning slips are symmetric (y_l = -y_r, eq. (8)),
      so eq. (13) gives ``v_Gx = (1-lambda_0) r (w_L + w_R)/2`` -- inputs: wheel speeds + gyro.
    * Lateral: eq. (15) ``v_By = (x_M - S) psi_dot`` with S(gamma) of eq. (41), gamma of eq. (40) from
      the model's tread speeds: ``gamma = -W psi_dot / (2 v_Gx)``.  Yi's runs are all forward; the
      ICR's longitudinal offset S is the slip's response to the centripetal load and reverses with the
      direction of travel, so here ``S = sign(v_Gx) S(|gamma|)``.  ``x_M`` (eq. (15): the
      longitudinal position of the measured point, here the ICP frame's origin) is fitted when the
      calibration windows drive both ways (otherwise 0, as for Yi's IMU at the centre).

    Fitting (calibration windows only): S(gamma) as Yi does (Sec. V-B): eq. (41) fitted by nonlinear
    least squares (:func:`methods.yi2009.fit_s_gamma`, a3 held at the published 0.039, only a1/a3
    and a2/a3 being identifiable) to one (gamma, S) point per steady turning window measured on the
    reference (:func:`yi_s_points`); then the slip parameters by least squares on Mandow's J over the
    windows' end poses (like the other models), S(gamma) held.  The sign rule (14) is not imposed:
    it follows from eq. (8) for forward driving when y_l >= W/2 >= -y_r and would be wrong for a
    wheel turning backwards, which the DRIVE steps contain.
    """

    wheel_radius: float
    track: float
    yaw_rate: str = "wheels"
    slip: float = 0.0
    y_l: float = math.nan
    y_r: float = math.nan
    a1: float = 0.02148  # published S(gamma), Sec. V-B (a1 = 2.148 cm)
    a2: float = 0.249
    a3: float = 0.039
    x_m: float = 0.0  # eq. (15) x_M [m]
    min_turn: float = MIN_TURN
    name: str = "yi2009_s_gamma"
    label: str = "Yi S(gamma) (eqs. (6), (8), (13), (15), (40), (41)); wheel speeds"
    fit_cost: float = math.nan
    n_fit: int = 0
    s_fit_rms: float = math.nan

    def __post_init__(self) -> None:
        if self.yaw_rate not in ("wheels", "gyro"):
            raise ValueError(f"YiSGamma.yaw_rate = {self.yaw_rate!r}: 'wheels' or 'gyro'")

    @classmethod
    def gyro(cls, wheel_radius: float, track: float, **kw: Any) -> "YiSGamma":
        return cls(wheel_radius, track, yaw_rate="gyro", name="yi2009_s_gamma_gyro",
                   label="Yi S(gamma) (eqs. (6), (13), (15), (40), (41)); wheel speeds + gyro yaw rate", **kw)

    def _s_fit(self, calib: DriveWindows) -> "YiSGamma":
        from methods.yi2009 import fit_s_gamma

        gam, s, usable = yi_s_points(calib, self.track, self.min_turn)
        if np.unique(np.abs(gam[usable])).size < 2:
            return dataclasses.replace(self, n_fit=int(usable.sum()))  # too few points: published curve kept
        u = window_twist(calib)[0]
        fwd = usable & (u > 0)
        bwd = usable & (u < 0)
        if min(fwd.sum(), bwd.sum()) < MIN_S_POINTS_PER_DIRECTION:  # one direction (Yi's case): x_M = 0
            fit = fit_s_gamma(gam[usable], s[usable] * np.sign(u[usable]), a3=self.a3)  # (41) uses |gamma|
            sg = fit.s_gamma
            return dataclasses.replace(self, a1=sg.a1, a2=sg.a2, a3=sg.a3, x_m=0.0, n_fit=fit.n_points,
                                       s_fit_rms=fit.residual_rms)
        # both directions: the measured -v_By/psi_dot = sign(u) S(|gamma|) - x_M (eq. (15)), a3 held
        g, sg_, sm = np.abs(gam[usable]), np.sign(u[usable]), s[usable]
        start = fit_s_gamma(gam[fwd], s[fwd], a3=self.a3).s_gamma

        def resid(q: np.ndarray) -> np.ndarray:
            return sg_ * q[1] / (q[2] * g + self.a3) - q[0] - sm

        lo, hi = np.array([-5.0, -5.0, 0.0]), np.array([5.0, 5.0, 1e3])
        q0 = np.clip([0.0, start.a1, start.a2], lo + 1e-9, hi - 1e-9)
        sol = least_squares(resid, q0, bounds=(lo, hi))
        r = resid(sol.x)
        return dataclasses.replace(self, x_m=float(sol.x[0]), a1=float(sol.x[1]), a2=float(sol.x[2]),
                                   n_fit=int(usable.sum()), s_fit_rms=float(np.sqrt(np.mean(r * r))))

    def fit(self, calib: DriveWindows) -> "YiSGamma":
        m = self._s_fit(calib)
        if self.yaw_rate == "gyro":
            return fit_end_poses(m, ["slip"], [0.0], ([-0.9], [0.9]), calib)
        chi0 = SymmetricChi(self.wheel_radius, self.track).fit(calib).chi
        half = chi0 * self.track / 2.0
        return fit_end_poses(m, ["slip", "y_l", "y_r"], [0.0, half, -half],
                              ([-0.9, 0.05, -5.0], [0.9, 5.0, -0.05]), calib)

    def velocities(self, w: DriveWindows) -> Pose:
        v_l, v_r = tread_speeds(w, self.wheel_radius)
        k = 1.0 - self.slip
        if self.yaw_rate == "gyro":
            wz = np.asarray(w["imu_gz"], float)
            vx = k * (v_l + v_r) / 2.0
        else:
            vx, _, wz = icr_forward(k * v_l, k * v_r, self.y_l, self.y_r, 0.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            gam = -self.track * wz / (2.0 * vx)
        return vx, (self.x_m - np.sign(vx) * s_of_gamma(gam, self.a1, self.a2, self.a3)) * wz, wz

    def params(self) -> dict[str, float]:
        out = {"lambda_0": self.slip}
        if self.yaw_rate == "wheels":
            out.update({"y_lc": self.y_l, "y_rc": self.y_r, "chi": (self.y_l - self.y_r) / self.track})
        out.update({"a1_cm": 100.0 * self.a1, "a2": self.a2, "a3": self.a3, "S(0)": self.a1 / self.a3, "x_M": self.x_m,
                    "n_S_points": float(self.n_fit), "S_fit_rms": self.s_fit_rms})
        return out


# ------------------------------------------------------------------------------------------
# synthetic windows
# ------------------------------------------------------------------------------------------
def _windows(seed: int) -> DriveWindows:
    """Steady windows of constant wheel speeds, forward and backward turns (>= 10 of each: the x_M branch of the
    S(gamma) fit), two straight and one stopped window, and a transitory one; the ICP reference is a known Yi model's
    prediction from random initial poses plus noise, the gyro z rate that model's yaw rate plus noise."""
    rng = np.random.default_rng(seed)
    n_turn = 40
    sign = np.where(np.arange(n_turn) % 2 == 0, 1.0, -1.0)[:, None]
    wl = np.vstack([np.repeat(rng.uniform(0.5, 6, (n_turn, 1)), N, axis=1) * sign, np.full((2, N), 3.0),
                    np.zeros((1, N)), np.linspace(0.0, 4.0, N)[None, :]])
    wr = np.vstack([np.repeat(rng.uniform(0.5, 6, (n_turn, 1)), N, axis=1) * sign, np.full((2, N), 3.0),
                    np.zeros((1, N)), np.linspace(0.0, 2.0, N)[None, :]])
    n = wl.shape[0]
    steady = np.ones(n, bool)
    steady[-1] = False
    z = np.zeros((n, N))
    w = DriveWindows(
        source="<synthetic>", dt=DRIVE_DT,
        channels={"cmd_wl": wl.copy(), "cmd_wr": wr.copy(), "enc_wl": wl, "enc_wr": wr,
                  "ref_x": z.copy(), "ref_y": z.copy(), "ref_yaw": z.copy(), "imu_gz": z.copy()},
        calib_step=np.arange(n), calib_step_label=np.arange(n), window=np.zeros(n, int), steady=steady,
        transitory=~steady, overlap=np.zeros(n, int), frame_yaw=np.zeros(n), row=np.arange(n),
    )
    truth = YiSGamma(R, B, slip=0.08, y_l=0.62, y_r=-0.58, a1=0.006, a2=0.05, a3=0.039, x_m=0.05)
    ch = dict(w.channels)
    for c, s in (("ref_x", 3.0), ("ref_y", 3.0), ("ref_yaw", np.pi)):
        ch[c] = ch[c].copy()
        ch[c][:, 0] = rng.uniform(-s, s, n)
    w = dataclasses.replace(w, channels=ch)
    x, y, h = truth.predict(w)
    gz = truth.velocities(w)[2]
    noisy = {"ref_x": x + 0.01 * rng.standard_normal(x.shape), "ref_y": y + 0.01 * rng.standard_normal(y.shape),
             "ref_yaw": h + 0.005 * rng.standard_normal(h.shape), "imu_gz": gz + 0.01 * rng.standard_normal(gz.shape)}
    return dataclasses.replace(w, channels={**ch, **noisy})


def _same(a: dict[str, float], b: dict[str, float]) -> bool:
    return a.keys() == b.keys() and all(x == y or (math.isnan(x) and math.isnan(y)) for x, y in
                                        ((a[k], b[k]) for k in a))


@pytest.mark.parametrize("plugin", ["yi2009.ekf_v1", "yi2009.ekf_v2", "yi2009.ekf_v3"])
def test_window_models_fit_and_predict_as_the_original_classes(plugin):
    """Each scheme's plugin offers the two original rows (names, labels, parameters); fitted on the same
    calibration windows they give the original's parameters and, on other windows, its poses, bit for bit."""
    calib, test = _windows(3), _windows(4)
    models = registry.get(plugin).window_models(R, B)
    originals = [YiSGamma(R, B), YiSGamma.gyro(R, B)]
    assert [type(m) for m in models] == [W.YiSGamma, W.YiSGamma]
    assert [(m.name, m.label) for m in models] == [(o.name, o.label) for o in originals]
    assert [m.name for m in models] == ["yi2009_s_gamma", "yi2009_s_gamma_gyro"]
    for m, o in zip(models, originals):
        assert _same(m.params(), o.params())
        fm, fo = m.fit(calib), o.fit(calib)
        assert _same(fm.params(), fo.params()), (m.name, fm.params(), fo.params())
        assert fm.fit_cost == fo.fit_cost and fm.n_fit == fo.n_fit and fm.x_m != 0.0
        for a, b in zip(fm.predict(test), fo.predict(test)):
            assert np.array_equal(a, b, equal_nan=True)
        assert np.isfinite(np.stack(fm.predict(test))).all()


def test_moved_helpers_are_the_original_ones():
    """yi_s_points (eqs. (7), (40) on the window twist) and s_of_gamma (eq. (41) with its limits: S -> 0 at
    |gamma| = inf, S(0) where gamma is 0/0) give the original numbers, NaN and inf included."""
    w = _windows(5)
    for a, b in zip(W.yi_s_points(w, B), yi_s_points(w, B)):
        assert np.array_equal(a, b, equal_nan=True)
    g = np.array([0.0, 0.3, -1.2, np.inf, -np.inf, np.nan])
    for a1, a2, a3 in ((0.02, 0.2, 0.039), (-0.006, 0.0, 0.039)):
        assert np.array_equal(W.s_of_gamma(g, a1, a2, a3), s_of_gamma(g, a1, a2, a3))
    assert W.MIN_S_POINTS_PER_DIRECTION == MIN_S_POINTS_PER_DIRECTION
