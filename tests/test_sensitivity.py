"""The sensitivity study (bench.reproduce.sensitivity): which verdicts a chosen testbed parameter decides.

Checked against independent expectations: a TOML edit read back by tomllib; the grouping of chosen parameters by
the claims they name; the verdict comparison on hand-made claims; the alternatives the shipped files declare (each
a value of its parameter's type, each written into a copy that the loader reads back); and the report's mark on a
headline claim that a choice decides (a fake paper, as tests/test_claims.py builds it).
"""
from __future__ import annotations

import json
import subprocess
import textwrap
import tomllib
from pathlib import Path

import pytest

from bench import reproduce as R
from bench.reproduce.sensitivity import Choice, Edit, choices, flips, papers_using, run_sensitivity, set_value
from bench.schema import SpecError, read_toml
from bench.sources import file_sources
from bench.spec import SCENARIO_DIR, Scenario, load_platform, load_scenario, load_terrain
from bench.spec_files import list_scenarios, registered
from tests.test_claims import reproduce_fake

TOML = textwrap.dedent('''
    name = "robot"
    mass = 10.0  # kg
    [motor]
    max_current = 120.0  # A: chosen
    max_power = 5.0
    [sensors.gnss]
    rate_hz = 5.0
    [sources]
    mass = {kind = "paper", ref = "x"}
''')


def test_set_value_writes_the_key_of_its_table_only_and_reads_back():
    out = set_value(TOML, "motor.max_current", 60.0)
    doc = tomllib.loads(out)
    assert doc["motor"] == {"max_current": 60.0, "max_power": 5.0} and doc["mass"] == 10.0
    assert tomllib.loads(set_value(TOML, "mass", 12.5))["mass"] == 12.5
    assert tomllib.loads(set_value(TOML, "sensors.gnss.rate_hz", 1.0))["sensors"]["gnss"]["rate_hz"] == 1.0
    assert tomllib.loads(set_value('model = "janosi"\n', "model", "coulomb"))["model"] == "coulomb"
    with pytest.raises(KeyError):
        set_value(TOML, "max_current", 1.0)  # not at the top level
    with pytest.raises(KeyError):
        set_value(TOML, "motor.stall_torque", 1.0)


def _chosen(tmp_path, extra: str = "") -> None:
    plat = tmp_path / "platforms"
    plat.mkdir(exist_ok=True)
    (tmp_path / "terrains").mkdir(exist_ok=True)
    (plat / "bot.toml").write_text(textwrap.dedent('''
        name = "bot"
        mass = 10.0
        [motor]
        max_current = 120.0
        max_power = 5.0
        [sources]
        mass = {kind = "chosen", ref = "r", claims = ["p.a"], alternative = 12.0, alternative_ref = "why m"}
        "motor.max_current" = {kind = "chosen", ref = "r", claims = ["p.a"], alternative = 60.0, alternative_ref = "w"}
        "motor.max_power" = {kind = "chosen", ref = "r", claims = ["p.b"]}
    ''') + extra)


def test_choices_group_the_parameters_chosen_for_the_same_claims(tmp_path):
    _chosen(tmp_path)
    got = choices(tmp_path)
    assert len(got) == 1  # max_power declares no alternative: not run
    c, = got
    assert c.claims == ("p.a",) and c.files == ("platforms/bot.toml",)
    assert {(e.key, e.value, e.alternative) for e in c.edits} == {("mass", 10.0, 12.0), ("motor.max_current", 120.0, 60.0)}


def test_testbed_values_with_an_alternative_are_a_choice_of_their_own(tmp_path):
    """Testbed values (no claim in view) that declare the same alternative change together, apart from the chosen
    ones; a testbed value without an alternative is not run; their choice names no claim (none is a target)."""
    _chosen(tmp_path)
    terr = tmp_path / "terrains" / "ground.toml"
    terr.write_text(textwrap.dedent('''
        name = "ground"
        mu_lat_ratio = 1.06
        shear_modulus_lat_ratio = 1.4
        rolling = 0.01
        [sources]
        mu_lat_ratio = {kind = "testbed", ref = "t", alternative = 1.0, alternative_ref = "isotropic"}
        shear_modulus_lat_ratio = {kind = "testbed", ref = "t", alternative = 1.0, alternative_ref = "isotropic"}
        rolling = {kind = "testbed", ref = "t"}
    '''))
    got = choices(tmp_path)
    assert [c.claims for c in got] == [(), ("p.a",)]
    testbed, = [c for c in got if not c.claims]
    assert {(e.file, e.key, e.value, e.alternative) for e in testbed.edits} == {
        ("terrains/ground.toml", "mu_lat_ratio", 1.06, 1.0),
        ("terrains/ground.toml", "shear_modulus_lat_ratio", 1.4, 1.0)}


