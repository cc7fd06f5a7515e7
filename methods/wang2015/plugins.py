"""Wang 2015: the method plugins, the default P3-AT model with constant chi (eq. (46)) and the proposed
model with chi(curvature ratio) (eq. (47)).

``wang2015.chi_lambda`` (:class:`ChiLambda`) and ``wang2015.constant_chi`` (:class:`ConstantChi`).  Both also
offer the real-data benchmark's window models (:meth:`ChiLambda.window_models`,
:meth:`ConstantChi.window_models`, :mod:`methods.wang2015.windows`).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Sequence

from bench.registry import Estimate
from bench.run import Run
from bench import registry
from methods.wang2015.chi import CURVATURE_RATIO_MAX, ChiCurve, ChiIdentification, identify_chi_curve
from methods.wang2015.kinematics import CHI_P3AT_DEFAULT, _estimate

if TYPE_CHECKING:
    from bench.real.windows import WindowModel

PAPER = "Wang et al. 2015"


class NotCalibratedError(registry.NotCalibratedError):
    """``wang2015.chi_lambda`` was asked to estimate before its (a, b) were identified."""


@dataclass(frozen=True)
class ChiLambda:
    """``wang2015.chi_lambda``: eq. (47), chi from the curvature ratio through eq. (44) with (a, b)
    identified on the calibration runs (Section 3).  ``ChiLambda(curve=PUBLISHED_CURVE)`` uses the
    published eq. (45) instead."""

    name: str = "wang2015.chi_lambda"
    paper: str = PAPER
    requires: frozenset[str] = frozenset({"enc_wl", "enc_wr"})
    curve: ChiCurve | None = None
    literal_eq46: bool = False
    skip_start: float = 0.0
    min_rotation: float = 0.25
    identification: ChiIdentification | None = field(default=None, compare=False, repr=False)

    def calibrate(self, runs: Sequence[Run]) -> "ChiLambda":
        cmax = self.curve.curvature_ratio_max if self.curve is not None else CURVATURE_RATIO_MAX
        ident = identify_chi_curve(runs, self.skip_start, self.min_rotation, cmax)
        return dataclasses.replace(self, curve=ident.curve, identification=ident)

    def estimate(self, run: Run) -> Estimate:
        if self.curve is None:
            raise NotCalibratedError(f"{self.name}: chi(curvature_ratio) not identified; call calibrate(runs) "
                                     "first or construct it with curve=PUBLISHED_CURVE")
        info: dict[str, Any] = {"a": self.curve.a, "b": self.curve.b,
                                "curvature_ratio_max": self.curve.curvature_ratio_max}
        if self.identification is not None:
            info["identification"] = self.identification.as_dict()
        return _estimate(self.name, run, self.curve, self.literal_eq46, info)

    def window_models(self, wheel_radius: float, track: float) -> list[WindowModel]:
        """The real-data benchmark's row ``wang2015_chi_curve``: eq. (44) in the symmetric model, (a, b) fitted
        to chi measured per steady calibration window (:class:`methods.wang2015.windows.WangChiCurve`; imported
        here: the window path needs scipy and :mod:`bench.real`, which the plugin's own path does not)."""
        from methods.wang2015.windows import WangChiCurve

        return [WangChiCurve(wheel_radius, track)]


@dataclass(frozen=True)
class ConstantChi:
    """``wang2015.constant_chi``: eq. (46), the default P3-AT symmetric model with chi = 1.5.
    Nothing to calibrate."""

    name: str = "wang2015.constant_chi"
    paper: str = PAPER
    requires: frozenset[str] = frozenset({"enc_wl", "enc_wr"})
    chi: float = CHI_P3AT_DEFAULT
    literal_eq46: bool = False

    def calibrate(self, runs: Sequence[Run]) -> "ConstantChi":
        return dataclasses.replace(self)

    def estimate(self, run: Run) -> Estimate:
        return _estimate(self.name, run, lambda cr: self.chi, self.literal_eq46, {"chi": self.chi})

    def window_models(self, wheel_radius: float, track: float) -> list[WindowModel]:
        """The real-data benchmark's row ``icr_sym_chi``: the symmetric model with a constant chi, here fitted on
        the calibration windows' end poses from eq. (46)'s 1.5 (:class:`methods.wang2015.windows.SymmetricChi`;
        imported here: the window path needs scipy and :mod:`bench.real`)."""
        from methods.wang2015.windows import SymmetricChi

        return [SymmetricChi(wheel_radius, track)]
