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
        ({"platform.mass": -3.0}, "platform.mass", "in [0.1, 5e4] kg"),
        ({"platform.wheel_radius": 1e-6}, "platform.wheel_radius", "in [0.01, 2] m"),
        ({"platform.cg_offset_x": float("inf")}, "platform.cg_offset_x", "finite"),
        ({"platform.cg_offset_y": 0.3}, "platform.cg_offset_y", "< track / 2"),
        ({"platform.sensors.imu.rate_hz": 1e9}, "platform.sensors.imu.rate_hz", "in (0, 10000] Hz"),
        ({"terrain.slope_deg": 90}, "terrain.slope_deg", "in SI: slope = 1.5708"),
        ({"initial_speed": float("inf")}, "initial_speed", "[-20, 20] m/s"),
        ({"platform.cg_offset_x": 1e300}, "platform.cg_offset_x", "< wheelbase / 2"),
        ({"platform.mass": "heavy"}, "platform.mass", "expected float"),
        ({"platform.wheels": 6}, "platform.wheels", "unknown key"),
        ({"command.kind": "teleport"}, "command.kind", "one of"),
        ({"duration": 0.0}, "duration", "(0, 14400]"),
        ({"platform.motor.pwm": 1.5}, "platform.motor.pwm", "(0, 1]"),
        ({"initial_yaw_rate": 12.0}, "initial_yaw_rate", "[-10, 10] rad/s"),
        ({"initial_yaw_rate": float("nan")}, "initial_yaw_rate", "not NaN"),
        ({"initial_skid_ratio": -0.5}, "initial_skid_ratio", "[0, 20]"),
    ],
)
def test_bad_values_name_file_field_value(override, field, fragment):
    with pytest.raises(SpecError) as ei:
        load_scenario("circle_vinyl", override)
    e = ei.value
    assert e.field == field and fragment in str(e)
    assert "circle_vinyl.toml" in e.file
    assert repr(list(override.values())[0]) in str(e) or str(list(override.values())[0]) in str(e)


@pytest.mark.parametrize(
    "segments, field, value, fragment",
    [
        ([[-1.0, 0.2, 4.0]], "command.segments[0].t_end", -1.0, "> 0 s"),
        ([[20.0, 0.2, 0.0]], "command.segments[0].b", 0.0, "|b| >= 1 mm"),
        ([[0.05, 1e300, 1e-300]], "command.segments[0].a", 1e300, "|a| <= 10000"),  # overflowed the wheel speeds
        ([[20.0, 1e3, 4.0]], "command.segments[0].a", 1e3, "[-20, 20] m/s"),
        ([[20.0, float("inf"), 4.0]], "command.segments[0].a", float("inf"), "finite"),
        ([[20.0, 0.2, float("nan")]], "command.segments[0].b", None, "NaN"),
    ],
)
def test_a_segment_the_command_cannot_follow_names_its_value(segments, field, value, fragment):
    """A command segment with a negative end, an infinite speed, a radius of 0 or NaN is refused at load time (the
    testbed would turn it into infinite wheel speeds or never move), naming the segment's field."""
    with pytest.raises(SpecError) as ei:
        load_scenario("circle_vinyl", {"command.segments": segments})
    e = ei.value
    assert e.field == field and fragment in str(e)
    if value is not None:
        assert e.value == value


def test_a_curvature_ratio_below_zero_and_an_infinite_wheel_speed_are_refused():
    with pytest.raises(SpecError, match=r"segments\[0\]\.b.*curvature ratio >= 0"):
        load_scenario("wang_circle_grid", {"command.kind": "v_curvature_ratio", "command.units": "rad/s",
                                           "command.segments": [[8.0, 0.3, -1.0]]})
    with pytest.raises(SpecError, match=r"segments\[0\]\.b.*finite wheel speed"):
        load_scenario("yi_straight", {"command.segments": [[20.0, 30.0, float("inf")]]})
    straight = load_scenario("circle_vinyl", {"command.segments": [[20.0, 0.2, float("inf")]]})  # v_radius: inf ok
    assert straight.command.segments[0].b == float("inf")


