"""Closed-form checks of the testbed effects added to the gap catalogue for real robots (issue 32): the robot's
own acceleration limits (``command_accel``), the drive's wheel-speed limit (``wheel_speed_limit``), lateral
friction anisotropy (``lateral_friction``), and the initial wheel speeds held while a delayed command has not
arrived yet.  Expectations are closed forms (a rate-limited ramp, a proportional scaling, the rigid-body kinematics
of an anisotropic Coulomb spot turn), not numbers of a previous run."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from bench.gap import catalogue as C
from bench.sim.testbed import _references
from bench.spec import CommandSpec, Segment, SpecError, load_scenario


def _step_scenario(wl: float, wr: float, duration: float = 3.0, **platform):
    """gap_test_coulomb's platform driven by one wheel-speed step (wl, wr) at t = 0, no ramp."""
    scn = load_scenario("gap_test_coulomb")
    cmd = CommandSpec(kind="wheel_speeds", units="rad/s", segments=(Segment(duration + 1.0, wl, wr),), accel=0.0)
    return dataclasses.replace(scn, command=cmd, duration=duration,
                               platform=dataclasses.replace(scn.platform, **platform))


def test_command_accel_ramps_mean_and_difference_at_their_limits():
    """A step (wl, wr) = (2, 6) rad/s from rest, mean 4 and half-difference 2: with acceleration limits of 5 and
    1.6 rad/s^2 the mean reaches 4 at t = 0.8 s and the half-difference 2 at t = 1.25 s, each along a straight
    line min(a t, target) (t = (k + 1) dt after the k-th step, as the rate limiter moves once per step)."""
    scn = _step_scenario(2.0, 6.0, command_accel_mean=5.0, command_accel_diff=1.6)
    n = int(round(2.0 / scn.dt))
    ref_l, ref_r = map(np.asarray, _references(scn, 0, n))
    t = np.arange(n + 1) * scn.dt + scn.dt
    mean, half = 0.5 * (ref_l + ref_r), 0.5 * (ref_r - ref_l)
    np.testing.assert_allclose(mean, np.minimum(5.0 * t, 4.0), rtol=0, atol=1e-9)
    np.testing.assert_allclose(half, np.minimum(1.6 * t, 2.0), rtol=0, atol=1e-9)
    plain = _references(_step_scenario(2.0, 6.0), 0, n)  # the default (inf) leaves the command as it is
    assert plain[0] == [2.0] * (n + 1) and plain[1] == [6.0] * (n + 1)
    assert C.get("command_accel").spec_overrides(scn, (5.0, 1.6)) == {
        "platform.command_accel_mean": 5.0, "platform.command_accel_diff": 1.6}


def test_wheel_speed_limit_scales_both_sides_and_keeps_their_ratio():
    """A command (-3, 8) rad/s under a 5 rad/s limit: the faster side at 5 and the other at -3 x 5/8 (the same
    curvature), for both signs; a command within the limit passes unchanged."""
    for wl, wr in ((-3.0, 8.0), (-8.0, 3.0), (8.0, 7.5)):
        scn = _step_scenario(wl, wr, wheel_speed_limit=5.0)
        ref_l, ref_r = _references(scn, 0, 10)
        k = 5.0 / max(abs(wl), abs(wr))
        assert ref_l[-1] == pytest.approx(wl * k, abs=1e-12) and ref_r[-1] == pytest.approx(wr * k, abs=1e-12)
    assert _references(_step_scenario(2.0, -4.5, wheel_speed_limit=5.0), 0, 10)[1][-1] == -4.5


def test_wheel_speed_limit_holds_the_faster_wheel_in_the_testbed(sim):
    """End to end: the simulated encoders of a turn commanded at (2, 6) rad/s under a 4 rad/s limit read 4 and
    4/3 rad/s in steady state (the closed form of the scaling), where the nominal run reads (2, 6)."""
    scn = _step_scenario(2.0, 6.0, duration=4.0, wheel_speed_limit=4.0)
    from bench.sim import simulate

    run = simulate(scn, 0)
    for c, expect in (("enc_wl", 4.0 / 3.0), ("enc_wr", 4.0)):
        t, v = run.samples(c)
        assert float(np.mean(v[t > 2.5])) == pytest.approx(expect, rel=0.02), c


