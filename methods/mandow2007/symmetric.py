"""Mandow 2007 Sec. III: the symmetric model (eq. (8)) from a pure rotation and a straight line, eqs. (11)-(12).

Implementation choice the paper leaves open (documented, configurable): eq. (11) is written without
alpha.  With eq. (3) (the tread ICR is defined on the corrected speed alpha*V), a pure rotation gives
``x_ICR = alpha (S_r - S_l) / (2 phi)``; this consistent form is the default (alpha from eq. (12) first),
``alpha_in_eq11=False`` gives the literal one.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np

from bench.run import Run, RunError
from methods.baselines import encoder_speeds, has_reference, held_integral, platform_geometry, reference_poses
from methods.mandow2007.kinematics import IcrParams
from methods.mandow2007.segments import CalibrationDataError

_ROTATION_KINDS = {"rotation", "pure_rotation", "spin", "turn_in_place"}
_STRAIGHT_KINDS = {"straight", "straight_line", "line"}


def run_kind(run: Run, tol: float = 0.05) -> str:
    """``"rotation"``, ``"straight"`` or ``"other"``: from ``run.meta["scenario_kind"]`` when it names
    one of them, else from the wheel commands (encoders if there are no commands).  A run is a pure rotation when
    ``|w_l + w_r| <= tol (|w_l| + |w_r|)`` and straight when ``|w_l - w_r| <= tol (|w_l| + |w_r|)``
    on 95 % of the samples where the robot is commanded to move."""
    kind = run.meta.get("scenario_kind")
    if kind is None and isinstance(run.meta.get("command"), Mapping):
        kind = run.meta["command"].get("kind")
    if isinstance(kind, str):
        k = kind.lower()
        if k in _ROTATION_KINDS:
            return "rotation"
        if k in _STRAIGHT_KINDS:
            return "straight"
        # other kinds (v_radius, wheel_speeds, ...) may still be a straight line: look at the commands
    chans = ("cmd_wl", "cmd_wr") if run.has("cmd_wl") and run.has("cmd_wr") else ("enc_wl", "enc_wr")
    if not (run.has(chans[0]) and run.has(chans[1])):
        return "other"
    wl, wr = run[chans[0]], run[chans[1]]
    ok = np.isfinite(wl) & np.isfinite(wr)
    mag = np.abs(wl[ok]) + np.abs(wr[ok])
    if mag.size == 0 or mag.max() <= 0:
        return "other"
    moving = mag > 0.2 * mag.max()
    sum_ratio = np.abs(wl[ok] + wr[ok])[moving] / mag[moving]
    diff_ratio = np.abs(wl[ok] - wr[ok])[moving] / mag[moving]
    if np.mean(sum_ratio <= tol) >= 0.95:
        return "rotation"
    if np.mean(diff_ratio <= tol) >= 0.95:
        return "straight"
    return "other"


@dataclass(frozen=True)
class RunTravel:
    """Wheel travel and reference motion of one run between its first and last reference sample."""

    run_id: str
    s_l: float  # integral V_l dt [m] (nominal tread speed)
    s_r: float
    distance: float  # reference displacement |p_end - p_start| [m]
    phi: float  # reference rotation angle (unwrapped) [rad]
    duration: float


def run_travel(run: Run) -> RunTravel:
    """Integrals of eqs. (11)-(12) for one run over the span of its reference samples."""
    _, radius = platform_geometry(run)
    t, wl, wr = encoder_speeds(run)
    tr, x, y, yaw = reference_poses(run)
    m = (tr >= t[0]) & (tr <= t[-1])
    if m.sum() < 2:
        raise RunError(run.where, "ref_yaw", f"{int(m.sum())} samples within the encoder span",
                       "identification needs two reference samples while the encoders run")
    tr, x, y, yaw = tr[m], x[m], y[m], yaw[m]
    s_l = float(radius * held_integral(t, wl, tr[0], tr[-1]))
    s_r = float(radius * held_integral(t, wr, tr[0], tr[-1]))
    return RunTravel(run.id, s_l, s_r, float(np.hypot(x[-1] - x[0], y[-1] - y[0])), float(yaw[-1] - yaw[0]),
                     float(tr[-1] - tr[0]))


@dataclass(frozen=True)
class SymmetricIdentification:
    """Result of eqs. (11)-(12): alpha from straight runs, x_ICR from pure rotations (pooled)."""

    alpha: float
    x_icr: float
    alpha_in_eq11: bool
    straight: tuple[RunTravel, ...]
    rotation: tuple[RunTravel, ...]

    @property
    def params(self) -> IcrParams:
        return IcrParams.symmetric(self.alpha, self.x_icr)

    def as_dict(self) -> dict[str, Any]:
        return {"alpha": self.alpha, "x_icr": self.x_icr, "alpha_in_eq11": self.alpha_in_eq11,
                "straight_runs": [r.run_id for r in self.straight],
                "rotation_runs": [r.run_id for r in self.rotation],
                "straight": [dataclasses.asdict(r) for r in self.straight],
                "rotation": [dataclasses.asdict(r) for r in self.rotation]}


def identify_symmetric(runs: Sequence[Run], alpha_in_eq11: bool = True) -> SymmetricIdentification:
    """Symmetric model of eq. (8) from the runs' pure rotations (eq. (11)) and straight lines
    (eq. (12)); runs are sorted by :func:`run_kind`, others ignored.  Pooled over runs:

        alpha = 2 sum d / sum |S_r + S_l|                                (eq. (12))
        x_ICR = alpha sum |S_r - S_l| / (2 sum |phi|)                    (eq. (11) with eq. (3))

    ``alpha_in_eq11=False`` drops the factor alpha (eq. (11) as printed)."""
    kinds = [(r, run_kind(r)) for r in runs]
    straight = [run_travel(r) for r, k in kinds if k == "straight" and has_reference(r)]
    rotation = [run_travel(r) for r, k in kinds if k == "rotation" and has_reference(r)]
    listing = ", ".join(f"{r.id}={k}" for r, k in kinds) or "(no runs)"
    if not rotation:
        raise CalibrationDataError(f"mandow2007.symmetric: eq. (11) needs a pure-rotation run with reference "
                                   f"poses; calibration runs: {listing}")
    if not straight:
        raise CalibrationDataError(f"mandow2007.symmetric: eq. (12) needs a straight-line run with reference "
                                   f"poses; calibration runs: {listing}")
    wheel = sum(abs(s.s_r + s.s_l) for s in straight)
    turn = sum(abs(s.phi) for s in rotation)
    if wheel <= 0 or turn <= 0:
        raise CalibrationDataError(f"mandow2007.symmetric: degenerate experiments (wheel travel {wheel} m, "
                                   f"rotation {turn} rad); calibration runs: {listing}")
    alpha = 2.0 * sum(s.distance for s in straight) / wheel
    x_icr = sum(abs(s.s_r - s.s_l) for s in rotation) / (2.0 * turn)
    if alpha_in_eq11:
        x_icr *= alpha
    return SymmetricIdentification(alpha, x_icr, alpha_in_eq11, tuple(straight), tuple(rotation))
