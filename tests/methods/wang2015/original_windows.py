"""Test data for the real-data window models: the models as bench/real/benchmark.py defined them before they
moved into the paper packages (git c1fd38c, copied verbatim, only renamed ``Original*``), and synthetic
DriveWindows built as tests/test_real.py builds them.

The window tests of tests/methods/wang2015/test_windows.py and tests/methods/mandow2007/test_windows.py compare
the plugins' window models (``window_models``) with these copies: same end poses, same fitted parameters.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from bench.kinematics import curvature_ratio, icr_forward
from bench.real.drive import DRIVE_DT, DriveWindows
from bench.real.windows import MIN_TURN, Pose, VelocityWindowModel, fit_end_poses, tread_speeds, window_chi

R, B = 0.165, 0.55  # the Husky's wheel radius and track [m] (tests/test_real.py)
N = 40  # samples per window (DRIVE: 2 s at 20 Hz)
WANG_P3AT = (0.4728, 0.0538)  # Wang 2015 eq. (45): (a, b) for the Pioneer P3-AT on tile


def make_windows(wl: np.ndarray, wr: np.ndarray, steady: np.ndarray | None = None) -> DriveWindows:
    """Windows with the given wheel speeds [rad/s] (n_windows, n_samples), ICP poses zero."""
    n, m = wl.shape
    z = np.zeros((n, m))
    steady = np.ones(n, bool) if steady is None else steady
    return DriveWindows(
        source="<synthetic>", dt=DRIVE_DT,
        channels={"cmd_wl": wl.copy(), "cmd_wr": wr.copy(), "enc_wl": wl, "enc_wr": wr,
                  "ref_x": z.copy(), "ref_y": z.copy(), "ref_yaw": z.copy()},
        calib_step=np.arange(n), calib_step_label=np.arange(n),
        window=np.zeros(n, int), steady=steady, transitory=~steady, overlap=np.zeros(n, int),
        frame_yaw=np.zeros(n), row=np.arange(n),
    )


def with_reference(w: DriveWindows, model, rng: np.random.Generator, noise: float = 0.0) -> DriveWindows:
    """Windows whose ICP reference is ``model``'s own prediction from random initial poses, plus Gaussian
    ``noise`` [m, rad] on every sample after the first."""
    ch = dict(w.channels)
    for c, s in (("ref_x", 3.0), ("ref_y", 3.0), ("ref_yaw", np.pi)):
        ch[c] = ch[c].copy()
        ch[c][:, 0] = rng.uniform(-s, s, w.n_windows)
    w = dataclasses.replace(w, channels=ch)
    x, y, h = model.predict(w)
    if noise:
        for a in (x, y, h):
            a[:, 1:] += rng.normal(0.0, noise, a[:, 1:].shape)
    return dataclasses.replace(w, channels={**ch, "ref_x": x, "ref_y": y, "ref_yaw": h})


def drive_speeds(rng: np.random.Generator, n: int, steady: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Wheel speeds of ``n`` windows [rad/s]: a random level per side, with sample noise unless ``steady``;
    window 0 drives straight (w_l = w_r), window 1 stands still (both zero)."""
    wl = np.repeat(rng.uniform(-6, 6, (n, 1)), N, axis=1)
    wr = np.repeat(rng.uniform(-6, 6, (n, 1)), N, axis=1)
    if not steady:
        wl, wr = wl + rng.normal(0, 0.3, (n, N)), wr + rng.normal(0, 0.3, (n, N))
    wr[0] = wl[0]
    wl[1] = wr[1] = 0.0
    return wl, wr


def same_poses(a: Pose, b: Pose) -> bool:
    """Bit-identical predictions (NaN where both are NaN)."""
    return all(np.array_equal(p, q, equal_nan=True) for p, q in zip(a, b, strict=True))


# ------------------------------------------------------------------------------------------
# the original window models (bench/real/benchmark.py at c1fd38c)
# ------------------------------------------------------------------------------------------
def wang_chi(lam: np.ndarray, a: float, b: float) -> np.ndarray:
    """Wang 2015 eq. (44): chi = 1 + a / (1 + b sqrt|curvature_ratio|); 1 on a straight line
    (|ratio| = inf); 1 + a when undefined (both treads stopped, where wz = 0 anyway)."""
    lam = np.asarray(lam, float)
    with np.errstate(invalid="ignore", over="ignore"):
        out = 1.0 + a / (1.0 + b * np.sqrt(np.abs(lam)))
    return np.where(np.isnan(lam), 1.0 + a, out)




