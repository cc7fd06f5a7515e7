"""asv benchmarks for skidbench (optional; see asv.conf.json and bench/report/dashboard.py).

``track_*`` report the reproduced numbers of ``results/metrics.json`` (or
``$SKIDBENCH_RESULTS/metrics.json``) over a ``params`` grid of metric ids ``<paper>.<table>.<metric>``;
``time_*`` time the testbed, the SE(2) integration and the trajectory metrics.  Run with
``asv run --environment existing`` (the installed skidbench in the running interpreter).
"""
from __future__ import annotations

import json
import math
import os
from pathlib import Path

RESULTS = Path(os.environ.get("SKIDBENCH_RESULTS", Path(__file__).resolve().parents[1] / "results"))
NO_METRICS = "(no metrics.json: run skidbench reproduce)"


def _metrics() -> dict:
    path = RESULTS / "metrics.json"
    if not path.is_file():
        return {}
    return {k: v for k, v in json.loads(path.read_text()).get("metrics", {}).items()
            if isinstance(v.get("value"), (int, float)) and math.isfinite(v["value"])}


_M = _metrics()


class Reproduced:
    """The reproduced value of every metric (asv detects steps between commits)."""

    params = [sorted(_M) or [NO_METRICS]]
    param_names = ["metric"]

    def setup(self, metric: str) -> None:
        if metric not in _M:
            raise NotImplementedError(metric)  # asv: skipped

    def track_value(self, metric: str) -> float:
        return float(_M[metric]["value"])

    track_value.unit = "value"


class DistanceToPublished:
    """|reproduced - published| for the metrics that have a published value."""

    params = [sorted(k for k, v in _M.items() if isinstance(v.get("published"), (int, float))) or [NO_METRICS]]
    param_names = ["metric"]

    def setup(self, metric: str) -> None:
        if metric not in _M:
            raise NotImplementedError(metric)

    def track_abs_error(self, metric: str) -> float:
        return abs(float(_M[metric]["value"]) - float(_M[metric]["published"]))

    track_abs_error.unit = "value"


class Speed:
    """Speed of the parts every reproduction uses (the full set is under tests/bench, `make bench`)."""

    number = 1
    repeat = (2, 5, 20.0)
    timeout = 300.0

    def setup(self) -> None:
        import numpy as np

        from bench import metrics as M
        from bench.kinematics import integrate_se2

        n = 100_000
        rng = np.random.default_rng(0)
        self.t = np.arange(n) * 0.01
        self.vx = 0.8 + 0.2 * np.sin(self.t / 7)
        self.wz = 0.4 * np.sin(self.t / 13) + rng.normal(0, 0.02, n)
        x, y, yaw = integrate_se2(self.t, self.vx, -0.03 * self.wz, self.wz)
        ex, ey, eyaw = integrate_se2(self.t, 1.02 * self.vx, 0 * self.vx, self.wz + 0.002)
        self.ref = M.Trajectory.planar(self.t, x, y, yaw, name="ref")
        self.est = M.Trajectory.planar(self.t, ex, ey, eyaw, name="est")

    def time_integrate_se2_100k(self) -> None:
        from bench.kinematics import integrate_se2

        integrate_se2(self.t, self.vx, -0.03 * self.wz, self.wz)

    def time_ape_translation_se3_100k(self) -> None:
        from bench import metrics as M

        M.ape(self.ref, self.est, "translation", "se3")


class Testbed:
    """Simulated seconds of a P3-AT circle on vinyl (pybullet testbed)."""

    number = 1
    repeat = (1, 3, 60.0)
    timeout = 600.0
    params = [["circle_vinyl"]]
    param_names = ["scenario"]

    def setup(self, scenario: str) -> None:
        from bench.spec import load_scenario

        self.scn = load_scenario(scenario, {"duration": 5.0})

    def time_simulate_5s(self, scenario: str) -> None:
        from bench.sim import simulate

        simulate(self.scn, 0)
