"""Method plugins: the protocol every paper's method implements, and their discovery.

Plugins are found through the entry-point group ``skidbench.methods``; each entry point names a
zero-argument callable (a class or factory) returning an object that satisfies :class:`Method`.
A third-party package adds a method by declaring an entry point in that group.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from importlib import metadata
from typing import Any, Callable, Mapping, Protocol, Sequence, runtime_checkable

import numpy as np
import pandas as pd

from bench.run import Run, RunError

ENTRY_POINT_GROUP = "skidbench.methods"
ESTIMATE_REQUIRED = ("t", "x", "y", "yaw")
ESTIMATE_OPTIONAL = (
    "vx", "vy", "wz", "slip_l", "slip_r", "y_l", "y_r", "x_icr", "tau_l", "tau_r", "wl", "wr", "chi",
    "z", "vz", "roll", "pitch",
)


@dataclass(frozen=True)
class Estimate:
    """A method's output: a DataFrame with t, x, y, yaw (world frame) and optional columns of
    :data:`ESTIMATE_OPTIONAL`, plus free-form ``info`` (identified parameters, diagnostics)."""

    data: pd.DataFrame
    method: str = ""
    info: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        for c in ESTIMATE_REQUIRED:
            if c not in self.data.columns:
                raise RunError(f"estimate of {self.method}", c, None, "missing estimate column")

    def __getitem__(self, name: str) -> np.ndarray:
        return self.data[name].to_numpy()

    @property
    def t(self) -> np.ndarray:
        return self.data["t"].to_numpy()


def make_estimate(method: str, info: Mapping[str, Any] | None = None, **columns: np.ndarray) -> Estimate:
    return Estimate(pd.DataFrame({k: np.asarray(v, dtype=np.float64) for k, v in columns.items()}), method, dict(info or {}))


@runtime_checkable
class Method(Protocol):
    name: str  # "liu2020.mi_ukf"
    paper: str  # short citation, "Liu et al. 2020"
    requires: frozenset[str]  # Run channels it reads
    # optional: ``calibration_requires`` (channels its calibration runs need besides), ``start_pose_channels`` (the
    # channels of ``requires`` it reads only for its start pose: the league groups methods by what they read after it)

    def calibrate(self, runs: Sequence[Run]) -> "Method": ...

    def estimate(self, run: Run) -> Estimate: ...


class CalibrationLeak(RuntimeError):
    """Raised when a method would be scored on a run it was calibrated on."""


class NotCalibratedError(RuntimeError):
    """A method asked to estimate before calibration identified its parameters (``skidbench estimate`` then says to
    give calibration runs).  The plugins' own not-calibrated errors derive from it; any other exception of
    ``estimate`` is the method's defect, reported whole."""


class CalibrationDataError(ValueError):
    """The calibration runs given cannot calibrate this method (they lack the experiment its identification needs):
    bad input, reported in one line.  A method's own calibration-data errors derive from it."""


def calibrated_on(method: Any) -> frozenset[str]:
    """Content hashes of the runs a method was calibrated on (set by :func:`calibrate`)."""
    return frozenset(getattr(method, "_calibration_hashes", frozenset()))


def calibrate(method: Method, runs: Sequence[Run]) -> Method:
    """Calibrate on truth-withheld views of ``runs`` and remember their hashes."""
    for r in runs:
        r.require(method.requires | getattr(method, "calibration_requires", frozenset()), method.name)
    out = method.calibrate([r.without_truth() for r in runs])
    return _mark_calibrated(out, calibrated_on(method) | {r.content_hash() for r in runs})


def derive(method: Any, **changes: Any) -> Any:
    """``dataclasses.replace(method, **changes)`` that keeps the calibration runs of ``method``
    (:func:`calibrated_on`): a copy with other settings is still refused on them by :func:`estimate`."""
    return _mark_calibrated(replace(method, **changes), calibrated_on(method))


def _mark_calibrated(out: Any, hashes: frozenset[str]) -> Any:
    object.__setattr__(out, "_calibration_hashes", frozenset(hashes)) if _frozen(out) else setattr(
        out, "_calibration_hashes", frozenset(hashes)
    )
    return out


def _frozen(obj: Any) -> bool:
    params = getattr(type(obj), "__dataclass_params__", None)
    return bool(params and params.frozen)


def estimate(method: Method, run: Run) -> Estimate:
    """Score-side call: refuses a run the method was calibrated on, withholds truth columns,
    checks the required channels, and returns the method's estimate."""
    if run.content_hash() in calibrated_on(method):
        raise CalibrationLeak(
            f"{method.name}: refusing to estimate on run '{run.id}', which it was calibrated on; "
            "calibration and scored runs must differ (other seed or path)"
        )
    run.validate()
    run.require(method.requires, method.name)
    return method.estimate(run.without_truth())


def discover() -> dict[str, Callable[[], Method]]:
    """All registered method factories by name (entry point name == method name)."""
    out: dict[str, Callable[[], Method]] = {}
    for ep in metadata.entry_points(group=ENTRY_POINT_GROUP):
        out[ep.name] = ep  # loaded lazily
    return dict(sorted(out.items()))


class PluginLoadError(RuntimeError):
    """A registered entry point that cannot be imported (a broken installed plugin): one line naming it."""


def get(name: str, **kwargs: Any) -> Method:
    eps = discover()
    if name not in eps:
        raise KeyError(f"unknown method '{name}'; registered: {', '.join(eps) or '(none)'}")
    ep = eps[name]
    try:
        factory = ep.load()  # type: ignore[union-attr]
    except Exception as exc:  # noqa: BLE001 - whatever the plugin's import raises, named in one line
        raise PluginLoadError(f"method '{name}': its entry point {getattr(ep, 'value', ep)} failed to load "
                              f"({type(exc).__name__}: {exc}); fix or uninstall the package that registers it") from exc
    return factory(**kwargs)