@pytest.mark.parametrize("entry, field", [
    ('{kind = "paper", ref = "r", alternative = 1.0, alternative_ref = "w"}', "only a 'chosen' or 'testbed' source"),
    ('{kind = "chosen", ref = "r", claims = ["p.a"], alternative = 1.0}', "alternative_ref"),
    ('{kind = "chosen", ref = "r", claims = ["p.a"], alternative = "x", alternative_ref = "w"}', "type"),
])
def test_a_malformed_alternative_is_a_one_line_error(entry, field):
    with pytest.raises(SpecError) as exc:
        file_sources(tomllib.loads(f"mass = 1.0\n[sources]\nmass = {entry}\n"), "f.toml")
    assert field in str(exc.value) and "\n" not in str(exc.value)


def test_a_switch_takes_a_switch_as_its_alternative():
    """bool is an int to Python, not to a spec: true -> false is an alternative, true -> 5.0 is not, 1.0 -> true not."""
    src = '{kind = "chosen", ref = "r", claims = ["p.a"], alternative = %s, alternative_ref = "w"}'
    assert file_sources(tomllib.loads(f"flag = true\n[sources]\nflag = {src % 'false'}\n"), "f")["flag"].alternative \
        is False
    for value, alt in (("true", "5.0"), ("1.0", "true")):
        with pytest.raises(SpecError, match="type"):
            file_sources(tomllib.loads(f"flag = {value}\n[sources]\nflag = {src % alt}\n"), "f")


def test_every_shipped_alternative_loads_as_a_valid_spec(tmp_path):
    """Each declared alternative, written into a copy of its file, loads (a valid platform / terrain) with the value;
    a terrain's ``dt_max`` (a requirement on the step, not a terrain field) is the step of a scenario on it."""
    got = choices()
    assert got, "the shipped files declare alternatives"
    for c in got:
        for e in c.edits:
            copy = tmp_path / e.file
            copy.parent.mkdir(parents=True, exist_ok=True)
            copy.write_text(set_value((SCENARIO_DIR / e.file).read_text(), e.key, e.alternative))
            spec = (load_platform if e.file.startswith("platforms/") else load_terrain)(copy)
            if e.key == "dt_max":
                scn = tmp_path / "on_it.toml"
                scn.write_text(f'platform = "p3at_pneumatic_20psi"\nterrain = "{copy.stem}"\nduration = 1.0\n'
                               '[command]\nkind = "v_radius"\nsegments = [[1.0, 0.2, inf]]\n')
                (tmp_path / "platforms").mkdir(exist_ok=True)
                (tmp_path / "platforms" / "p3at_pneumatic_20psi.toml").write_text(
                    (SCENARIO_DIR / "platforms" / "p3at_pneumatic_20psi.toml").read_text())
                assert load_scenario(scn, root=tmp_path).dt == min(Scenario.dt, e.alternative), e.name
                continue
            obj = spec
            for part in e.key.split("."):
                obj = getattr(obj, part)
            assert obj == e.alternative, (e.name, obj)


def test_flips_lists_the_changed_verdicts_of_the_papers_run():
    base = {"p.a": {"verdict": "holds"}, "p.b": {"verdict": "does not hold"}, "q.c": {"verdict": "holds"}}
    alt = {"p.a": {"verdict": "does not hold", "measured": "1 < 0"}, "p.b": {"verdict": "does not hold"},
           "q.c": {"verdict": "does not hold"}}
    rows = flips(base, alt, ["p"])
    assert [(r["claim"], r["base"], r["alternative"]) for r in rows] == [("p.a", "holds", "does not hold")]
    # a calibration target keeps its verdict string: its numbers' verdict (holds) is what may change
    base = {"p.t": {"verdict": "calibration target", "holds": True}, "p.u": {"verdict": "calibration target",
                                                                            "holds": False}}
    alt = {"p.t": {"verdict": "calibration target", "holds": False}, "p.u": {"verdict": "calibration target",
                                                                            "holds": False}}
    assert [r["claim"] for r in flips(base, alt, ["p"])] == ["p.t"]


def test_papers_using_match_the_platform_and_terrain_names():
    c = Choice(("p.a",), (Edit("platforms/dubhe.toml", "motor.max_current", 120.0, 60.0, "w"),))
    manifest = {"scenarios": {
        "1": {"paper": "liu2020", "platform": {"name": "dubhe"}, "terrain": {"name": "dirt"}},
        "2": {"paper": "yi2009", "platform": {"name": "yi2009_4wd"}, "terrain": {"name": "dubhe"}},
        "3": {"paper": "league", "platform": {"name": "dubhe"}, "terrain": {"name": "dirt"}}}}
    assert papers_using(c, manifest, ["liu2020", "yi2009"]) == ["liu2020", "yi2009"]
    assert papers_using(c, manifest, ["yu2010"]) == []


