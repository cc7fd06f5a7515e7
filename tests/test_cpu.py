"""The CPU pin of bench.cpu: without it the same run differs between an AVX-512 and an AVX2 machine; with it the
dispatch a process inherits no longer matters, and the ``skidbench`` program pins itself."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from bench.cpu import pinned_env

REPO = Path(__file__).resolve().parents[1]
HASH = """
from bench.cpu import dispatch_state
from bench.sim import simulate
from bench.spec import load_scenario
print(dispatch_state(), simulate(load_scenario("yi_circle", {"duration": 3.0}), 1).content_hash())
"""


def _run(env: dict[str, str]) -> tuple[str, str]:
    out = subprocess.run([sys.executable, "-c", HASH], cwd=REPO, env=env, capture_output=True, text=True, check=True)
    state, digest = out.stdout.split()[-2:]
    return state, digest


def _native_features() -> dict[str, bool]:
    """numpy's CPU features as an unpinned process sees them (``make test`` runs pytest under the pin, where the
    disabled targets read False)."""
    env = {k: v for k, v in os.environ.items() if k not in ("NPY_DISABLE_CPU_FEATURES", "OPENBLAS_CORETYPE")}
    code = "import json; from numpy._core._multiarray_umath import __cpu_features__ as f; print(json.dumps(f))"
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True).stdout
    return json.loads(out)


def _has_avx512() -> bool:
    return bool(_native_features().get("X86_V4", False))


@pytest.mark.skipif(not _has_avx512(), reason="needs a CPU with numpy's X86_V4 (AVX-512) dispatch to emulate two CPUs")
def test_the_pin_makes_an_avx512_and_an_avx2_machine_agree():
    """Emulated on one CPU: the native AVX-512 dispatch and an AVX2-only one (X86_V4 and above disabled, as on a CPU
    without AVX-512) give different runs of the same scenario and seed (the cause of issue 34's mismatches); the
    pinned environment, started from either, gives one run."""
    base = {k: v for k, v in os.environ.items() if k not in ("NPY_DISABLE_CPU_FEATURES", "OPENBLAS_CORETYPE")}
    avx2 = dict(base, NPY_DISABLE_CPU_FEATURES="X86_V4 AVX512_ICL AVX512_SPR")
    native_state, native = _run(base)
    avx2_state, on_avx2 = _run(avx2)
    assert native_state.startswith("native") and avx2_state.startswith("native")
    assert native != on_avx2  # the problem the pin removes
    pinned_a, pinned_b = _run(pinned_env(base)), _run(pinned_env(avx2))
    assert pinned_a == pinned_b and pinned_a[0] == "baseline"


def test_the_program_reexecutes_itself_pinned(tmp_path):
    """``python -m bench.cli`` (what the ``skidbench`` script runs) re-executes under the pin and says so in the
    manifest check; SKIDBENCH_CPU=native keeps the native dispatch."""
    manifest = tmp_path / "m.json"
    manifest.write_text('{"runs": {}, "scenarios": {}}')
    env = {k: v for k, v in os.environ.items() if k not in ("NPY_DISABLE_CPU_FEATURES", "SKIDBENCH_CPU_PINNED")}
    out = subprocess.run([sys.executable, "-m", "bench.cli", "verify-runs", str(manifest)], cwd=REPO, env=env,
                         capture_output=True, text=True, check=True).stdout
    assert "checked under baseline" in out
    if _has_avx512():
        native = subprocess.run([sys.executable, "-m", "bench.cli", "verify-runs", str(manifest)], cwd=REPO,
                                env=dict(env, SKIDBENCH_CPU="native"), capture_output=True, text=True,
                                check=True).stdout
        assert "checked under native" in native


def test_verify_runs_on_a_missing_manifest_is_one_line(tmp_path):
    r = subprocess.run([sys.executable, "-m", "bench.cli", "verify-runs", str(tmp_path / "none.json")], cwd=REPO,
                       capture_output=True, text=True)
    assert r.returncode == 2 and "none.json" in r.stderr and "Traceback" not in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1


def test_python_m_bench_cpu_runs_a_command_pinned():
    """``python -m bench.cpu CMD`` (how ``make test`` starts pytest): CMD sees every numpy dispatch target disabled,
    so the tests' numbers are the pinned program's; without a command, a one-line usage error (exit 2)."""
    env = {k: v for k, v in os.environ.items() if k not in ("NPY_DISABLE_CPU_FEATURES", "SKIDBENCH_CPU_PINNED",
                                                            "SKIDBENCH_CPU")}
    code = "from bench.cpu import dispatch_state; print(dispatch_state())"
    out = subprocess.run([sys.executable, "-m", "bench.cpu", sys.executable, "-c", code], cwd=REPO, env=env,
                         capture_output=True, text=True, check=True).stdout.split()
    assert out[-1] == ("baseline" if _native_features().get("AVX2", False) else "native:openblas")
    r = subprocess.run([sys.executable, "-m", "bench.cpu"], cwd=REPO, env=env, capture_output=True, text=True)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1
