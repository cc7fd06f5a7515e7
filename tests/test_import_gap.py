"""Issue 8's "an imported log runs through the gap workflow": a testbed run written as a CSV in a logger's own units,
imported with ``bench.formats.import_csv`` and handed to ``bench.gap.find_gap`` like any measured run."""
from __future__ import annotations

import math

import numpy as np
import pytest

from bench.formats import import_csv
from bench.gap import catalogue as C
from bench.gap import find_gap

SCN = "gap_dev_coulomb"  # development scenario of the gap tests (P3-AT, 20 psi, vinyl; laser reference)
BIAS = 0.02  # rad/s, hidden gyro bias

MAPPING = """
run_id = "imported"
[time]
column = "stamp_ms"
unit = "ms"
[platform]
name = "p3at_pneumatic_20psi"
[wheels]
left = "wl_rpm"
right = "wr_rpm"
unit = "rpm"
[commands]
left = "cmd_l_rpm"
right = "cmd_r_rpm"
unit = "rpm"
[imu]
ax = "acc_x_g"
ay = "acc_y_g"
az = "acc_z_g"
gz = "gyro_z_dps"
accel_unit = "g"
gyro_unit = "deg/s"
[reference]
x = "laser_x_cm"
y = "laser_y_cm"
yaw = "laser_yaw_deg"
position_unit = "cm"
yaw_unit = "deg"
"""

RPM = 60.0 / (2 * math.pi)
COLUMNS = {  # CSV column: (Run channel, factor SI -> the logger's unit)
    "wl_rpm": ("enc_wl", RPM), "wr_rpm": ("enc_wr", RPM), "cmd_l_rpm": ("cmd_wl", RPM), "cmd_r_rpm": ("cmd_wr", RPM),
    "acc_x_g": ("imu_ax", 1 / 9.80665), "acc_y_g": ("imu_ay", 1 / 9.80665), "acc_z_g": ("imu_az", 1 / 9.80665),
    "gyro_z_dps": ("imu_gz", 180 / math.pi), "laser_x_cm": ("ref_x", 100.0), "laser_y_cm": ("ref_y", 100.0),
    "laser_yaw_deg": ("ref_yaw", 180 / math.pi),
}


def _write_csv(path, run) -> None:
    """One row per log tick; an empty cell where a sensor has no sample (its own rate)."""
    cols = {"stamp_ms": run.t * 1000.0} | {name: run[ch] * k for name, (ch, k) in COLUMNS.items()}
    lines = [",".join(cols)]
    for i in range(run.t.size):
        lines.append(",".join("" if not np.isfinite(v[i]) else repr(float(v[i])) for v in cols.values()))
    path.write_text("\n".join(lines) + "\n")


def test_an_imported_csv_log_runs_through_the_gap_workflow(sim, tmp_path):
    """A run with a hidden gyro bias, exported in ms, rpm, g, deg/s, cm and deg and imported back: the workflow
    names the bias and fits it to the closed form on the run itself (mean measured minus true yaw rate, as in
    tests/test_gap.py), and the imported channels equal the run's within the CSV's float text."""
    measured = sim(SCN, 4, **{"platform__sensors__imu__gyro_bias_z": BIAS})
    (tmp_path / "map.toml").write_text(MAPPING)
    _write_csv(tmp_path / "log.csv", measured)
    imported = import_csv(tmp_path / "log.csv", tmp_path / "map.toml")
    for _, (ch, _k) in COLUMNS.items():
        np.testing.assert_allclose(imported[ch], measured[ch], rtol=1e-12, atol=1e-12, err_msg=ch)
    res = find_gap(imported, SCN, catalogue=(C.get("gyro_bias"), C.get("encoder_scale")), workers=1)
    t, gz = measured.samples("imu_gz")
    expected = float(np.mean(gz - np.interp(t, measured.t, measured["truth_wz"])))
    assert res.named == ["gyro_bias"]
    assert res.effects[0]["parameters"]["gyro_bias_z"] == pytest.approx(expected, abs=2e-5)
    assert expected == pytest.approx(BIAS, abs=2e-3)  # the closed form is the hidden bias, up to the gyro noise
