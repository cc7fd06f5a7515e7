"""The testbed's C step (bench/sim/_kernel.c); everything else is in pyproject.toml.

The Python loop of bench/sim/testbed.py is the step's reference and its fallback (a checkout without the built
extension runs it, with the same numbers). Compiled without fused multiply-add and fast math, so that the C step
does the Python loop's double operations bit for bit (tests/sim/test_kernel.py)."""
from setuptools import Extension, setup

setup(ext_modules=[Extension("bench.sim._kernel", sources=["bench/sim/_kernel.c"],
                             extra_compile_args=["-O2", "-ffp-contract=off", "-fno-fast-math"])])
