"""Real robot logs: DRIVE window tables, the real-data benchmark, the gap workflow on real logs.

- :mod:`bench.real.drive`       DRIVE window tables -> per-window arrays (DriveWindows) and Runs
- :mod:`bench.real.windows`     the window protocol (WindowModel, a plugin's ``window_models``) and its primitives
- :mod:`bench.real.benchmark`   the real-data benchmark: split, fit, score (models from the registry's plugins)
- :mod:`bench.real.chi`         measured chi by curvature-ratio bin, Wang's published curve, the testbed's chi
- :mod:`bench.real.report`      the benchmark's markdown report, CSV tables and figures
- :mod:`bench.real.adapter`     a Run-based plugin scored on windows (PluginModel)
- :mod:`bench.real.gap`         the gap workflow (bench.gap) on the real data; ``python -m bench.real.gap --full``
- :mod:`bench.real.held_out`    its held-out scoring
- :mod:`bench.real.gap_report`  its markdown report and figure
- :mod:`bench.real.io`          atomic file and figure outputs
"""