@pytest.mark.parametrize("k", [0.7, 1.6])
def test_lateral_friction_sets_chi_of_a_coulomb_spot_turn(k):
    """Spot turn on Coulomb ground with mu_lat = k mu_lon at the four contacts (+-a, +-b): the yaw moment of the
    sliding forces vanishes when w (k a^2 + b^2) = b u (u the tread speed), so chi = u / (w b) = 1 + k (a/b)^2
    and w = b u / (b^2 + k a^2) (k = 1: validate-testbed's coulomb_rotation_closed_form)."""
    from bench.sim import simulate
    from bench.sim.validate import chi_eq25

    base = load_scenario("gap_test_coulomb")
    terr = dataclasses.replace(base.terrain, model="coulomb", mu_lat_ratio=k)
    run = simulate(dataclasses.replace(base, terrain=terr, command=CommandSpec(kind="rotation", v=0.2),
                                       duration=5.0), 0)
    a, b = base.platform.wheelbase / 2, base.platform.track / 2
    assert chi_eq25(run.data, base.platform, 2.5) == pytest.approx(1 + k * (a / b) ** 2, rel=0.02)
    d = run.data[run.data["t"] >= 2.5]
    u = base.platform.wheel_radius * base.platform.wheel_radius_scale_r * float(d["truth_wr"].mean())
    assert float(d["truth_wz"].mean()) == pytest.approx(b * u / (b * b + k * a * a), rel=0.02)
    assert C.get("lateral_friction").spec_overrides(base, (k,)) == {"terrain.mu_lat_ratio": k}


def test_a_moving_start_holds_its_speed_until_the_delayed_command_arrives():
    """With an actuator delay d, the references before t = d are the initial wheel speeds v0 / r_eff (the robot keeps
    doing what it did), not 0 (which braked every replayed moving step for d seconds); from rest they stay 0."""
    scn = dataclasses.replace(_step_scenario(1.0, 3.0, actuator_delay=0.2), initial_speed=0.4)
    ref_l, ref_r = map(np.asarray, _references(scn, 0, int(round(0.5 / scn.dt))))
    t = np.arange(ref_l.size) * scn.dt
    plat = scn.platform
    before = t < 0.2 - 1e-9
    assert np.allclose(ref_l[before], 0.4 / (plat.wheel_radius * plat.wheel_radius_scale_l), rtol=0, atol=1e-12)
    assert np.allclose(ref_r[before], 0.4 / (plat.wheel_radius * plat.wheel_radius_scale_r), rtol=0, atol=1e-12)
    assert np.all(ref_l[~before] == 1.0) and np.all(ref_r[~before] == 3.0)
    rest = _references(_step_scenario(1.0, 3.0, actuator_delay=0.2), 0, ref_l.size - 1)
    assert set(np.asarray(rest[0])[before]) == {0.0}


@pytest.mark.parametrize("field,value", [("command_accel_mean", 0.0), ("command_accel_diff", -1.0),
                                         ("wheel_speed_limit", 0.0)])
def test_limits_must_be_positive(field, value):
    with pytest.raises(SpecError, match=field):
        load_scenario("gap_test_coulomb", {f"platform.{field}": value})


@pytest.mark.parametrize("k", [0.6, 2.5])
def test_motor_torque_scales_the_motor_line_at_every_speed(k):
    """``motor_torque`` scales stall torque and current limit by k: on the DC-motor line (Yu 2010 eq. (26),
    I = (V - K_B g w) / R_a with R_a = V_nom K_T / tau_stall, clipped at I_max) the wheel torque is k times the
    nominal motor's at every voltage and wheel speed, in the linear part and at the current limit alike (the
    Husky's motor, which has no power limit)."""
    from bench.sim.drive import MotorConstants, motor_law
    from bench.spec import replace

    scn = load_scenario("real_husky_asphalt")
    assert scn.platform.motor.max_power == 0.0
    eff = C.get("motor_torque")
    scaled = replace(scn, **eff.spec_overrides(scn, (k,)))
    base = motor_law(MotorConstants.from_spec(scn.platform.motor))
    law = motor_law(MotorConstants.from_spec(scaled.platform.motor))
    m = scn.platform.motor
    clipped = 0
    for volt in (-20.0, 2.0, 6.0, 22.8):
        for w in (-5.0, 0.0, 1.0, 4.0, 7.5):
            tb, ib, _ = base(volt, w)
            tk, ik, _ = law(volt, w)
            assert tk == pytest.approx(k * tb, rel=1e-9, abs=1e-12) and ik == pytest.approx(k * ib, rel=1e-9, abs=1e-12)
            clipped += abs(ib) == m.max_current
    assert clipped > 0  # the current-limited branch is exercised (full voltage against a reversing wheel)
    assert eff.neutral(scn) == (1.0,)


