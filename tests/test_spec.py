"""Spec loading and validation: each bad input names file, field and value."""
from __future__ import annotations

import math

import pytest

from bench.spec import SpecError, load_platform, load_scenario, load_terrain, parse_override


def test_platforms_load_with_paper_values():
    p = load_platform("p3at_pneumatic_20psi")
    assert (p.mass, p.yaw_inertia, p.track, p.wheel_radius) == (30.6, 0.816, 0.40, 0.1075)  # Yu Table II
    assert p.motor.gear_ratio == 49.8 and p.pid.kp == 30.25
    yi = load_platform("yi2009_4wd")
    assert (yi.wheelbase, yi.track, yi.mass, yi.wheel_radius) == (0.365, 0.419, 10.4, 0.086)  # Yi Table I
    d = load_platform("dubhe")
    assert (d.track, d.wheelbase, d.wheel_radius, d.mass) == (0.87, 0.79, 0.23, 200.0)  # Liu Table 1
    assert load_platform("p3at_solid").wheel_radius == 0.095  # Mandow: 19 cm solid tires


@pytest.mark.parametrize("name", ["vinyl", "asphalt", "smooth_concrete", "concrete", "tile", "sand", "dirt",
                                  "ramp_asphalt_5p4", "ramp_wood_15", "ramp_whiteboard_13p5"])
def test_terrains_load(name):
    t = load_terrain(name)
    assert t.name == name


def test_ramp_slope_converted_from_degrees():
    assert math.isclose(load_terrain("ramp_wood_15").slope, math.radians(15.0))
    assert math.isclose(load_terrain("ramp_asphalt_5p4").slope, math.radians(5.4))


def test_vinyl_friction_is_yu_table_ii():
    v = load_terrain("vinyl")
    assert (v.mu_sa, v.mu_op, v.rolling_resistance) == (0.4437, 0.3093, 0.0371)


@pytest.mark.parametrize(
    "override, field, fragment",
    [
        ({"terrain.mu_sa": -1.0}, "terrain.mu_sa", "expected in (0, 3)"),
        ({"platform.mass": -3.0}, "platform.mass", "> 0 kg"),
        ({"platform.mass": "heavy"}, "platform.mass", "expected float"),
        ({"platform.wheels": 6}, "platform.wheels", "unknown key"),
        ({"command.kind": "teleport"}, "command.kind", "one of"),
        ({"duration": 0.0}, "duration", "(0, 14400]"),
        ({"platform.motor.pwm": 1.5}, "platform.motor.pwm", "(0, 1]"),
    ],
)
def test_bad_values_name_file_field_value(override, field, fragment):
    with pytest.raises(SpecError) as ei:
        load_scenario("circle_vinyl", override)
    e = ei.value
    assert e.field == field and fragment in str(e)
    assert "circle_vinyl.toml" in e.file
    assert repr(list(override.values())[0]) in str(e) or str(list(override.values())[0]) in str(e)


def test_missing_file_and_unknown_platform(tmp_path):
    with pytest.raises(SpecError, match="file not found"):
        load_scenario(tmp_path / "nope.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text('platform = "no_such_robot"\nterrain = "vinyl"\nduration = 1.0\n[command]\nkind = "rotation"\n')
    with pytest.raises(SpecError) as ei:
        load_scenario(bad)
    assert ei.value.field == "platform" and "no_such_robot" in str(ei.value)


def test_malformed_toml(tmp_path):
    bad = tmp_path / "broken.toml"
    bad.write_text("platform = \n")
    with pytest.raises(SpecError, match="malformed TOML"):
        load_scenario(bad)


def test_missing_required_field(tmp_path):
    bad = tmp_path / "nodur.toml"
    bad.write_text('platform = "dubhe"\nterrain = "dirt"\n[command]\nkind = "rotation"\n')
    with pytest.raises(SpecError) as ei:
        load_scenario(bad)
    assert ei.value.field == "duration" and "missing" in str(ei.value)


def test_override_parsing():
    assert parse_override("terrain.mu_sa=0.5") == ("terrain.mu_sa", 0.5)
    assert parse_override("terrain.model=coulomb") == ("terrain.model", "coulomb")
    assert parse_override("platform.sensors.gnss.outages=[[10.0, 30.0]]") == ("platform.sensors.gnss.outages", [[10.0, 30.0]])
    s = load_scenario("circle_vinyl", dict([parse_override("platform.sensors.gnss.outages=[[10.0, 30.0]]")]))
    assert s.platform.sensors.gnss.outages == ((10.0, 30.0),)
