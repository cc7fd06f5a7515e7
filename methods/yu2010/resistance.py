"""Terrain resistance C(q, q_dot) of Yu 2010 eqs. (7)-(22), vectorised over operating points.

Frames.  Internally this module uses Yu's local frame (Sec. II, Fig. 1): origin at the CG,
``x`` *lateral* (positive to the right, towards the right wheels), ``y`` *longitudinal* (forward),
z up, yaw rate ``phidot`` counter-clockwise.  A body twist is (u_x, u_y, phidot) in that frame;
skidbench's body frame (x forward, y left) has vx = u_y, vy = -u_x, wz = phidot.  Public
functions take and return wheel speeds and torques only (left/right, rad/s, N m), so no frame leaks.

Model (per side, both wheels of a side share one speed ``omega``):

* A tread element enters the contact patch at its leading edge y_e (y_e = L/2 and -C/2 for the
  front and rear patch when omega > 0; C/2 and -L/2 when omega < 0), moves back at r*omega
  relative to the body and stays for t = (y_e - y)/(r omega), eq. (8).
* Its sliding velocity is v_s = (u_x - phidot*y, u_y + phidot*x - r*omega), eq. (9).
* Its shear displacement j is the chord between its ground contact point and its current
  position, eqs. (12)-(13) (front) and (15)-(16) (rear), written here for a general twist with
  theta = phidot*t and the stable kernels sin(theta)/theta, (1-cos theta)/theta, so that straight
  motion (R -> infinity) needs no special case.  For the paper's kinematics (u_x = 0,
  u_y = R*phidot) it reduces exactly to (12)-(16).  Elements that would stay in contact while
  the body turns more than half a revolution (|theta| > pi, only near omega = 0) are clamped at
  |theta| = pi: the chord formula would otherwise fold back although the element has slid far
  (fully sheared); the contact time is also capped where the element would have slid 10 m
  (>> K), which only matters for a (nearly) locked wheel.  A locked wheel (omega = 0) therefore
  carries fully developed friction.
* Shear stress tau_ss = p mu (1 - exp(-j/K)), eq. (7), opposing v_s (eq. (10)); its longitudinal
  part integrated over the two patches gives F_f, eqs. (17)/(20); Gauss-Legendre quadrature on
  each patch rectangle (``n_quad_y`` x ``n_quad_x`` nodes), all points and nodes as one array.
* Resistance torque tau_Res = r (F_f + f_r), eqs. (18)/(21); rolling resistance of a side
  f_r = mu_roll * (m g cos(beta) / 2) * sign(omega) (Sec. V-A: mu_roll is the rolling resistance
  over the weight, shared equally by the two sides); C = [tau_lRes, tau_rRes], eq. (22).
* Uniform pressure p = m g cos(beta) / (2 (L - C) b) (Wang 2015 after eq. (21)).
* mu: mu_sa when the motor drives the wheel (torque and speed of the same sign), mu_op when it
  brakes (Sec. V-A).  In steady state the motor torque *is* tau_Res, so the choice is made
  self-consistently: mu_sa if r(mu_sa F' + f_r) >= 0, else mu_op if r(mu_op F' + f_r) < 0, where
  F' = F_f sign(omega); in the narrow band where neither is consistent the torque is zero (the
  switch point).  This is continuous in F_f.  A stationary wheel (omega = 0) is "not the same
  sign", hence mu_op, and has no rolling resistance.

Scale invariance: t ~ 1/|q_dot| and v_s ~ |q_dot|, so j, the stress direction and C depend only on
the direction of q_dot = (w_l, w_r), i.e. on psi = atan2(w_r, w_l) (the commanded radius), not on
the speed; this is the speed independence Yu reports for 0.1-0.6 m/s (Sec. V-A).  The
:class:`ResistanceTable` exploits it: an exact one-dimensional table over psi.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from methods.yu2010.params import YuParams

_CAP_LENGTH = 10.0  # [m] slid distance beyond which an element is certainly fully sheared (>> K)
_CHUNK = 2048


# --------------------------------------------------------------------------------------------
# quadrature nodes of one side's two patches
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class PatchNodes:
    """Gauss-Legendre nodes of the front and rear patch of one side (offsets from the wheel centre
    line in x, absolute y), their weights (area elements, sum = (L - C) b), and the leading edge
    y_e of each node for forward (omega >= 0) and backward rotation."""

    x: np.ndarray
    y: np.ndarray
    w: np.ndarray
    ye_fwd: np.ndarray
    ye_bwd: np.ndarray

    @classmethod
    def build(cls, L: float, C: float, b: float, ny: int, nx: int) -> "PatchNodes":
        gy, wy = np.polynomial.legendre.leggauss(int(ny))
        gx, wx = np.polynomial.legendre.leggauss(int(nx))
        half_len = (L - C) / 4.0  # half length of one patch
        mid = (L + C) / 4.0  # centre of the front patch
        xs = gx * b / 2.0
        ys_front = mid + gy * half_len
        w2 = np.outer(wy * half_len, wx * b / 2.0)  # (ny, nx)
        Y, X = np.meshgrid(np.concatenate([ys_front, -ys_front]), xs, indexing="ij")
        W = np.concatenate([w2, w2], axis=0)
        front = Y > 0
        ye_fwd = np.where(front, L / 2.0, -C / 2.0)
        ye_bwd = np.where(front, C / 2.0, -L / 2.0)
        return cls(X.ravel(), Y.ravel(), W.ravel(), ye_fwd.ravel(), ye_bwd.ravel())


def patch_nodes(params: YuParams, ny: int | None = None, nx: int | None = None) -> PatchNodes:
    return PatchNodes.build(params.L, params.C, params.b, ny or params.n_quad_y, nx or params.n_quad_x)


# --------------------------------------------------------------------------------------------
# one side: shear displacement and friction forces for a general body twist
# --------------------------------------------------------------------------------------------
def _sinc_kernels(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """sin(theta)/theta and (1 - cos theta)/theta, stable at theta = 0."""
    s = np.sinc(theta / np.pi)
    h = np.sinc(theta / (2.0 * np.pi))
    return s, 0.5 * theta * h * h


def shear_displacement(omega: ArrayLike, u_x: ArrayLike, u_y: ArrayLike, phidot: ArrayLike, x: ArrayLike,
                       y: ArrayLike, y_e: ArrayLike, r: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Shear displacement (j_X, j_Y) of the tread element now at body point (x, y) that entered the
    patch at (x, y_e), eqs. (8), (12)-(13), (15)-(16), for the body twist (u_x, u_y, phidot) in
    Yu's frame (x lateral right, y forward).  All arguments broadcast.  Returns (j_X, j_Y, t) with
    t the (clamped) contact time."""
    omega, u_x, u_y, phidot = (np.asarray(a, float) for a in (omega, u_x, u_y, phidot))
    x, y, y_e = (np.asarray(a, float) for a in (x, y, y_e))
    rw = r * omega
    dist = np.abs(y_e - y)
    speed = np.hypot(u_x, u_y) + np.abs(rw) + np.abs(phidot) * 1.0  # a degree-1 speed scale
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(rw != 0.0, dist / np.abs(rw), np.inf)  # eq. (8)
        t_half_turn = np.where(phidot != 0.0, np.pi / np.abs(phidot), np.inf)
        t_cap = np.where(speed > 0.0, _CAP_LENGTH / speed, 0.0)
    t = np.minimum(np.minimum(t, t_half_turn), t_cap)
    theta = phidot * t
    s, cc = _sinc_kernels(theta)
    sn, cs = np.sin(theta), np.cos(theta)
    jx = x * (cs - 1.0) - y_e * sn + t * (s * u_x - cc * u_y) + rw * t * sn
    jy = x * sn + y_e * (cs - 1.0) + t * (s * u_y + cc * u_x) - rw * t * cs
    return jx, jy, t


