"""The plugin example of docs/plugins.md, run as written: calibrated on one simulated-style run it recovers the
effective track it was built with and dead-reckons another run; its window models fit the same scale on a DRIVE
table (the synthetic robot of tests/test_real_cli.py, chi = 1.6: Wang's yaw rate (v_r - v_l) / (chi B)) and
predict its windows' end poses."""
from __future__ import annotations

import re
import sys
import types
from pathlib import Path

import numpy as np
import pytest

from bench.kinematics import integrate_se2
from bench.real.drive import import_drive_windows
from bench.real.windows import end_errors
from bench.registry import calibrate, estimate
from bench.run import from_arrays
from tests.fixtures.encoders import readings

DOC = Path(__file__).resolve().parents[1] / "docs" / "plugins.md"


@pytest.fixture(scope="module")
def example() -> dict:
    """The doc's code block as a module of its own (dataclasses look their module up)."""
    code = re.search(r"```python\n(.*?)```", DOC.read_text(), re.S).group(1)
    mod = types.ModuleType("docs_plugins_example")
    sys.modules[mod.__name__] = mod
    exec(compile(code, str(DOC), "exec", dont_inherit=True), mod.__dict__)
    yield mod.__dict__
    del sys.modules[mod.__name__]


def _run(seed: int, scale: float, r: float = 0.1, track: float = 0.5):
    """A robot whose yaw rate is r (w_r - w_l) / (scale B): encoders at 100 Hz, a reference pose at every tick."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 20.0, 0.01)
    wl = 4.0 + 2.0 * np.sin(0.3 * t + rng.uniform(0, 6))
    wr = 4.0 + 2.0 * np.cos(0.2 * t + rng.uniform(0, 6))
    vx = r * (wl + wr) / 2
    wz = r * (wr - wl) / (scale * track)
    x, y, yaw = integrate_se2(t, vx, np.zeros_like(t), wz)
    meta = {"id": f"doc{seed}", "platform": {"name": "doc_robot", "wheel_radius": r, "track": track}}
    enc_l, enc_r = readings(wl), readings(wr)
    return from_arrays({"t": t, "enc_wl": enc_l, "enc_wr": enc_r, "ref_x": x, "ref_y": y, "ref_yaw": yaw}, meta)


def test_the_example_recovers_its_track_on_runs(example):
    m = calibrate(example["ScaledTrack"](), [_run(1, 1.4)])
    assert m.scale == pytest.approx(1.4, rel=1e-3)
    run = _run(2, 1.4)
    est = estimate(m, run)
    end = np.hypot(est["x"][-1] - run["ref_x"][-1], est["y"][-1] - run["ref_y"][-1])
    nominal = estimate(example["ScaledTrack"](), run)  # scale 1: the nominal track
    end_nominal = np.hypot(nominal["x"][-1] - run["ref_x"][-1], nominal["y"][-1] - run["ref_y"][-1])
    assert end < 0.01 * end_nominal + 1e-3


def test_the_example_window_model_fits_the_tables_chi(example, tmp_path):
    from tests.test_real_cli import B, CHI, R, _log, _table

    path = tmp_path / "t.parquet"
    _table(_log(n_steps=12)).to_parquet(path)
    w = import_drive_windows(path)
    model, = example["ScaledTrack"]().window_models(R, B)
    fitted = model.fit(w)
    assert fitted.params()["scale"] == pytest.approx(CHI, rel=0.02)
    e_fit = np.median(end_errors(fitted.predict(w), w)[0])
    e_nom = np.median(end_errors(model.predict(w), w)[0])
    assert e_fit < 0.2 * e_nom