def test_a_friction_patch_may_be_unbounded_but_not_inverted():
    half = load_scenario("circle_vinyl", {"terrain.friction_patches": [{"x_min": 0.0, "x_max": float("inf"),
                                                                         "mu_scale": 0.5}]})
    assert half.terrain.friction_patches[0].x_max == float("inf")
    with pytest.raises(SpecError) as ei:
        load_scenario("circle_vinyl", {"terrain.friction_patches": [{"y_min": 2.0, "y_max": 1.0}]})
    assert ei.value.field == "terrain.friction_patches[0].y_max" and ">= y_min = 2.0" in str(ei.value)
    with pytest.raises(SpecError, match=r"mu_scale.*in \[0, 10\]"):
        load_scenario("circle_vinyl", {"terrain.friction_patches": [{"mu_scale": -5.0}]})


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


# --------------------------------------------------------------------------- parameter sources (issue 30)
import dataclasses  # noqa: E402
import glob  # noqa: E402
import tomllib  # noqa: E402
from pathlib import Path  # noqa: E402

from bench.sources import SOURCE_KINDS, _field_name  # noqa: E402
from bench.spec import SCENARIO_DIR, Platform, Terrain, to_dict  # noqa: E402

PLATFORM_FILES = sorted(glob.glob(str(SCENARIO_DIR / "platforms" / "*.toml")))
TERRAIN_FILES = sorted(glob.glob(str(SCENARIO_DIR / "terrains" / "*.toml")))


def _leaf_fields(cls: type, prefix: str = "") -> set[str]:
    """Every parameter field of a Platform / Terrain, nested dataclasses by dotted key (independent of
    bench.sources: walks the dataclass definitions)."""
    out = set()
    for f in dataclasses.fields(cls):
        if f.name.startswith("_") or f.name in ("name", "source", "sources"):
            continue
        default = f.default_factory() if f.default_factory is not dataclasses.MISSING else f.default
        if dataclasses.is_dataclass(default):
            out |= _leaf_fields(type(default), f"{prefix}{f.name}.")
        else:
            out.add(prefix + f.name)
    return out


def _claim_ids() -> set[str]:
    ids = set()
    for path in (SCENARIO_DIR / "papers").glob("*.toml"):
        ids |= {f"{path.stem}.{c['id']}" for c in tomllib.loads(path.read_text()).get("claims", [])}
    return ids


@pytest.mark.parametrize("path", PLATFORM_FILES + TERRAIN_FILES, ids=lambda p: Path(p).stem)
def test_every_shipped_parameter_names_its_source(path):
    cls, load = (Platform, load_platform) if "/platforms/" in path else (Terrain, load_terrain)
    spec = load(path)
    assert set(spec.sources) == _leaf_fields(cls)  # every field: from the file's [sources] or the default's
    raw = tomllib.loads(Path(path).read_text())
    written = {k for k in raw if k not in ("name", "source", "sources") and not isinstance(raw[k], dict)}
    written |= {f"{k}.{j}" for k, v in raw.items() if isinstance(v, dict) and k != "sources" for j in v
                if not isinstance(v[j], dict)}
    written |= {f"{k}.{j}.{i}" for k, v in raw.items() if isinstance(v, dict) and k != "sources"
                for j, w in v.items() if isinstance(w, dict) for i in w}
    for key in written - {"dt_max"}:  # dt_max: a requirement on the scenario's step, not a terrain field
        src = spec.sources[_field_name(key)]  # slope_deg -> slope, as the loader converts it
        assert src.kind in SOURCE_KINDS and src.ref, (key, src)
    for key in set(spec.sources) - {_field_name(k) for k in written}:  # a default the file relies on says what it is
        assert not spec.sources[key].ref.startswith("default <") and " of bench.spec." not in spec.sources[key].ref, key
    claims = _claim_ids()
    for key, src in spec.sources.items():
        assert (src.kind == "chosen") == bool(src.claims), (key, src)
        for c in src.claims:  # a chosen source names claims that exist, so they become calibration targets
            assert c in claims, (key, c)