def test_the_study_and_the_report_mark_a_verdict_a_choice_decides(tmp_path, monkeypatch):
    """run_sensitivity with the child run replaced by hand-made claims: a flip of a claim that is not a calibration
    target is listed as decided, a flip of a target is not; the report marks the headline row and the paper."""
    out, _res = reproduce_fake(tmp_path, monkeypatch)
    base = json.loads((out / "claims.json").read_text())["claims"]
    assert base["p.fails"]["verdict"] == "does not hold" and base["p.order"]["verdict"] == "calibration target"

    study = tmp_path / "study"  # a scenario folder of its own (test_claims' files are not all strict specs)
    study.mkdir()
    _chosen(study)
    alt = {k: dict(v) for k, v in base.items()}
    alt["p.fails"]["verdict"] = "holds"
    alt["p.order"]["verdict"] = "does not hold"
    monkeypatch.setattr("bench.reproduce.sensitivity.run_choice", lambda c, papers, workers, root: alt)
    monkeypatch.setattr("bench.reproduce.paper.list_papers", lambda: ["p"])
    manifest = {"scenarios": {"1": {"paper": "p", "platform": {"name": "bot"}, "terrain": {"name": "vinyl"}}}}
    (out / "runs_manifest.json").write_text(json.dumps(manifest))
    doc = run_sensitivity(out / "extended", base_file=out / "claims.json", root=study)
    rows = {r["claim"]: r["target"] for c in doc["choices"] for r in c["flips"]}
    assert rows == {"p.fails": False, "p.order": True}
    assert "p.fails" in (out / "extended" / "sensitivity.md").read_text()

    R.reproduce(["p"], results_dir=out, cache_dir=tmp_path / "cache" / "runs", log=lambda s: None)
    report = (out / "REPORT.md").read_text()
    head = report.split("## Headline claims")[1].split("## Per paper")[0]
    fails = next(ln for ln in head.splitlines() if "double < speed" in ln)
    order = next(ln for ln in head.splitlines() if "speed < double" in ln)
    assert "decided by a testbed choice" in fails and "bot.mass" in fails
    assert "decided by a testbed choice" not in order
    assert "verdicts decided by a testbed choice" in report.split("## Per paper")[1]
    details = (out / "p" / "claims_details.md").read_text()
    fails_part = details.split('<a id="claim-fails"></a>')[1]
    order_part = details.split('<a id="claim-order"></a>')[1].split("<a id=")[0]
    assert "decided by a testbed choice: at bot.mass = 12.0, bot.motor.max_current = 60.0" in fails_part
    assert "it holds:" in fails_part and "decided by a testbed choice" not in order_part


def test_the_study_runs_with_extended_only(capsys):
    from bench.cli import main
    from bench.cli.reproduce import EXTENDED_EXTRAS, EXTENDED_ONLY, EXTRAS

    assert "sensitivity" in EXTRAS and "sensitivity" in EXTENDED_EXTRAS and "sensitivity" in EXTENDED_ONLY
    assert main(["reproduce", "sensitivity"]) == 2
    assert "runs with --extended only" in capsys.readouterr().err


def test_the_study_skips_without_a_full_run_and_reruns_when_it_changes(tmp_path, monkeypatch, capsys):
    """No results/claims.json: the extra says so and writes nothing (the extended run goes on); its marker's key
    follows the full run's files, so a new full run with the same code runs the study again."""
    import bench.reproduce.sensitivity as S
    from bench.cli import reproduce as CR

    claims, manifest = tmp_path / "claims.json", tmp_path / "runs_manifest.json"
    monkeypatch.setattr(S, "base_files", lambda: (claims, manifest))
    out = tmp_path / "extended"
    CR._extra_sensitivity(out, False, workers=1, extended=True)
    assert "skipped: no full run" in capsys.readouterr().out and not out.exists()
    monkeypatch.setattr(CR, "data_root", lambda: tmp_path)
    k0 = CR._extra_marker("sensitivity", out, False, True)
    claims.write_text('{"claims": {}}')
    manifest.write_text('{"scenarios": {}}')
    k1 = CR._extra_marker("sensitivity", out, False, True)
    claims.write_text('{"claims": {"p.a": {"verdict": "holds"}}}')
    assert len({k0, k1, CR._extra_marker("sensitivity", out, False, True)}) == 3


