"""The testbed's C step (bench/sim/_kernel.c) against its reference, the Python loop of run_physics:
the same physics-rate trace, bit for bit, on every branch the loop has (Janosi and Coulomb laws, a
standing wheel held on a ramp, an initial speed, a controller slower than the physics, saturating
motors, unequal wheel radii, the command map, friction patches steady and periodic, rate-limited
references, a stiff terrain at its own physics step, the pneumatic and solid tire contacts with a CoM offset,
friction falling with the sliding speed)."""
from __future__ import annotations

import numpy as np
import pytest

from bench.sim import testbed
from bench.spec import load_scenario

pytestmark = pytest.mark.skipif(testbed.KERNEL is None, reason="bench.sim._kernel not built")

CASES = {
    "janosi_circle": ("circle_vinyl", {"duration": 3.0}),
    "coulomb_rotation": ("gap_dev_coulomb", {"duration": 2.0}),
    "ramp_standing_then_climb": ("ramp_wood_15", {"duration": 2.0}),
    "initial_speed_ramp": ("ramp_asphalt_5p4", {"duration": 1.5, "initial_speed": 0.5}),
    "initial_turn_ramp": ("ramp_asphalt_5p4", {"duration": 1.5, "initial_speed": 0.4, "initial_yaw_rate": -0.5,
                                               "initial_skid_ratio": 1.8}),
    "initial_turn_backward_solid_tire": ("mandow_joystick_asphalt_solid", {"duration": 1.0, "initial_speed": -0.3,
                                                                  "initial_yaw_rate": 0.6, "initial_skid_ratio": 2.0}),
    "slow_pid_random_seeded": ("stress_dubhe_random", {"duration": 2.5, "platform.pid.rate_hz": 20.0}),
    "saturating_motor_power_limit": ("yu_lemniscate", {"duration": 2.0, "platform.motor.max_power": 5.0,
                                                        "platform.motor.max_current": 1.0}),
    "unequal_radii_command_map": ("straight_0p2_vinyl", {"duration": 2.0, "platform.wheel_radius_scale_l": 1.03,
                                                          "platform.command_gain_diff": 0.8,
                                                          "platform.command_limit_mean": 5.0}),
    "friction_patches": ("gap_dev_coulomb", {"duration": 2.0, "terrain.friction_patches": (
        (-1e3, 1e3, -1e3, 0.0, 0.5, 0.0), (-1e3, 1e3, 0.0, 1e3, 0.7, 0.9))}),
    "stiff_tile_fine_step": ("wang_circle_grid", {"duration": 1.5}),
    "rate_limited_references": ("liu_small_radius", {"duration": 2.0}),
    # issue 31: per-wheel patch and loaded radius from the load, a CoM offset, a tire's rolling resistance
    "solid_tire_cg_offset": ("mandow_joystick_asphalt_solid", {"duration": 2.5}),
    "pneumatic_50psi_rotation": ("mandow_rotation_smooth_concrete_pneumatic_50psi", {"duration": 2.0}),
    # Bekker soil: sinkage, shear strength and the compaction resistance on the body, standing, turning, rough
    "soil_sand_turn": ("yi_s_gamma_sand", {"duration": 2.0}),
    "soil_dirt_rough_straight": ("liu_straight", {"duration": 1.5}),
    "pneumatic_standing_on_ramp": ("ramp_wood_15", {"duration": 1.0, "platform.tire_pressure": 2.0e5,
                                                     "platform.cg_offset_x": -0.05}),
    # issue 32: friction falling with the sliding speed (Dugoff), on both laws
    "speed_decay_coulomb_turn": ("gap_test_coulomb", {"duration": 2.5, "terrain.friction_speed_decay": 3.0}),
    "speed_decay_janosi_rotation": ("mandow_rotation_smooth_concrete_pneumatic_50psi",
                                    {"duration": 1.5, "terrain.friction_speed_decay": 3.0}),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_c_step_gives_the_python_loop_bytes(case: str, monkeypatch: pytest.MonkeyPatch) -> None:
    name, over = CASES[case]
    scn = load_scenario(name, over)
    monkeypatch.setenv("SKIDBENCH_KERNEL", "python")
    ref = testbed.run_physics(scn, 3)
    monkeypatch.setenv("SKIDBENCH_KERNEL", "c")
    fast = testbed.run_physics(scn, 3)
    assert fast.data.shape == ref.data.shape
    assert fast.data.tobytes() == ref.data.tobytes()
    assert fast.cg_offset == ref.cg_offset


@pytest.mark.parametrize("case", sorted(c for c in CASES if c.startswith("speed_decay")))
def test_the_speed_decay_cases_change_the_physics(case: str) -> None:
    """The decay cases above reach sliding speeds where the decay acts (a trace that moved by rounding only would
    leave the C branch untested): some column moves by more than 1e-3 against the same run without the decay."""
    name, over = CASES[case]
    a = testbed.run_physics(load_scenario(name, over), 3).data
    b = testbed.run_physics(load_scenario(name, dict(over, **{"terrain.friction_speed_decay": 0.0})), 3).data
    assert float(np.nanmax(np.abs(a - b))) > 1e-3


def test_the_c_step_is_used_by_default(monkeypatch: pytest.MonkeyPatch) -> None:
    """run_physics takes the C step unless SKIDBENCH_KERNEL=python (so the comparison above compares two paths)."""
    calls = []
    real = testbed._kernel_loop
    monkeypatch.setattr(testbed, "_kernel_loop", lambda *a, **k: calls.append(1) or real(*a, **k))
    monkeypatch.delenv("SKIDBENCH_KERNEL", raising=False)
    testbed.run_physics(load_scenario("circle_vinyl", {"duration": 0.2}), 0)
    monkeypatch.setenv("SKIDBENCH_KERNEL", "python")
    testbed.run_physics(load_scenario("circle_vinyl", {"duration": 0.2}), 0)
    assert calls == [1]


def test_a_failing_run_through_the_c_step_leaves_a_usable_client() -> None:
    scn = load_scenario("circle_vinyl", {"duration": 0.5})
    before = testbed.run_physics(scn, 0).data

    def fail(frac: float) -> None:
        raise RuntimeError("stop")

    with pytest.raises(RuntimeError, match="stop"):
        testbed.run_physics(load_scenario("yi_circle", {"duration": 0.5}), 0, progress=fail)
    assert testbed.run_physics(scn, 0).data.tobytes() == before.tobytes()