def test_the_calibration_targets_named_by_issue_30_are_marked_chosen():
    """The parameters the issue names as chosen for an outcome and kept (no independent source)."""
    p20 = load_platform("p3at_pneumatic_20psi").sources
    assert p20["motor.max_power"].kind == "chosen" and "yu2010.ramps_testbed" in p20["motor.max_power"].claims
    # issue 31: the tire's loaded rolling radius replaces the radius scales copied from Mandow (no longer chosen)
    assert p20["wheel_radius_scale_l"].kind == "testbed" and load_platform("p3at_pneumatic_20psi").wheel_radius_scale_l == 1
    assert load_platform("dubhe").sources["motor.max_current"].kind == "chosen"
    assert load_terrain("ramp_whiteboard_13p5").sources["mu_sa"].kind == "chosen"
    for name in ("asphalt", "smooth_concrete"):
        assert load_terrain(name).sources["mu_sa"].kind == "chosen"
    speed = ("wang2015.chi_speed_constant", "wang2015.chi_speed_vs_curvature")
    assert load_terrain("tile").sources["model"].claims == speed
    # re-derived from Wang 2015 Table 1 (Wang's own terrain for its tile field): no longer chosen
    t = load_terrain("tile")
    assert (t.shear_modulus, t.mu_sa, t.mu_op, t.rolling_resistance) == (0.00054, 0.4437, 0.3093, 0.0371)
    assert (t.mu_lat_ratio, t.shear_modulus_lat_ratio) == (1.0, 1.0)
    assert {t.sources[k].kind for k in ("shear_modulus", "mu_sa", "mu_op", "rolling_resistance")} == {"paper"}


def test_a_terrain_dt_max_sets_the_step_of_scenarios_that_set_none():
    """Wang's K = 0.54 mm is resolved only at dt <= 1/1920 s (tile.toml [sources]): scenarios on tile run at it
    unless they set dt, or replace the Janosi law the requirement was measured for."""
    assert load_scenario("wang_circle_grid").dt == pytest.approx(1 / 1920)
    assert load_scenario("wang_circle_grid", {"dt": 0.005}).dt == 0.005
    assert load_scenario("gap_test_coulomb").dt == pytest.approx(1 / 120)  # tile with the Coulomb law
    assert load_scenario("circle_vinyl").dt == pytest.approx(1 / 120)


def _copy_without(tmp_path, name: str, line_start: str, folder: str = "terrains") -> Path:
    text = (SCENARIO_DIR / folder / f"{name}.toml").read_text()
    kept = [ln for ln in text.splitlines() if not ln.startswith(line_start)]
    assert len(kept) == len(text.splitlines()) - 1  # exactly one line removed
    out = tmp_path / f"{name}.toml"
    out.write_text("\n".join(kept) + "\n")
    return out


def test_a_parameter_without_a_source_is_a_one_line_error_naming_file_field_value(tmp_path):
    path = _copy_without(tmp_path, "vinyl", "mu_op = {")
    with pytest.raises(SpecError) as ei:
        load_terrain(path)
    msg = str(ei.value)
    assert "\n" not in msg and msg.startswith(f"{path}: field 'mu_op' = 0.3093: no source")
    path = _copy_without(tmp_path, "p3at_solid", '"motor.max_power" = {', "platforms")
    with pytest.raises(SpecError, match=r"field 'motor.max_power' = 10.0: no source"):
        load_platform(path)
    # a scenario naming the platform fails the same way (the file is checked where it is read)
    scn = tmp_path / "s.toml"
    scn.write_text(f'platform = "{path}"\nterrain = "vinyl"\nduration = 1.0\n[command]\nkind = "rotation"\n')
    with pytest.raises(SpecError, match=r"p3at_solid.toml: field 'motor.max_power' = 10.0: no source"):
        load_scenario(scn)


@pytest.mark.parametrize("entry, fragment", [
    ('mu_op = {kind = "guess", ref = "x"}',
     "source kind 'guess' is not one of paper|datasheet|calibration|real|testbed|chosen"),
    ('mu_op = {kind = "chosen", ref = "tuned"}', "a 'chosen' source lists the claims"),
    ('mu_op = {kind = "paper", ref = ""}', "needs a ref"),
    ('mu_op = {kind = "paper", ref = "Yu", claims = ["yu2010.fig9"]}', "only a 'chosen' source lists claims"),
    ('mu_op = {kind = "chosen", ref = "x", claims = ["fig9"]}', "must be a list of"),
    ('mu_op = {kind = "paper", reference = "Yu"}', "unknown key"),
])
def test_a_malformed_source_names_file_field_value(tmp_path, entry, fragment):
    path = _copy_without(tmp_path, "vinyl", "mu_op = {")
    path.write_text(path.read_text() + entry + "\n")
    with pytest.raises(SpecError) as ei:
        load_terrain(path)
    assert str(ei.value).startswith(f"{path}: field 'mu_op' = 0.3093: ") and fragment in str(ei.value)


