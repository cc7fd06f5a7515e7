"""Mandow 2007: the method plugins (the P3-AT default, the symmetric model of eqs. (11)-(12), and the
asymmetric model of eq. (7) identified by the GA of Sec. III or by differential evolution).

``mandow2007.default_p3at`` (:class:`DefaultP3at`), ``mandow2007.symmetric`` (:class:`Symmetric`),
``mandow2007.asymmetric_ga`` (:class:`AsymmetricGa`), ``mandow2007.asymmetric_de`` (:class:`AsymmetricDe`).
The asymmetric plugins also offer the real-data benchmark's window model (:meth:`AsymmetricGa.window_models`,
:mod:`methods.mandow2007.windows`).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Sequence

from bench.registry import Estimate
from bench.run import Run
from bench import registry
from methods.mandow2007.ga import DeSettings, GaSettings, GeneRanges, Identification, identify_de, identify_ga
from methods.mandow2007.kinematics import IcrParams, dead_reckoning
from methods.mandow2007.p3at import P3AT_DEFAULT
from methods.mandow2007.segments import build_segments
from methods.mandow2007.symmetric import SymmetricIdentification, identify_symmetric

if TYPE_CHECKING:
    from bench.real.windows import WindowModel

PAPER = "Mandow et al. 2007"


class NotCalibratedError(registry.NotCalibratedError):
    """A plugin that needs identified parameters was asked to estimate before calibration."""


def _require_params(method: Any) -> IcrParams:
    if method.params is None:
        raise NotCalibratedError(f"{method.name}: no kinematic parameters; call calibrate(runs) first "
                                 "or construct it with params=IcrParams(...)")
    return method.params


def _window_models(wheel_radius: float, track: float) -> list[WindowModel]:
    """Eq. (7) on DRIVE windows: :class:`methods.mandow2007.windows.AsymmetricICR`, K fitted on the windows'
    end poses by least squares on J (eq. (13)) instead of the GA or DE (imported here: the window path needs
    scipy and :mod:`bench.real`, which the plugins' own path does not)."""
    from methods.mandow2007.windows import AsymmetricICR

    return [AsymmetricICR(wheel_radius, track)]


def _ident_info(method: Any) -> dict[str, Any]:
    info: dict[str, Any] = {}
    if method.identification is not None:
        info["identification"] = method.identification.as_dict()
    if method.cross_identification is not None:
        info["cross_check"] = method.cross_identification.as_dict()
    return info


@dataclass(frozen=True)
class DefaultP3at:
    """``mandow2007.default_p3at``: the P3-AT server's symmetric model, alpha = 1, x_ICR = 0.3 m
    (Sec. IV-B).  Nothing to calibrate."""

    name: str = "mandow2007.default_p3at"
    paper: str = PAPER
    requires: frozenset[str] = frozenset({"enc_wl", "enc_wr"})
    params: IcrParams = P3AT_DEFAULT

    def calibrate(self, runs: Sequence[Run]) -> "DefaultP3at":
        return dataclasses.replace(self)

    def estimate(self, run: Run) -> Estimate:
        return dead_reckoning(self.params, run, self.name, {"model": "P3-AT default (alpha=1, x_ICR=0.3 m)"})


@dataclass(frozen=True)
class Symmetric:
    """``mandow2007.symmetric``: eq. (8) with alpha from straight runs (eq. (12)) and x_ICR from
    pure rotations (eq. (11)); calibration picks those runs by :func:`run_kind`."""

    name: str = "mandow2007.symmetric"
    paper: str = PAPER
    requires: frozenset[str] = frozenset({"enc_wl", "enc_wr"})
    params: IcrParams | None = None
    alpha_in_eq11: bool = True
    identification: SymmetricIdentification | None = field(default=None, compare=False, repr=False)

    def calibrate(self, runs: Sequence[Run]) -> "Symmetric":
        ident = identify_symmetric(runs, self.alpha_in_eq11)
        return dataclasses.replace(self, params=ident.params, identification=ident)

    def estimate(self, run: Run) -> Estimate:
        info = {"identification": self.identification.as_dict()} if self.identification else {}
        return dead_reckoning(_require_params(self), run, self.name, info)


@dataclass(frozen=True)
class AsymmetricGa:
    """``mandow2007.asymmetric_ga``: eq. (7) with K identified by the GA of Sec. III on every
    calibration run that has reference poses (segments at the reference rate, eq. (13))."""

    name: str = "mandow2007.asymmetric_ga"
    paper: str = PAPER
    requires: frozenset[str] = frozenset({"enc_wl", "enc_wr"})
    params: IcrParams | None = None
    ranges: GeneRanges | None = None
    settings: GaSettings = GaSettings()
    segment_period: float | None = None
    cross_check: bool = False  # also run differential evolution on the same segments (reported only)
    identification: Identification | None = field(default=None, compare=False, repr=False)
    cross_identification: Identification | None = field(default=None, compare=False, repr=False)

    def calibrate(self, runs: Sequence[Run]) -> "AsymmetricGa":
        seg = build_segments(runs, self.segment_period)
        ident = identify_ga(seg, self.ranges, self.settings)
        other = identify_de(seg, self.ranges) if self.cross_check else None
        return dataclasses.replace(self, params=ident.params, identification=ident, cross_identification=other)

    def estimate(self, run: Run) -> Estimate:
        return dead_reckoning(_require_params(self), run, self.name, _ident_info(self))

    def window_models(self, wheel_radius: float, track: float) -> list[WindowModel]:
        """The real-data benchmark's row ``mandow2007_icr`` (:func:`_window_models`)."""
        return _window_models(wheel_radius, track)


@dataclass(frozen=True)
class AsymmetricDe:
    """``mandow2007.asymmetric_de``: as :class:`AsymmetricGa`, K identified by scipy's differential
    evolution (second optimiser beside the published GA)."""

    name: str = "mandow2007.asymmetric_de"
    paper: str = PAPER
    requires: frozenset[str] = frozenset({"enc_wl", "enc_wr"})
    params: IcrParams | None = None
    ranges: GeneRanges | None = None
    settings: DeSettings = DeSettings()
    segment_period: float | None = None
    cross_check: bool = False  # also run the published GA on the same segments (reported only)
    identification: Identification | None = field(default=None, compare=False, repr=False)
    cross_identification: Identification | None = field(default=None, compare=False, repr=False)

    def calibrate(self, runs: Sequence[Run]) -> "AsymmetricDe":
        seg = build_segments(runs, self.segment_period)
        ident = identify_de(seg, self.ranges, self.settings)
        other = identify_ga(seg, self.ranges) if self.cross_check else None
        return dataclasses.replace(self, params=ident.params, identification=ident, cross_identification=other)

    def estimate(self, run: Run) -> Estimate:
        return dead_reckoning(_require_params(self), run, self.name, _ident_info(self))

    def window_models(self, wheel_radius: float, track: float) -> list[WindowModel]:
        """The real-data benchmark's row ``mandow2007_icr`` (:func:`_window_models`)."""
        return _window_models(wheel_radius, track)
