"""Two C extensions and the package layout; everything else is in pyproject.toml.

Packages: bench and methods (not the asv ``benchmarks`` folder, not tests), and the checkout's ``scenarios/`` shipped
as the package data ``bench/scenarios`` (scenario, platform, terrain and paper files), where bench.paths finds them
when skidbench runs installed.

* bench/sim/_kernel.c: the testbed's per-step arithmetic.
* methods/mandow2007/_cost.c: Mandow 2007 eq. (13), the GA's cost (numpy's segment_cost is its reference,
  agreement to 1e-12 relative and the same GA result tested: tests/methods/mandow2007/test_cost_c.py).


The Python loop of bench/sim/testbed.py is the step's reference and its fallback (a checkout without the built
extension runs it, with the same numbers). Compiled without fused multiply-add and fast math, so that the C step
does the Python loop's double operations bit for bit (tests/sim/test_kernel.py)."""
from setuptools import Extension, find_packages, setup

FLAGS = ["-O2", "-ffp-contract=off", "-fno-fast-math"]
SCENARIO_PACKAGES = ["bench.scenarios", "bench.scenarios.platforms", "bench.scenarios.terrains", "bench.scenarios.papers"]
setup(packages=find_packages(include=["bench", "bench.*", "methods", "methods.*"]) + SCENARIO_PACKAGES,
      package_dir={"bench.scenarios": "scenarios"},
      package_data={name: ["*.toml"] for name in SCENARIO_PACKAGES},
      ext_modules=[Extension("bench.sim._kernel", sources=["bench/sim/_kernel.c"], extra_compile_args=FLAGS),
                   Extension("methods.mandow2007._cost", sources=["methods/mandow2007/_cost.c"], extra_compile_args=FLAGS)])