def test_a_source_for_a_parameter_the_file_does_not_set_is_an_error(tmp_path):
    path = tmp_path / "vinyl.toml"
    path.write_text((SCENARIO_DIR / "terrains" / "vinyl.toml").read_text()
                    + 'slope_deg = {kind = "paper", ref = "Yu Fig. 19"}\n')
    with pytest.raises(SpecError, match=r"field 'sources.slope_deg' .* a source for a parameter the file does not set"):
        load_terrain(path)


def test_a_misspelt_scenario_name_is_one_line_with_the_nearest_names():
    with pytest.raises(SpecError) as ei:
        load_scenario("circle_vinly")
    msg = str(ei.value)
    assert "field 'scenario' = 'circle_vinly'" in msg and "did you mean circle_vinyl?" in msg and "\n" not in msg
    with pytest.raises(SpecError) as ei:  # nothing near: no empty "did you mean ?"
        load_scenario("zzzzqq")
    assert "did you mean" not in str(ei.value) and "`skidbench list` shows them all" in str(ei.value)


def test_a_misspelt_parameter_is_named_not_its_source(tmp_path):
    """stall_torqe = 1.95 above a [sources] entry for stall_torque: the error names the parameter and its entry's
    name (either may be the misspelt one), not only the entry that no longer finds its parameter."""
    src = (SCENARIO_DIR / "platforms" / "p3at_pneumatic_20psi.toml").read_text()
    assert "\nstall_torque = " in src
    path = tmp_path / "bot.toml"
    path.write_text(src.replace("\nstall_torque = ", "\nstall_torqe = ", 1))
    with pytest.raises(SpecError) as ei:
        load_platform(path)
    msg = str(ei.value)
    assert "field 'motor.stall_torqe'" in msg and "entry is named motor.stall_torque" in msg and "\n" not in msg
    assert "misspelt" in msg


def test_overrides_get_an_override_source_and_leave_the_physics_hash_alone():
    from bench.sim import scenario_hash

    base = load_scenario("mandow_straight_asphalt_solid")
    # the scenario's [platform_overrides], with the source its own [sources] gives
    assert base.platform.sources["sensors.reference.kind"].kind == "paper"
    assert "Mandow 2007 Sec. IV-C" in base.platform.sources["sensors.reference.kind"].ref
    assert base.terrain.sources["mu_sa"].kind == "chosen"
    s = load_scenario("mandow_straight_asphalt_solid", {"terrain.mu_sa": 0.5, "platform.motor.max_power": 3.0})
    assert s.terrain.mu_sa == 0.5 and s.terrain.sources["mu_sa"].kind == "override"
    assert s.platform.sources["motor.max_power"].ref == "--set"
    assert s.terrain.sources["mu_op"] == base.terrain.sources["mu_op"]  # untouched fields keep theirs
    # sources are provenance: not in to_dict (run metadata, scenario hash) nor in equality
    assert "sources" not in to_dict(base)["platform"] and "sources" not in to_dict(base.terrain)
    stripped = dataclasses.replace(base.terrain, sources=type(base.terrain.sources)())
    assert stripped == base.terrain
    assert scenario_hash(dataclasses.replace(base, terrain=stripped)) == scenario_hash(base)


def test_tire_fields_convert_psi_at_the_file_boundary_and_are_range_checked(tmp_path):
    """tire_pressure_psi -> Pa (1 psi = 6894.757 Pa, NIST SP 811); the tire fields reject what is not physical and
    are --set-able; every P3-AT tire set names a source for each new parameter (issue 31)."""
    p20, p50, solid = (load_platform(n) for n in ("p3at_pneumatic_20psi", "p3at_pneumatic_50psi", "p3at_solid"))
    assert p20.tire_pressure == pytest.approx(20 * 6894.757, rel=1e-6)
    assert p50.tire_pressure == pytest.approx(50 * 6894.757, rel=1e-6)
    assert (solid.tire_pressure, p20.tire_modulus) == (0.0, 0.0) and solid.tire_modulus > 0
    for p in (p20, p50, solid):
        assert (p.cg_offset_x, p.cg_offset_y) == (-0.004, 0.0026)
        for key in ("tire_pressure", "tire_modulus", "tire_rolling_resistance", "cg_offset_x", "cg_offset_y"):
            assert p.sources[key].kind in ("paper", "testbed"), (p.name, key)
    scn = load_scenario("circle_vinyl", {"platform.tire_pressure": 2.0e5, "platform.tire_rolling_resistance": 0.01})
    assert (scn.platform.tire_pressure, scn.platform.tire_rolling_resistance) == (2.0e5, 0.01)
    assert scn.platform.sources["tire_pressure"].kind == "override"
    for key, bad in (("platform.tire_pressure", -1.0), ("platform.tire_modulus", -5.0),
                     ("platform.tire_rolling_resistance", 0.3)):
        with pytest.raises(SpecError, match=key.split(".")[1]):
            load_scenario("circle_vinyl", {key: bad})


