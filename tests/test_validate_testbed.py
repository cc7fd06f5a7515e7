"""`skidbench validate-testbed`: every physics check of the papers passes (Wang Table 3 trend,
closed-form pure rotation, Yu Fig. 9, Fig. 17 saturation, Figs. 18-20 ramps)."""
from __future__ import annotations

import json
import subprocess
import sys


def test_validate_testbed_json_all_pass():
    out = subprocess.run([sys.executable, "-m", "bench.cli", "validate-testbed", "--json", "--quick"],
                         capture_output=True, text=True)
    report = json.loads(out.stdout)
    failed = [c["name"] for c in report["checks"] if not c["passed"]]
    assert not failed, failed
    assert out.returncode == 0
    names = {c["name"] for c in report["checks"]}
    assert {"chi_in_band", "chi_non_increasing", "chi_speed_invariant", "coulomb_rotation_closed_form",
            "torque_decreases_with_radius", "saturation_speed", "ramp_5p4_holds_speed", "ramp_15_decelerates",
            "ramp_13p5_fails"} <= names
