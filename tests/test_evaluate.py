"""`skidbench evaluate` against evo's own command line (evo_ape / evo_rpe, run as programs): the same statistics to
1e-9 for every alignment evo has (none, -a, -as), with --project_to_plane, and RPE in metres and frames."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from bench import cli

EVO_APE = Path(sys.executable).with_name("evo_ape")
EVO_RPE = Path(sys.executable).with_name("evo_rpe")
pytestmark = pytest.mark.skipif(not EVO_APE.exists(), reason="evo's command line is not installed (dev extra)")


def _tum(path: Path, t, xyz, quat) -> Path:
    path.write_text("\n".join(" ".join(repr(float(v)) for v in (ti, *p, *q)) for ti, p, q in zip(t, xyz, quat)) + "\n")
    return path


@pytest.fixture(scope="module")
def pair(tmp_path_factory) -> tuple[Path, Path]:
    """A 3-D reference (a climbing, rolling figure-8) and an estimate with a rotated, shifted, scaled and noisy copy
    of it, on other time stamps (association within 0.01 s)."""
    d = tmp_path_factory.mktemp("evo")
    rng = np.random.default_rng(4)
    t = np.arange(0.0, 30.0, 0.05)
    xyz = np.column_stack([3 * np.sin(0.2 * t), 2 * np.sin(0.4 * t), 0.02 * t])
    eul = np.column_stack([0.2 * t, 0.05 * np.sin(t), 0.03 * np.cos(0.7 * t)])
    rot = Rotation.from_euler("ZYX", eul)
    ref = _tum(d / "gt.tum", t, xyz, rot.as_quat())
    g = Rotation.from_euler("ZYX", [0.4, 0.02, -0.01])
    te = t + rng.uniform(-0.004, 0.004, t.size)
    xyz_e = 1.07 * g.apply(xyz + rng.normal(0, 0.03, xyz.shape)) + [1.0, -0.5, 0.2]
    rot_e = g * rot * Rotation.from_rotvec(rng.normal(0, 0.01, (t.size, 3)))
    est = _tum(d / "est.tum", te, xyz_e, rot_e.as_quat())
    return ref, est


def _evo(tool: Path, args: list[str], tmp: Path) -> dict:
    out = tmp / f"res{len(list(tmp.glob('res*')))}.zip"
    env = {**os.environ, "HOME": str(tmp), "MPLBACKEND": "Agg"}
    subprocess.run([str(tool), "tum", *args, "--save_results", str(out), "--no_warnings"], check=True, env=env,
                   capture_output=True, text=True)
    with zipfile.ZipFile(out) as z:
        return json.loads(z.read("stats.json"))


def _ours(args: list[str], tmp: Path) -> dict:
    out = tmp / "ours.json"
    assert cli.main(["evaluate", *args, "--json", str(out)]) == 0
    return json.loads(out.read_text())


def _same_statistics(tool: Path, pair: tuple[Path, Path], tmp: Path, ours: list[str], theirs: list[str]) -> None:
    ref, est = pair
    want = _evo(tool, [str(ref), str(est), *theirs], tmp)
    got = _ours([str(ref), str(est), *ours], tmp)
    for k in ("rmse", "mean", "median", "std", "min", "max", "sse"):
        assert got[k] == pytest.approx(want[k], rel=1e-9, abs=1e-12), k


@pytest.mark.parametrize("ours, theirs", [
    ([], []), (["--align", "se3"], ["-a"]), (["--align", "sim3"], ["-as"]),
    (["--align", "se3", "--project-to-plane"], ["-a", "--project_to_plane", "xy"]),
    (["--relation", "angle_deg", "--align", "se3"], ["-r", "angle_deg", "-a"]),
    (["--relation", "full"], ["-r", "full"]),
])
def test_ape_equals_evo_ape(pair, tmp_path, ours, theirs) -> None:
    _same_statistics(EVO_APE, pair, tmp_path, ours, theirs)


@pytest.mark.parametrize("ours, theirs", [
    (["--rpe-delta", "10", "--delta-unit", "frames"], ["-d", "10", "-u", "f"]),
    (["--rpe-delta", "1.5", "--delta-unit", "m", "--align", "se3"], ["-d", "1.5", "-u", "m", "-a"]),
    (["--rpe-delta", "5", "--relation", "angle_deg"], ["-d", "5", "-r", "angle_deg"]),
])
def test_rpe_equals_evo_rpe(pair, tmp_path, ours, theirs) -> None:
    _same_statistics(EVO_RPE, pair, tmp_path, ours, theirs)


def test_se2_on_planar_data_equals_evo_se3(tmp_path) -> None:
    """The planar alignment (not in evo) on planar trajectories: evo's 3-D Umeyama finds the same rotation."""
    t = np.arange(0.0, 20.0, 0.1)
    xyz = np.column_stack([np.cos(0.3 * t) * t, np.sin(0.3 * t) * t, np.zeros_like(t)])
    yaw = Rotation.from_euler("z", (0.3 * t)[:, None])
    ref = _tum(tmp_path / "gt.tum", t, xyz, yaw.as_quat())
    g = Rotation.from_euler("z", 0.7)
    est = _tum(tmp_path / "est.tum", t, g.apply(xyz * 1.01) + [2.0, 1.0, 0.0], (g * yaw).as_quat())
    want = _evo(EVO_APE, [str(ref), str(est), "-a"], tmp_path)
    got = _ours([str(ref), str(est), "--align", "se2"], tmp_path)
    assert got["rmse"] == pytest.approx(want["rmse"], rel=1e-9)


def test_evaluate_reads_runs_and_estimates_and_plots(tmp_path) -> None:
    from bench.sim import simulate
    from bench.spec import load_scenario

    run = tmp_path / "r.parquet"
    simulate(load_scenario("straight_0p2_vinyl", {"duration": 2.0}), 0).to_parquet(run)
    assert cli.main(["estimate", "baseline.ideal_dd", str(run), "-o", str(tmp_path / "e.csv")]) == 0
    got = _ours([str(run), str(tmp_path / "e.csv"), "--plot", str(tmp_path / "ape.png")], tmp_path)
    assert got["kind"] == "APE" and 0 < got["rmse"] < 0.1 and (tmp_path / "ape.png").stat().st_size > 10_000


@pytest.mark.parametrize("args, words", [
    (["nope.tum", "nope2.tum"], "nope.tum: column '<file>' = 'nope.tum': file not found"),
    (["{gt}", "{gt}", "--rpe-delta", "0"], "'--rpe-delta' = 0"),
])
def test_bad_input_is_one_line(pair, tmp_path, capsys, args, words) -> None:
    ref, _ = pair
    args = [a.format(gt=ref) for a in args]
    assert cli.main(["evaluate", *args]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and words in err[0]
