"""A Run-based method plugin scored on DRIVE windows: :class:`PluginModel` adapts any
:class:`bench.registry.Method` (``calibrate(runs)``, ``estimate(run)``) to the window protocol
(:class:`bench.real.windows.WindowModel`) by running its ``estimate`` on one Run per window
(:func:`window_runs`); slower than a plugin's own ``window_models``, which the benchmark prefers."""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from bench.real.drive import DriveWindows
from bench.real.windows import Pose
from bench.run import Run, from_arrays


def window_runs(w: DriveWindows, platform: Mapping[str, Any] | None = None, with_reference: bool = True
                ) -> list[Run]:
    """One Run per window (t from 0), for plugins written against :class:`bench.run.Run`."""
    runs = []
    names = [c for c in w.channels if with_reference or not c.startswith("ref_")]
    stem = Path(w.source).stem
    for i in range(w.n_windows):
        cols = {"t": w.t, **{c: w.channels[c][i] for c in names}}
        runs.append(from_arrays(cols, {"run_id": f"{stem}:row{int(w.row[i])}", "source_file": w.source,
                                       "platform": dict(platform or {}), "calib_step": int(w.calib_step[i])}))
    return runs


@dataclass(frozen=True)
class PluginModel:
    """Adapter: a :class:`bench.registry.Method` plugin as a :class:`WindowModel`.

    ``fit`` calibrates the method on one Run per calibration window (reference included, as the
    papers' identification reads it); ``predict`` runs ``estimate`` on each window with the
    reference withheld, takes the estimated pose at the window's samples, and re-bases it on the
    window's initial ICP pose (the estimate's own start pose is not trusted).  Loops over windows.
    """

    method: Any
    platform: Mapping[str, Any] = field(default_factory=dict)
    name: str = ""
    label: str = ""
    fit_cost: float = math.nan

    def __post_init__(self) -> None:
        if not self.name:
            object.__setattr__(self, "name", str(getattr(self.method, "name", type(self.method).__name__)))
        if not self.label:
            object.__setattr__(self, "label", f"plugin {self.name}")

    def fit(self, calib: DriveWindows) -> "PluginModel":
        return dataclasses.replace(self, method=self.method.calibrate(window_runs(calib, self.platform)))

    def predict(self, windows: DriveWindows) -> Pose:
        n, m = windows.n_windows, windows.n_samples
        out = [np.empty((n, m)) for _ in range(3)]
        for i, run in enumerate(window_runs(windows, self.platform, with_reference=False)):
            est = self.method.estimate(run)
            xe, ye, he = (np.interp(windows.t, est.t, est[c]) for c in ("x", "y", "yaw"))
            c0, s0 = np.cos(he[0]), np.sin(he[0])
            dx, dy = xe - xe[0], ye - ye[0]
            xr, yr = c0 * dx + s0 * dy, -s0 * dx + c0 * dy
            x0, y0, h0 = (windows[c][i, 0] for c in ("ref_x", "ref_y", "ref_yaw"))
            out[0][i] = x0 + np.cos(h0) * xr - np.sin(h0) * yr
            out[1][i] = y0 + np.sin(h0) * xr + np.cos(h0) * yr
            out[2][i] = h0 + np.unwrap(he) - he[0]
        return out[0], out[1], out[2]

    def params(self) -> dict[str, float]:
        return {}