def _scenario_with_override(tmp_path, sources: str) -> Path:
    """A scenario file in a scenario root of its own (its platform and terrain files copied) with one terrain
    override and the given [sources] lines."""
    import shutil

    for sub in ("platforms", "terrains"):
        shutil.copytree(SCENARIO_DIR / sub, tmp_path / sub)
    path = tmp_path / "ovr.toml"
    path.write_text((SCENARIO_DIR / "gap_test_coulomb.toml").read_text().split("\n# where each override")[0]
                    + "\n" + sources)
    return path


def test_a_scenario_override_without_a_source_is_a_one_line_error(tmp_path):
    path = _scenario_with_override(tmp_path, "")
    with pytest.raises(SpecError, match=r"ovr.toml.*terrain_overrides.model.*no source: add \"terrain.model\""):
        load_scenario(path, root=tmp_path)
    path = _scenario_with_override(tmp_path / "b", '[sources]\n"terrain.model" = {kind = "testbed", ref = "x"}\n'
                                   '"terrain.mu_sa" = {kind = "paper", ref = "y"}\n')
    with pytest.raises(SpecError, match=r"sources.terrain.mu_sa.*a source for no \[platform_overrides\]"):
        load_scenario(path, root=tmp_path / "b")


def test_a_scenario_override_chosen_for_a_claim_is_a_calibration_target(tmp_path):
    from bench.reproduce.sources import calibration_targets, parameter_sources

    path = _scenario_with_override(tmp_path, '[sources]\n"terrain.model" = {kind = "chosen", ref = "picked for p.q", '
                                             'claims = ["p.q"]}\n')
    scn = load_scenario(path, root=tmp_path)
    assert scn.terrain.sources["model"].kind == "chosen" and scn.terrain.sources["model"].claims == ("p.q",)
    assert [(s.file, s.parameter) for s in calibration_targets((tmp_path,))["p.q"]] == [
        (f"{tmp_path.name}/ovr.toml", "terrain.model")]
    # the shipped scenarios: every override has a source, none of them chosen today
    shipped = [s for s in parameter_sources() if s.file.startswith("scenarios/")]
    assert len(shipped) == 18 * 4 + 4 * 7 + 2 and not [s for s in shipped if s.kind == "chosen"]


def test_the_source_of_a_field_named_kind_may_be_an_unquoted_dotted_key():
    """TOML reads ``platform.sensors.reference.kind = {kind = ..., ref = ...}`` as nested tables whose innermost
    key is ``kind``: that is the field's source, not a source entry of ``reference`` (before: 'a source for no
    [platform_overrides] entry')."""
    import tomllib

    from bench.sources import override_sources

    text = ('[platform_overrides]\nsensors.reference.kind = "dgps"\n'
            '[sources]\nplatform.sensors.reference.kind = {kind = "paper", ref = "Mandow 2007 Sec. IV-B"}\n')
    got = override_sources(tomllib.loads(text), "x.toml")
    assert list(got) == ["platform.sensors.reference.kind"] and got["platform.sensors.reference.kind"].kind == "paper"
    quoted = text.replace("platform.sensors.reference.kind =", '"platform.sensors.reference.kind" =')
    assert override_sources(tomllib.loads(quoted), "x.toml") == got


def test_a_spec_without_sources_says_what_a_testbed_spec_needs(tmp_path):
    """A new user's kinematic TOML given where a testbed spec is needed (real-gap, a mapping's platform): the error
    says a [sources] table is missing and that `skidbench real` reads such a file, not 'no source' for one field."""
    p = tmp_path / "mulebot.toml"
    p.write_text("wheel_radius = 0.15\ntrack = 0.6\n")
    with pytest.raises(SpecError) as exc:
        load_platform(p)
    msg = str(exc.value)
    assert "mulebot.toml" in msg and "'sources'" in msg and "skidbench real" in msg and "\n" not in msg
