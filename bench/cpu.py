"""The CPU code paths the numbers are made on: numpy's SIMD dispatch and OpenBLAS's kernel, pinned.

numpy picks, at import, the widest SIMD variant of its loops the CPU has (``__cpu_dispatch__``: on numpy 2.4
x86-64 wheels X86_V3 = AVX2/FMA3, X86_V4 = AVX-512, AVX512_ICL, AVX512_SPR), and those variants differ in the
last bits of, e.g., ``np.sin`` and reductions; OpenBLAS (DYNAMIC_ARCH) picks its kernels by CPU model the same
way.  The testbed feeds numpy-made wheel references into a chaotic contact simulation, so a last-bit difference
on another CPU became a different run (issue 34: 1 of 46 committed runs re-simulated to the same hash on
another machine; all 46 with the AVX-512 dispatch disabled).

``skidbench`` therefore re-executes itself once with :func:`pinned_env`: every numpy dispatch target disabled
(numpy runs its baseline code, the same instructions on every x86-64 CPU that has the baseline, X86_V2 =
SSE4.2 for numpy 2.4) and OpenBLAS held to its Haswell kernels (on a CPU with AVX2; a CPU without it keeps
OpenBLAS's own choice, and :func:`dispatch_state` says ``native:openblas``).  Processes forked from it (the local pools)
inherit the pin; a Dask worker started by hand needs the same environment (README).  The run cache key carries
:func:`dispatch_state`, so a run made under another dispatch is never served to a pinned reproduction.
``SKIDBENCH_CPU=native`` skips the pin (faster numpy on wide-SIMD CPUs; runs then match only on that CPU).
"""
from __future__ import annotations

import os
import sys

_MARK = "SKIDBENCH_CPU_PINNED"  # set in the re-executed process: never re-execute twice


def _numpy_cpu() -> tuple[list[str], dict[str, bool]]:
    from numpy._core._multiarray_umath import __cpu_dispatch__, __cpu_features__

    return list(__cpu_dispatch__), dict(__cpu_features__)


def pinned_env(environ: dict[str, str] | None = None) -> dict[str, str]:
    """``environ`` (default ``os.environ``) with numpy's dispatch targets disabled and OpenBLAS pinned."""
    env = dict(os.environ if environ is None else environ)
    env.pop("NPY_ENABLE_CPU_FEATURES", None)  # numpy refuses to import with both variables set
    targets, features = _numpy_cpu()
    env["NPY_DISABLE_CPU_FEATURES"] = " ".join(targets)
    if features.get("AVX2", False):
        env["OPENBLAS_CORETYPE"] = "Haswell"
    env.setdefault("OPENBLAS_NUM_THREADS", "1")  # the matrices are small; the pools already use every core
    env[_MARK] = "1"
    return env


def dispatch_state() -> str:
    """``"baseline"`` when no numpy dispatch target is active in this process (pinned, or a CPU without any)
    and OpenBLAS is pinned or irrelevant; else ``"native:<active targets>"``."""
    targets, features = _numpy_cpu()
    active = [t for t in targets if features.get(t, False)]
    if active:
        return "native:" + "+".join(active)
    if os.environ.get("OPENBLAS_CORETYPE", "").lower() != "haswell":
        return "native:openblas"  # OpenBLAS picks its kernel by CPU model (a CPU without AVX2 cannot be pinned here)
    return "baseline"


def reexec_pinned(argv: list[str] | None = None) -> None:
    """Replace this process by this package's ``bench.cli`` main with ``argv`` (the interpreter's flags kept) under
    :func:`pinned_env`, unless it is pinned
    already, was re-executed once (:data:`_MARK`) or ``SKIDBENCH_CPU=native``.  Returns only when it does not
    re-execute."""
    if os.environ.get("SKIDBENCH_CPU", "").lower() == "native" or os.environ.get(_MARK):
        return
    if dispatch_state() == "baseline":
        return
    import subprocess
    from pathlib import Path

    args = sys.argv[1:] if argv is None else argv
    # the package that is running, not whatever `bench/` the working directory holds (`-m` would put it first)
    root = str(Path(__file__).resolve().parents[1])
    code = f"import sys; sys.path.insert(0, {root!r}); from bench.cli import main; sys.exit(main())"
    sys.stdout.flush()
    sys.stderr.flush()
    os.execve(sys.executable, [sys.executable, *subprocess._args_from_interpreter_flags(), "-c", code, *args],
              pinned_env())


def main(argv: list[str] | None = None) -> int:
    """``python -m bench.cpu CMD [ARGS...]``: run CMD under :func:`pinned_env` (``make test`` runs pytest so, and
    the tests then see the numbers the pinned ``skidbench`` makes, on any x86-64 CPU)."""
    args = sys.argv[1:] if argv is None else argv
    if not args:
        print("usage: python -m bench.cpu CMD [ARGS...]", file=sys.stderr)
        return 2
    env = pinned_env() if os.environ.get("SKIDBENCH_CPU", "").lower() != "native" else dict(os.environ)
    sys.stdout.flush()
    sys.stderr.flush()
    os.execvpe(args[0], args, env)
    return 0  # not reached


if __name__ == "__main__":
    sys.exit(main())