def side_unit_forces(omega: ArrayLike, u_x: ArrayLike, u_y: ArrayLike, phidot: ArrayLike, x_w: float,
                     params: YuParams, K: float | None = None, nodes: PatchNodes | None = None,
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Friction of one side's two patches for unit friction coefficient (mu = 1) on flat ground.

    ``x_w`` is the lateral position of the side's wheel centre line in Yu's frame (+B/2 right,
    -B/2 left).  Returns (F_long, F_lat, M_z): the ground force on the tires along y (forward) and x
    (right) [N] and its yaw moment about the CG [N m], eqs. (17)/(20) (and Wang 2015 (18)-(21) for
    the lateral part).  F_long > 0 means the ground pushes the side forward (the motor must drive).
    Vectorised over the shapes of omega, u_x, u_y, phidot (broadcast together)."""
    K = params.K if K is None else K
    nd = nodes or patch_nodes(params)
    omega, u_x, u_y, phidot = np.broadcast_arrays(*(np.asarray(a, float) for a in (omega, u_x, u_y, phidot)))
    shape = omega.shape
    om, ux, uy, ph = (a.reshape(-1) for a in (omega, u_x, u_y, phidot))
    out = np.empty((3, om.size))
    x = x_w + nd.x
    p = params.pressure
    for a in range(0, om.size, _CHUNK):
        sl = slice(a, a + _CHUNK)
        o, vx_, vy_, w_ = om[sl, None], ux[sl, None], uy[sl, None], ph[sl, None]
        ye = np.where(o >= 0.0, nd.ye_fwd, nd.ye_bwd)
        jx, jy, _ = shear_displacement(o, vx_, vy_, w_, x, nd.y, ye, params.r)
        stress = -np.expm1(-np.hypot(jx, jy) / K)  # eq. (7) / (p mu)
        vsx = vx_ - w_ * nd.y  # eq. (9)
        vsy = vy_ + w_ * x - params.r * o
        vs = np.hypot(vsx, vsy)
        with np.errstate(divide="ignore", invalid="ignore"):
            k = np.where(vs > 0.0, stress / vs, 0.0) * nd.w  # direction opposite to v_s, eq. (10)
        fy = -(k * vsy).sum(axis=1)
        fx = -(k * vsx).sum(axis=1)
        mz = -(k * (x * vsy - nd.y * vsx)).sum(axis=1)
        out[0, sl], out[1, sl], out[2, sl] = fy * p, fx * p, mz * p
    return out[0].reshape(shape), out[1].reshape(shape), out[2].reshape(shape)


# --------------------------------------------------------------------------------------------
# mu choice (Sec. V-A) and the resistance C(q, q_dot), eq. (22)
# --------------------------------------------------------------------------------------------
def rolling_force(params: YuParams, slope: float = 0.0) -> float:
    """Rolling resistance magnitude of one side, mu_roll m g cos(beta) / 2 [N]."""
    return params.mu_roll * params.m * params.g * math.cos(slope) / 2.0


def mu_consistent(F_long: np.ndarray, omega: np.ndarray, f_r: float, mu_sa: float, mu_op: float) -> np.ndarray:
    """Effective friction coefficient chosen self-consistently with the sign of the steady motor
    torque r (mu F_long + f_r sign(omega)) (see module docstring).  Returns mu per point."""
    sig = np.sign(omega)
    Fp = F_long * sig
    a = mu_sa * Fp + f_r
    b = mu_op * Fp + f_r
    with np.errstate(divide="ignore", invalid="ignore"):
        gap = np.where(Fp != 0.0, -f_r / Fp, mu_op)
    mu = np.where(a >= 0.0, mu_sa, np.where(b < 0.0, mu_op, gap))
    return np.where(sig == 0.0, mu_op, mu)


def side_torque(F_long: np.ndarray, omega: np.ndarray, params: YuParams, slope: float = 0.0,
                mu_sa: float | None = None, mu_op: float | None = None) -> np.ndarray:
    """tau_Res = r (mu F_f + f_r sign(omega)), eqs. (18)/(21), with ``F_long`` the unit-mu force on
    flat ground (scaled here by cos(beta)) and mu from :func:`mu_consistent`."""
    mu_sa = params.mu_sa if mu_sa is None else mu_sa
    mu_op = params.mu_op if mu_op is None else mu_op
    cb = math.cos(slope)
    f_r = rolling_force(params, slope)
    F = np.asarray(F_long, float) * cb
    mu = mu_consistent(F, np.asarray(omega, float), f_r, mu_sa, mu_op)
    return params.r * (mu * F + f_r * np.sign(omega))


def yu_twist(wl: ArrayLike, wr: ArrayLike, params: YuParams, alpha: float | None = None
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Body twist of the kinematic model eq. (1) in Yu's frame: (u_x, u_y, phidot) =
    (0, r (w_l + w_r)/2, r (w_r - w_l)/(alpha B))."""
    alpha = params.alpha if alpha is None else alpha
    wl, wr = np.asarray(wl, float), np.asarray(wr, float)
    return np.zeros(np.broadcast(wl, wr).shape), params.r * (wl + wr) / 2.0, params.r * (wr - wl) / (alpha * params.B)


def unit_long_forces(wl: ArrayLike, wr: ArrayLike, params: YuParams, K: float | None = None,
                     nodes: PatchNodes | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Longitudinal friction F_f of the left and right side for mu = 1, flat ground, eqs.
    (17)/(20), at wheel speeds (w_l, w_r) with the kinematics of eq. (1)."""
    wl, wr = np.broadcast_arrays(np.asarray(wl, float), np.asarray(wr, float))
    ux, uy, ph = yu_twist(wl, wr, params)
    nd = nodes or patch_nodes(params)
    Fl = side_unit_forces(wl, ux, uy, ph, -params.B / 2.0, params, K, nd)[0]
    Fr = side_unit_forces(wr, ux, uy, ph, params.B / 2.0, params, K, nd)[0]
    return Fl, Fr


def resistance(wl: ArrayLike, wr: ArrayLike, params: YuParams, slope: float = 0.0, K: float | None = None,
               mu_sa: float | None = None, mu_op: float | None = None, nodes: PatchNodes | None = None,
               ) -> tuple[np.ndarray, np.ndarray]:
    """Steady-state resistance C(q, q_dot) = [tau_lRes, tau_rRes] of eq. (22) [N m] for arrays of
    wheel speeds (w_l, w_r) [rad/s] (direct quadrature, vectorised over all operating points)."""
    wl, wr = np.broadcast_arrays(np.asarray(wl, float), np.asarray(wr, float))
    Fl, Fr = unit_long_forces(wl, wr, params, K, nodes)
    return (side_torque(Fl, wl, params, slope, mu_sa, mu_op),
            side_torque(Fr, wr, params, slope, mu_sa, mu_op))


# --------------------------------------------------------------------------------------------
# lookup table over the direction of q_dot (exact by scale invariance)
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ResistanceTable:
    """C(q_dot) tabulated over psi = atan2(w_r, w_l) on a uniform periodic grid (flat ground).

    ``tau_l``/``tau_r``: resistance torques with the consistent mu rule; ``F_l``/``F_r``: unit-mu
    longitudinal forces (for the literal 'motor' mu rule).  Lists are kept alongside the arrays
    because indexing a Python list is what the 1 kHz loop does fastest."""

    psi: np.ndarray
    tau_l: np.ndarray
    tau_r: np.ndarray
    F_l: np.ndarray
    F_r: np.ndarray

    @classmethod
    def build(cls, params: YuParams, n: int | None = None) -> "ResistanceTable":
        """Tabulate on ``n`` (rounded up to a multiple of 4) intervals over [-pi, pi].  Only the
        right side is integrated: by the vehicle's left-right mirror symmetry
        tau_l(w_l, w_r) = tau_r(w_r, w_l), i.e. tau_l(psi) = tau_r(pi/2 - psi), which on this grid
        is an index permutation (exact up to rounding)."""
        n = int(n or params.n_table)
        n += (-n) % 4
        k = np.arange(n + 1)
        psi = -np.pi + k * (2.0 * np.pi / n)
        wl, wr = np.cos(psi), np.sin(psi)
        wl[np.abs(wl) < 1e-12] = 0.0
        wr[np.abs(wr) < 1e-12] = 0.0
        ux, uy, ph = yu_twist(wl, wr, params)
        Fr = side_unit_forces(wr, ux, uy, ph, params.B / 2.0, params)[0]
        mirror = (n // 4 - k) % n  # psi' = pi/2 - psi (mod 2 pi)
        Fl = Fr[mirror]
        return cls(psi, side_torque(Fl, wl, params), side_torque(Fr, wr, params), Fl, Fr)

    @property
    def dpsi(self) -> float:
        return float(self.psi[1] - self.psi[0])

    def __call__(self, wl: ArrayLike, wr: ArrayLike, slope: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """Interpolated C at wheel speeds (w_l, w_r) (arrays), on a slope beta (scales by cos beta)."""
        wl, wr = np.broadcast_arrays(np.asarray(wl, float), np.asarray(wr, float))
        psi = np.arctan2(wr, wl)
        cb = math.cos(slope)
        return cb * np.interp(psi, self.psi, self.tau_l), cb * np.interp(psi, self.psi, self.tau_r)

    def as_lists(self) -> dict[str, Any]:
        return {"tau_l": self.tau_l.tolist(), "tau_r": self.tau_r.tolist(), "F_l": self.F_l.tolist(),
                "F_r": self.F_r.tolist(), "psi0": float(self.psi[0]), "inv_dpsi": 1.0 / self.dpsi,
                "n": int(self.psi.size - 1)}