def test_imu_lever_arm_and_turned_axes_read_the_numerically_differentiated_point_acceleration(sim):
    """The testbed's IMU mounted at a lever arm r = (0.3, -0.2) m with its axes turned by 0.1 rad (noise off):
    turned back, its reading minus the CoM IMU's equals the body-frame second derivative of the lever vector
    R(yaw) r, differentiated numerically from the physics trace's yaw (independent of the rigid-body formula
    of bench.sim.sensors.imu_mounting), in the turns of gap_dev_coulomb (up to 0.59 m/s^2; the tangential term's sign flipped errs by 0.98)."""
    from bench.gap.model import testbed_trace

    quiet = {"platform__sensors__imu__accel_noise": 0.0, "platform__sensors__imu__accel_bias_walk": 0.0}
    plain = sim("gap_dev_coulomb", 0, **quiet)
    lx, ly, psi = 0.3, -0.2, 0.1
    mounted = sim("gap_dev_coulomb", 0, **quiet, platform__sensors__imu__lever_x=lx,
                  platform__sensors__imu__lever_y=ly, platform__sensors__imu__yaw_misalignment=psi)
    tr = testbed_trace(load_scenario("gap_dev_coulomb"), {})
    t, yaw = tr["t"], tr["yaw"]
    px, py = np.cos(yaw) * lx - np.sin(yaw) * ly, np.sin(yaw) * lx + np.cos(yaw) * ly  # world lever vector
    ax, ay = np.gradient(np.gradient(px, t), t), np.gradient(np.gradient(py, t), t)
    bx, by = np.cos(yaw) * ax + np.sin(yaw) * ay, -np.sin(yaw) * ax + np.cos(yaw) * ay  # into body axes
    ti, fx0 = plain.samples("imu_ax")
    _, fy0 = plain.samples("imu_ay")
    _, fx1 = mounted.samples("imu_ax")
    _, fy1 = mounted.samples("imu_ay")
    c, s = np.cos(psi), np.sin(psi)
    dx, dy = c * fx1 - s * fy1 - fx0, s * fx1 + c * fy1 - fy0  # the mounted reading turned back, less the CoM's
    ex, ey = np.interp(ti, t, bx), np.interp(ti, t, by)
    inner = (ti > 0.2) & (ti < ti[-1] - 0.2)
    assert np.max(np.hypot(ex, ey)[inner]) > 0.3  # the check has something to see
    assert np.max(np.abs(dx - ex)[inner]) < 0.005 and np.max(np.abs(dy - ey)[inner]) < 0.005  # measured 4e-4


def test_gyro_scale_flips_the_yaw_rate_and_nothing_else(sim):
    """gyro_scale_z = -1 (an IMU mounted upside down): the gyro reads minus the body's yaw rate, sample for sample,
    with the same noise draws; the accelerometer and every other channel are unchanged."""
    quiet = {"platform__sensors__imu__gyro_noise": 0.0, "platform__sensors__imu__gyro_bias_walk": 0.0}
    plain = sim("gap_dev_coulomb", 1, **quiet)
    flipped = sim("gap_dev_coulomb", 1, **quiet, platform__sensors__imu__gyro_scale_z=-1.0)
    np.testing.assert_array_equal(flipped.samples("imu_gz")[1], -plain.samples("imu_gz")[1])
    for c in ("imu_ax", "imu_ay", "enc_wl", "enc_wr", "ref_x"):
        np.testing.assert_array_equal(flipped.samples(c)[1], plain.samples(c)[1])


def test_the_centre_of_mass_search_stays_inside_what_the_spec_accepts():
    """The cg_offset candidate's bounds (+-0.15 m) reach beyond the P3-AT's axles (wheelbase 0.27 m): on it the
    search is narrowed to 90 % of the half wheelbase and half track, so a fitted value is one `--set` accepts
    (Platform._check_whole); on the Husky (wheelbase 0.512 m) the catalogue's own bounds stay."""
    from bench.gap.fit import Layout, _clip
    from bench.spec import replace

    cg = C.get("cg_offset")
    p3at = load_scenario("gap_example")
    wb, tr = p3at.platform.wheelbase, p3at.platform.track
    assert wb / 2 < 0.15
    assert cg.bounds(p3at) == ((-0.45 * wb, 0.45 * wb), (max(-0.15, -0.45 * tr), min(0.15, 0.45 * tr)))
    assert cg.bounds(load_scenario("gap_blind_launch")) == cg.bounds() == ((-0.15, 0.15), (-0.15, 0.15))
    lay = Layout((cg,), C.ModelConfig())
    lo, hi = lay.bounds_u(p3at)
    theta = _clip(np.array([-0.15, 0.15]), lay, p3at)
    assert lo[0] < theta[0] < 0 and theta[0] > -0.45 * wb
    x, y = theta
    assert replace(p3at, **{"platform.cg_offset_x": x, "platform.cg_offset_y": y}).platform._check_whole() is None
    assert replace(p3at, **{"platform.cg_offset_x": -0.15}).platform._check_whole() is not None


def test_a_fit_on_the_scenarios_limit_is_reported_at_its_bound():
    """The report's "(at bound)" reads the bounds the fit used (the entry's "bounds"), not the catalogue's."""
    from bench.gap.report import uncertainty_text

    lim = 0.45 * load_scenario("gap_example").platform.wheelbase
    at_limit = -lim + 1e-7
    assert "at bound" not in uncertainty_text("cg_offset", "cg_offset_x", at_limit, 0.01)
    assert f"(at bound {-lim:g})" in uncertainty_text("cg_offset", "cg_offset_x", at_limit, 0.01, bounds=(-lim, lim))
