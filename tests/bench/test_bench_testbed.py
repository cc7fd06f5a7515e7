"""Speed of the testbed (make bench): real-time factor for P3-AT and DUBHE, and the bare
pybullet stepSimulation cost of the same world beside it."""
from __future__ import annotations

import pytest

from bench.sim.testbed import _build_world, p, run_physics
from bench.spec import load_scenario

DURATION = 10.0


@pytest.mark.parametrize("scenario", ["circle_vinyl", "liu_large_radius"])
def test_testbed_real_time_factor(benchmark, scenario):
    scn = load_scenario(scenario, {"duration": DURATION})
    benchmark.pedantic(run_physics, args=(scn, 0), rounds=3, iterations=1, warmup_rounds=1)
    benchmark.extra_info["real_time_factor"] = DURATION / benchmark.stats["mean"]
    benchmark.extra_info["dt"] = scn.dt
    benchmark.extra_info["platform"] = scn.platform.name


def test_bare_step_simulation(benchmark):
    scn = load_scenario("circle_vinyl")
    cid = p.connect(p.DIRECT)
    try:
        _build_world(scn, cid)
        n = 1000

        def steps():
            for _ in range(n):
                p.stepSimulation(physicsClientId=cid)

        benchmark.pedantic(steps, rounds=5, iterations=1, warmup_rounds=1)
        benchmark.extra_info["us_per_step"] = benchmark.stats["mean"] / n * 1e6
    finally:
        p.disconnect(cid)
