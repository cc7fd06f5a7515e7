"""Wang 2015 Sec. 3: the ICR coefficient chi measured per run and its curve chi(curvature ratio),
eqs. (25)-(27), (36), (42)-(45) and Table 3.

chi per run from the encoder travels and the reference rotation angle (eqs. (25), (36), (42) with (15)),
the 40 identification runs (eqs. (26)-(27)), the curve of eq. (44) (:class:`ChiCurve`), its nonlinear
least-squares fit and the published fit of eq. (45); the identification of Section 3 on calibration runs.

Implementation choices (documented, configurable)
    * chi(lambda) is stated for lambda in [0, 10]; beyond, chi is held at chi(10)
      (``curvature_ratio_max``; ``None`` extrapolates the formula, whose limit is 1).
    * chi per run uses the whole run from ``skip_start`` seconds on (default 0: the paper measures
      "the rotation angle change during entire cycle of motion"); the wheel travels are the exact
      integrals of the held encoder speeds between the first and last reference samples used.
      A run turning less than ``min_rotation`` (0.25 rad) gives no chi (straight runs; the paper's
      heading error of 0.018 rad, eq. (41), would dominate) and is skipped by the calibration.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np
from numpy.typing import ArrayLike

from bench import registry
from bench.run import Run, RunError
from methods.baselines import encoder_speeds, held_integral, platform_geometry

CURVATURE_RATIO_MAX = 10.0  # domain of eq. (44)

TABLE_3 = {  # lambda -> (mean chi, std chi), Table 3
    0: (1.4662, 0.0033), 1: (1.4480, 0.0065), 2: (1.4394, 0.0055), 3: (1.4341, 0.0068),
    4: (1.4215, 0.0080), 5: (1.4232, 0.0050), 6: (1.4165, 0.0077), 7: (1.4115, 0.0043),
}


class CalibrationDataError(registry.CalibrationDataError):
    """The calibration runs do not allow the identification of Section 3."""


@dataclass(frozen=True)
class ChiCurve:
    """Eq. (44): chi = 1 + a / (1 + b |curvature_ratio|^(1/2)), a > 0, b > 0 (standard errors from
    the fit when identified)."""

    a: float
    b: float
    a_std: float = float("nan")
    b_std: float = float("nan")
    curvature_ratio_max: float | None = CURVATURE_RATIO_MAX

    def __call__(self, cr: ArrayLike) -> np.ndarray:
        return chi_of_curvature_ratio(cr, self.a, self.b, self.curvature_ratio_max)


PUBLISHED_CURVE = ChiCurve(0.4728, 0.0538)
"""Eq. (45): the fit Wang et al. report for the P3-AT on their lab tiles."""


def chi_of_curvature_ratio(cr: ArrayLike, a: float, b: float, curvature_ratio_max: float | None = CURVATURE_RATIO_MAX
                           ) -> np.ndarray:
    """Eq. (44) with ``|cr|`` held at ``curvature_ratio_max`` beyond the fitted domain (``None``:
    no limit; infinite ``cr`` gives chi = 1)."""
    m = np.abs(np.asarray(cr, float))
    if curvature_ratio_max is not None:
        m = np.minimum(m, curvature_ratio_max)
    with np.errstate(invalid="ignore"):
        return 1.0 + a / (1.0 + b * np.sqrt(m))


def _chi_model(cr: np.ndarray, a: float, b: float) -> np.ndarray:
    return 1.0 + a / (1.0 + b * np.sqrt(np.abs(cr)))


@dataclass(frozen=True)
class RunChi:
    """Eqs. (25), (36), (42), (15) on one run: wheel travels, reference rotation, y0 and chi."""

    run_id: str
    chi: float
    y0: float
    curvature_ratio: float  # (S_l + S_r)/(S_r - S_l), eq. (13) on the travels
    speed: float  # centre speed (S_l + S_r)/(2 T) [m/s]
    tread_speed: float  # (|S_l| + |S_r|)/(2 T) [m/s]
    phi: float  # reference rotation angle [rad], eq. (36)
    s_l: float  # integral of r w_l dt [m]
    s_r: float
    duration: float  # [s]


def chi_per_run(run: Run, skip_start: float = 0.0, min_rotation: float = 0.25) -> RunChi:
    """Eq. (25)/(42): ``y0 = (S_r - S_l)/(2 phi)`` with ``phi`` the reference rotation (eq. (36),
    unwrapped ``ref_yaw`` between its first and last sample used) and the encoder travels
    ``S = integral r w dt`` over the same interval; eq. (15): ``chi = 2 y0 / B = (S_r - S_l)/(phi B)``.

    Raises :class:`RunError` when the run lacks ``ref_yaw`` samples or turns less than
    ``min_rotation`` rad (chi is undefined on a straight run)."""
    track, radius = platform_geometry(run)
    t, wl, wr = encoder_speeds(run)
    if "ref_yaw" not in run.channels:
        raise RunError(run.where, "ref_yaw", None, "chi per run needs the reference sensor's heading")
    tr, yaw = run.samples("ref_yaw")
    m = (tr >= t[0] + skip_start) & (tr <= t[-1])
    if m.sum() < 2:
        raise RunError(run.where, "ref_yaw", f"{int(m.sum())} samples after {skip_start} s within the encoder span",
                       "chi per run needs two reference headings")
    tr, yaw = tr[m], np.unwrap(yaw[m])
    phi = float(yaw[-1] - yaw[0])
    if abs(phi) < min_rotation:
        raise RunError(run.where, "ref_yaw", f"rotation {phi:.4g} rad",
                       f"chi per run needs a turning run (|phi| >= {min_rotation} rad)")
    s_l = float(radius * held_integral(t, wl, tr[0], tr[-1]))
    s_r = float(radius * held_integral(t, wr, tr[0], tr[-1]))
    duration = float(tr[-1] - tr[0])
    y0 = (s_r - s_l) / (2.0 * phi)
    with np.errstate(divide="ignore", invalid="ignore"):
        cr = float(np.divide(s_l + s_r, s_r - s_l))
    return RunChi(run.id, 2.0 * y0 / track, y0, cr, (s_l + s_r) / (2.0 * duration),
                  (abs(s_l) + abs(s_r)) / (2.0 * duration), phi, s_l, s_r, duration)


def fit_chi_curve(curvature_ratio: ArrayLike, chi: ArrayLike, p0: tuple[float, float] = (0.5, 0.05),
                  curvature_ratio_max: float | None = CURVATURE_RATIO_MAX) -> ChiCurve:
    """Nonlinear least squares of eq. (44) (scipy ``curve_fit``, trust-region reflective with the
    paper's constraints a > 0, b > 0).  NaN pairs are dropped; at least two points are needed."""
    from scipy.optimize import curve_fit

    cr, chi = np.asarray(curvature_ratio, float).ravel(), np.asarray(chi, float).ravel()
    if cr.shape != chi.shape:
        raise ValueError(f"curvature_ratio and chi differ in length: {cr.size} vs {chi.size}")
    ok = np.isfinite(cr) & np.isfinite(chi)
    if ok.sum() < 2:
        raise CalibrationDataError(f"eq. (44) needs at least two (curvature_ratio, chi) points, got {int(ok.sum())}")
    popt, pcov = curve_fit(_chi_model, np.abs(cr[ok]), chi[ok], p0=p0, bounds=([0.0, 0.0], [np.inf, np.inf]),
                           method="trf", xtol=1e-15, ftol=1e-15, gtol=1e-15)
    err = np.sqrt(np.clip(np.diag(pcov), 0.0, np.inf)) if np.all(np.isfinite(pcov)) else (np.nan, np.nan)
    return ChiCurve(float(popt[0]), float(popt[1]), float(err[0]), float(err[1]), curvature_ratio_max)


@dataclass(frozen=True)
class PlanEntry:
    curvature_ratio: float
    speed: float  # centre speed v; for curvature_ratio = 0 the tread speed
    v_l: float
    v_r: float


def identification_plan(curvature_ratios: Sequence[float] = tuple(range(8)),
                        speeds: Sequence[float] = (0.1, 0.2, 0.3, 0.4, 0.5)) -> tuple[PlanEntry, ...]:
    """Eqs. (26)-(27): the 8 x 5 = 40 steady-circle runs as tread speeds.  From eq. (13) and
    v = (v_l + v_r)/2: ``v_l = v (1 - 1/lambda)``, ``v_r = v (1 + 1/lambda)``; lambda = 0 is a pure
    rotation with tread speeds -v, +v.  Counter-clockwise, as the equations are written; the reproduction turns its
    grid clockwise, as Wang's experiments (Sec. 3.2, Fig. 9): :func:`methods.wang2015.repro.grid_scenario`."""
    out = []
    for cr in curvature_ratios:
        for v in speeds:
            if cr == 0:
                out.append(PlanEntry(0.0, float(v), -float(v), float(v)))
            else:
                out.append(PlanEntry(float(cr), float(v), float(v * (1 - 1 / cr)), float(v * (1 + 1 / cr))))
    return tuple(out)


@dataclass(frozen=True)
class ChiIdentification:
    """Section 3 on the calibration runs: chi per run, the fitted curve and a Table-3-like summary."""

    runs: tuple[RunChi, ...]
    curve: ChiCurve
    skipped: tuple[tuple[str, str], ...] = ()

    def table(self) -> dict[int, tuple[float, float, int]]:
        """Per rounded |curvature_ratio|: (mean chi, std chi, number of runs), as Table 3."""
        key = np.array([round(abs(r.curvature_ratio)) if np.isfinite(r.curvature_ratio) else -1 for r in self.runs])
        chi = np.array([r.chi for r in self.runs])
        return {int(k): (float(chi[key == k].mean()), float(chi[key == k].std(ddof=1)) if (key == k).sum() > 1
                         else float("nan"), int((key == k).sum())) for k in np.unique(key) if k >= 0}

    def as_dict(self) -> dict[str, Any]:
        return {"a": self.curve.a, "b": self.curve.b, "a_std": self.curve.a_std, "b_std": self.curve.b_std,
                "runs": [dataclasses.asdict(r) for r in self.runs], "skipped": [list(s) for s in self.skipped],
                "table": {str(k): list(v) for k, v in self.table().items()}}


def identify_chi_curve(runs: Sequence[Run], skip_start: float = 0.0, min_rotation: float = 0.25,
                       curvature_ratio_max: float | None = CURVATURE_RATIO_MAX) -> ChiIdentification:
    """chi per run (:func:`chi_per_run`) on every calibration run that turns and has a reference
    heading, then the fit of eq. (44).  Runs that cannot give chi are listed in ``skipped``."""
    got, skipped = [], []
    for r in runs:
        try:
            got.append(chi_per_run(r, skip_start, min_rotation))
        except RunError as exc:
            skipped.append((r.id, str(exc)))
    if len(got) < 2:
        raise CalibrationDataError(f"wang2015: eq. (44) needs chi from at least two turning runs with ref_yaw; "
                                   f"usable {len(got)}, skipped {skipped}")
    curve = fit_chi_curve([g.curvature_ratio for g in got], [g.chi for g in got],
                          curvature_ratio_max=curvature_ratio_max)
    return ChiIdentification(tuple(got), curve, tuple(skipped))