def test_the_child_run_reads_the_alternative_and_writes_only_its_own_folder(tmp_path):
    """run_choice for real (a child `skidbench reproduce` on a copy of the scenario folder): a fake paper's steady
    speed on the straight drops when the P3-AT's current limit takes a tiny alternative, the copy with no edit gives
    the speed of the scenario folder itself, and nothing is written under results/."""
    import shutil

    from bench.paths import default_results
    from bench.reproduce.sensitivity import run_choice
    from tests.test_claims import FAKE

    root = tmp_path / "scenarios"
    shutil.copytree(SCENARIO_DIR, root)
    (root / "papers" / "p.toml").write_text(FAKE)
    before = {p: p.stat().st_mtime_ns for p in default_results().glob("*.json")}
    same = run_choice(Choice(("p.x",), ()), ["p"], 1, root)
    weak = run_choice(Choice(("p.x",), (Edit("platforms/p3at_pneumatic_20psi.toml", "motor.max_current", 5.5, 0.2,
                                             "a drive too weak to keep 0.2 m/s"),)), ["p"], 1, root)

    def speed(claims):
        return float(claims["p.order"]["measured"].split("speed = ")[1].split()[0])

    assert speed(same) == pytest.approx(0.2, rel=0.05)
    assert speed(weak) < 0.9 * speed(same)
    assert {p: p.stat().st_mtime_ns for p in default_results().glob("*.json")} == before


def test_a_choice_of_many_parameters_keeps_the_headline_cell_short():
    """The lateral tire ratios of ten terrains (20 parameters) name their keys and the number of files; a choice of
    up to three is named in full; the committed report has no cell over the limit."""
    from bench.report.cells import long_cells
    from bench.reproduce.report import choice_label

    many = [{"name": f"t{i}.{k}"} for i in range(10) for k in ("mu_lat_ratio", "shear_modulus_lat_ratio")]
    assert choice_label(many) == ["mu_lat_ratio, shear_modulus_lat_ratio of 10 files"]
    few = [{"name": "dubhe.motor.max_current"}, {"name": "tile.model"}]
    assert choice_label(few) == ["dubhe.motor.max_current", "tile.model"]
    report = Path(__file__).resolve().parent.parent / "results" / "REPORT.md"
    assert long_cells(report.read_text()) == []


def test_no_shipped_scenario_on_a_terrain_with_a_step_requirement_sets_its_own_step():
    """A terrain's ``dt_max`` (its own, or a sensitivity alternative's) applies only to a scenario that sets no ``dt``
    (bench.spec._apply_dt_max): a shipped scenario on such a terrain that set one would run the stiff contact at a step
    that does not resolve it, silently."""
    with_step = {t for t in registered("terrain") if "dt_max" in read_toml(SCENARIO_DIR / "terrains" / f"{t}.toml")}
    assert {"tile", "vinyl", "lab_lemniscate"} <= with_step
    on_them = {name: raw for name in list_scenarios() if (raw := read_toml(SCENARIO_DIR / f"{name}.toml")).get(
        "terrain") in with_step}
    assert on_them, "no scenario on those terrains: the check would be vacuous"
    assert [name for name, raw in on_them.items() if "dt" in raw] == []


def test_the_study_says_whether_its_base_ran_other_code(tmp_path):
    """code_differs against a throwaway git history: a commit that only writes results/ runs the same code as its
    parent, one that edits code does not, an unknown commit cannot be compared; the study's header says which."""
    from bench.reproduce.provenance import code_differs
    from bench.reproduce.sensitivity import _markdown

    def git(*args: str) -> str:
        return subprocess.run(["git", "-c", "user.email=t@t", "-c", "user.name=t", *args], cwd=tmp_path, check=True,
                              capture_output=True, text=True).stdout.strip()

    git("init", "-q")
    (tmp_path / "code.py").write_text("x = 1\n")
    git("add", "-A"), git("commit", "-qm", "code")
    code = git("rev-parse", "HEAD")
    (tmp_path / "results").mkdir()
    (tmp_path / "results" / "claims.json").write_text("{}\n")
    git("add", "-A"), git("commit", "-qm", "results")
    results = git("rev-parse", "HEAD")
    (tmp_path / "code.py").write_text("x = 2\n")
    git("add", "-A"), git("commit", "-qm", "more code")
    more = git("rev-parse", "HEAD")
    assert code_differs(code, results, tmp_path) is False and code_differs(results, results, tmp_path) is False
    assert code_differs(results, more, tmp_path) is True and code_differs(results, results + "+dirty", tmp_path) is True
    assert code_differs(code, "0" * 40, tmp_path) is None
    assert code_differs("unknown", "unknown", tmp_path) is None and code_differs("", "", tmp_path) is None

    def header(differs):
        doc = {"base_file": "claims.json", "base_commit": code, "commit": results, "code_differs": differs,
               "choices": []}
        return next(ln for ln in _markdown(doc).splitlines() if ln.startswith("Base:"))
    assert "results/ only: the same code" in header(False)
    assert "**different code**" in header(True) and "not compared here" in header(None)
