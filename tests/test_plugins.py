"""The plugin mechanism: a third-party package adds a method through an entry point; the CLI
lists it and runs it; calibration runs are refused for scoring."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from bench import registry

REPO = Path(__file__).resolve().parents[1]


def _thirdparty_dist(tmp_path: Path) -> Path:
    """A minimal installed distribution (dist-info) declaring one skidbench method."""
    d = tmp_path / "site"
    info = d / "thirdparty_skid-0.1.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: thirdparty-skid\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text('[skidbench.methods]\nthirdparty.echo = tests.fixtures.thirdparty:Echo\n')
    return d


def _env(site: Path) -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(site), str(REPO), env.get("PYTHONPATH", "")])
    return env


def test_third_party_method_is_discovered_listed_and_run(tmp_path):
    site = _thirdparty_dist(tmp_path)
    out = subprocess.run([sys.executable, "-m", "bench.cli", "list", "--json"], capture_output=True, text=True,
                         env=_env(site), check=True)
    methods = {m["name"]: m for m in json.loads(out.stdout)["methods"]}
    assert methods["thirdparty.echo"]["paper"].startswith("A. Nobody")
    assert methods["thirdparty.echo"]["requires"] == ["enc_wl", "enc_wr"]
    assert "liu2020.mi_ukf" in methods and "mandow2007.asymmetric_ga" in methods  # ours too
    run = tmp_path / "run.parquet"
    subprocess.run([sys.executable, "-m", "bench.cli", "simulate", "circle_vinyl", "--set", "duration=3.0",
                    "-o", str(run)], check=True, capture_output=True, env=_env(site))
    est = tmp_path / "est.csv"
    out = subprocess.run([sys.executable, "-m", "bench.cli", "estimate", "thirdparty.echo", str(run), "-o", str(est)],
                         capture_output=True, text=True, env=_env(site))
    assert out.returncode == 0, out.stderr
    header = est.read_text().splitlines()[0].split(",")
    assert header[:4] == ["t", "x", "y", "yaw"]


def test_every_registered_method_satisfies_the_protocol():
    for name in registry.discover():
        m = registry.get(name)
        assert isinstance(m, registry.Method), name
        assert m.name == name and m.paper and m.requires, name


def test_estimate_cli_refuses_to_score_a_calibration_run(tmp_path):
    a, b = tmp_path / "a.parquet", tmp_path / "b.parquet"
    for path, seed in ((a, "0"), (b, "1")):
        subprocess.run([sys.executable, "-m", "bench.cli", "simulate", "mandow_rotation_asphalt_pneumatic_20psi",
                        "--seed", seed, "--set", "duration=4.0", "-o", str(path)], check=True, capture_output=True)
    ok = subprocess.run([sys.executable, "-m", "bench.cli", "estimate", "wang2015.constant_chi", str(b),
                         "--calibrate", str(a), "-o", str(tmp_path / "e.csv")], capture_output=True, text=True)
    assert ok.returncode == 0, ok.stderr
    with pytest.raises(registry.CalibrationLeak, match="calibrated on"):
        from bench.run import Run

        run = Run.from_parquet(a)
        m = registry.calibrate(registry.get("wang2015.constant_chi"), [run])
        registry.estimate(m, run)


def test_unknown_method_is_a_clear_error(tmp_path):
    out = subprocess.run([sys.executable, "-m", "bench.cli", "estimate", "nobody.nothing", str(tmp_path / "x.parquet"),
                          "-o", str(tmp_path / "e.csv")], capture_output=True, text=True)
    assert out.returncode == 2 and "unknown method 'nobody.nothing'" in out.stderr