@dataclass(frozen=True)
class OriginalSymmetricChi(VelocityWindowModel):
    """Symmetric ICR model with constant chi (Wang eqs. (11), (15)); chi fitted on end poses."""

    wheel_radius: float
    track: float
    chi: float = 1.0
    name: str = "icr_sym_chi"
    label: str = "symmetric ICR, constant chi (end-pose LSQ)"
    fit_cost: float = math.nan

    def fit(self, calib: DriveWindows) -> "OriginalSymmetricChi":
        return fit_end_poses(self, ["chi"], [1.5], ([0.5], [10.0]), calib)

    def velocities(self, w: DriveWindows) -> Pose:
        half = self.chi * self.track / 2.0
        return icr_forward(*tread_speeds(w, self.wheel_radius), half, -half, 0.0)

    def params(self) -> dict[str, float]:
        return {"chi": self.chi}


@dataclass(frozen=True)
class OriginalAsymmetricICR(VelocityWindowModel):
    """Mandow 2007 eqs. (6)-(7) in skidbench axes (module docstring); fitted on end poses."""

    wheel_radius: float
    track: float
    y_l: float = math.nan
    y_r: float = math.nan
    x_icr: float = 0.0
    alpha_l: float = 1.0
    alpha_r: float = 1.0
    name: str = "mandow2007_icr"
    label: str = "asymmetric ICR (Mandow: y_l, y_r, x_icr, alpha_l, alpha_r)"
    fit_cost: float = math.nan

    def fit(self, calib: DriveWindows) -> "OriginalAsymmetricICR":
        # start from the symmetric fit (a GA-free, deterministic start for Mandow's search)
        chi0 = OriginalSymmetricChi(self.wheel_radius, self.track).fit(calib).chi
        half = chi0 * self.track / 2.0
        names = ["y_l", "y_r", "x_icr", "alpha_l", "alpha_r"]
        lo = [0.05, -5.0, -2.0, 0.3, 0.3]
        hi = [5.0, -0.05, 2.0, 3.0, 3.0]
        return fit_end_poses(self, names, [half, -half, 0.0, 1.0, 1.0], (lo, hi), calib)

    def velocities(self, w: DriveWindows) -> Pose:
        v_l, v_r = tread_speeds(w, self.wheel_radius)
        return icr_forward(self.alpha_l * v_l, self.alpha_r * v_r, self.y_l, self.y_r, self.x_icr)

    def params(self) -> dict[str, float]:
        return {"y_l": self.y_l, "y_r": self.y_r, "x_icr": self.x_icr, "alpha_l": self.alpha_l,
                "alpha_r": self.alpha_r, "chi": (self.y_l - self.y_r) / self.track}


@dataclass(frozen=True)
class OriginalWangChiCurve(VelocityWindowModel):
    """Wang 2015 eq. (44) chi(curvature ratio) in the symmetric model (eq. (47), corrected)."""

    wheel_radius: float
    track: float
    a: float = WANG_P3AT[0]
    b: float = WANG_P3AT[1]
    min_turn: float = MIN_TURN
    name: str = "wang2015_chi_curve"
    label: str = "chi(curvature ratio), Wang eq. (44) fitted to measured chi"
    fit_cost: float = math.nan
    n_fit: int = 0

    def fit(self, calib: DriveWindows) -> "OriginalWangChiCurve":
        chi, lam, _, usable = window_chi(calib, self.wheel_radius, self.track, self.min_turn)
        chi, lam = chi[usable], lam[usable]
        if chi.size < 2:
            return dataclasses.replace(self, n_fit=int(chi.size))
        sol = least_squares(lambda p: wang_chi(lam, p[0], p[1]) - chi, np.array(WANG_P3AT),
                            bounds=([0.0, 0.0], [np.inf, np.inf]), method="trf")
        return dataclasses.replace(self, a=float(sol.x[0]), b=float(sol.x[1]),
                                   fit_cost=float(2 * sol.cost / chi.size), n_fit=int(chi.size))

    def velocities(self, w: DriveWindows) -> Pose:
        v_l, v_r = tread_speeds(w, self.wheel_radius)
        with np.errstate(divide="ignore", invalid="ignore"):
            lam = curvature_ratio(v_l, v_r)
        half = wang_chi(lam, self.a, self.b) * self.track / 2.0
        return icr_forward(v_l, v_r, half, -half, 0.0)

    def params(self) -> dict[str, float]:
        return {"a": self.a, "b": self.b, "chi(0)": 1.0 + self.a}
