"""The league's tables (``results/league.md``, ``results/league.csv``): one table per sensor group, ranked within it.

A method is compared only with methods that read the same sensors while they estimate (its plugin's ``requires``
less the channels it reads once for its start pose, ``start_pose_channels``): a filter that fuses GNSS fixes
throughout a run is not "better" than wheel odometry because of its method.  Every method's calibration may read
the reference sensor of its calibration set (bench/reproduce/league.py), so the groups differ only in what the
estimate reads.

Per cell: the mean position RMS over the seeds and its 95 % bootstrap interval; "diverged at t = ..." (time and
log step of the first seed that left the bound of :func:`bench.metrics.divergence`) instead of a number; the reason
in words when the method cannot run there.  Per method: the median of its means over the scenarios where it has
one, and its rank in the group by the median over the scenarios where every method of the group has a number.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Iterable, Mapping

import numpy as np

from bench import registry
from bench.metrics.position import DIVERGENCE_FLOOR
from bench.reproduce.league import Cell

# channel prefix -> sensor family
FAMILIES = {"enc_": "wheels", "cmd_": "drive", "tau_": "drive", "imu_": "imu", "gnss_": "gnss"}


@dataclass(frozen=True)
class SensorGroup:
    """Methods whose estimate reads one of ``families`` (sets of sensor families of :data:`FAMILIES`)."""

    title: str
    families: tuple[frozenset[str], ...]
    reads: str  # one line: what the methods of the group may read


SENSOR_GROUPS = (
    SensorGroup("Wheel odometry", (frozenset({"wheels"}),),
                "the wheel-encoder speeds, and a start pose (the first reference pose; Liu's En-DR and ICR: the first "
                "GNSS fix, nothing from the GNSS after it)"),
    SensorGroup("Wheels + IMU", (frozenset({"wheels", "imu"}),),
                "the wheel-encoder speeds and the IMU (accelerometer and gyro), and a start pose"),
    SensorGroup("Wheels + IMU + GNSS", (frozenset({"wheels", "imu", "gnss"}), frozenset({"wheels", "gnss"})),
                "the wheel-encoder speeds, the IMU and every GNSS fix (position, velocity, heading) of the run"),
    SensorGroup("Dynamic model (no odometry)", (frozenset({"drive"}),),
                "no pose or speed sensor: the wheel-speed commands (closed loop) and the measured motor torques (open "
                "loop) drive the model, from a start pose; a prediction, not an estimate"),
)


def families(method: str) -> frozenset[str]:
    """The sensor families a registered method reads while it estimates."""
    plugin = registry.get(method)
    reads = set(plugin.requires) - set(getattr(plugin, "start_pose_channels", frozenset()))
    return frozenset(fam for ch in reads for prefix, fam in FAMILIES.items() if ch.startswith(prefix))


def group_of(method: str) -> SensorGroup:
    """The :data:`SENSOR_GROUPS` entry of a method; a method that reads another mix of sensors (a user's plugin)
    gets a group of its own, named after what it reads."""
    fam = families(method)
    for g in SENSOR_GROUPS:
        if fam in g.families:
            return g
    names = " + ".join(sorted(fam)) or "no sensor"
    return SensorGroup(f"Other: {names}", (fam,), f"the channels {', '.join(sorted(registry.get(method).requires))}")


def _fmt(x: float) -> str:
    return f"{x:.3g}"


def cell_text(c: Cell, summary: tuple[float, float, float] | None = None) -> str:
    """What a table cell shows (at most 290 characters); ``summary``: ``c.summary()`` when already computed."""
    if c.error:
        return c.error if len(c.error) <= 290 else c.error[:287] + "..."
    if c.diverged:
        seed, t, step, _, _ = min(c.diverged, key=lambda d: d[1])
        return f"diverged at t = {t:.2f} s (step {step}, seed {seed}; {len(c.diverged)} of {len(c.values)} seeds)"
    mean, lo, hi = summary or c.summary()
    if not math.isfinite(mean):
        return "no finite score"
    return f"{_fmt(mean)} [{_fmt(lo)}, {_fmt(hi)}]"


def median_over_scenarios(cells: Iterable[Cell]) -> tuple[float, int]:
    """The median of a method's per-scenario means (scenarios where it has a number) and how many there are."""
    return _median(c.summary()[0] for c in cells)


def _median(means: Iterable[float]) -> tuple[float, int]:
    finite = [m for m in means if math.isfinite(m)]
    return (float(np.median(finite)), len(finite)) if finite else (math.nan, 0)


def _notes(cells: list[Cell], n_scenarios: int) -> list[str]:
    """One line per distinct note: the methods it applies to, by the scenarios ("every scenario" when all)."""
    by_text: dict[str, dict[str, list[str]]] = {}
    for c in cells:
        if c.note:
            by_text.setdefault(c.note, {}).setdefault(c.method, []).append(c.scenario)
    lines = []
    for text, per_method in by_text.items():
        by_where: dict[str, list[str]] = {}
        for m, s in per_method.items():
            by_where.setdefault("every scenario" if len(s) == n_scenarios else ", ".join(s), []).append(m)
        where = "; ".join(f"{', '.join(ms)} on {w}" for w, ms in by_where.items())
        lines.append(f"- {where}: {text}")
    return lines


def league_markdown(cells: list[Cell], n_seeds: int, extended: bool = False,
                    columns: Mapping[str, str] | None = None) -> str:
    """The league report: one ranked table per sensor group.  ``columns``: scenario -> "platform, terrain"."""
    scen = list(dict.fromkeys(c.scenario for c in cells))
    by = {(c.method, c.scenario): c for c in cells}
    summ = {key: c.summary() for key, c in by.items()}  # one bootstrap per cell (each is 2000 resamples)
    mean = {key: s[0] for key, s in summ.items()}
    groups: dict[str, tuple[SensorGroup, list[str]]] = {}
    for m in dict.fromkeys(c.method for c in cells):
        g = group_of(m)
        groups.setdefault(g.title, (g, []))[1].append(m)
    known = [g.title for g in SENSOR_GROUPS]
    groups = dict(sorted(groups.items(), key=lambda kv: known.index(kv[0]) if kv[0] in known else len(known)))
    cols = columns or {}
    head = " | ".join(f"{s}<br>{cols[s]}" if s in cols else s for s in scen)
    lines = [
        "# League table: position RMS against the testbed truth [m]", "",
        f"Mean and 95% bootstrap interval over {n_seeds} seeds per scenario (column: scenario, then its platform and "
        "terrain); lower is better. Each method is calibrated on a separate calibration set of the scenario's "
        "platform and terrain (bench/reproduce/league.py) and ranked only against the methods that read the same "
        "sensors (one table per group). "
        + ("The papers' configurations, the baselines and skidbench's own consistent configurations (*_consistent)."
           if extended else "The papers' configurations and the baselines (skidbench's own consistent configurations: "
           "`skidbench reproduce league --extended`, results/extended/league.md)."),
        "",
        f"Median: of the method's means over the scenarios (of k when it has numbers on fewer); the rank compares "
        f"methods on the same scenarios (said per group). Bold: the best mean of a column within the group. A cell says \"diverged at t\" when an "
        f"estimate's position error went past the path length the robot had travelled (at least {DIVERGENCE_FLOOR:g} m) "
        "and stayed past it to the end, or the estimate ended in NaN (bench.metrics.divergence; t and the log step "
        "of the first seed that did); such a cell has no number and no rank.",
    ]
    for title, (g, meths) in groups.items():
        med = {m: _median(mean[(m, s)] for s in scen if (m, s) in by) for m in meths}
        common = [s for s in scen if all((m, s) in by and math.isfinite(mean[(m, s)]) for m in meths)]
        key = {m: _median(mean[(m, s)] for s in common)[0] if common else med[m][0] for m in meths}
        order = sorted(meths, key=lambda m: (not math.isfinite(key[m]), key[m] if math.isfinite(key[m]) else 0, m))
        best = {}
        for s in scen:
            means = [(mean[(m, s)], m) for m in meths if (m, s) in by and math.isfinite(mean[(m, s)])]
            best[s] = min(means)[1] if len(means) > 1 else None
        ranked_by = ("the median over all scenarios" if len(common) == len(scen) else
                     f"the median over the {len(common)} scenarios where every method here has a number "
                     f"({', '.join(common)})" if common else "each method's own median (no scenario has a number "
                     "for every method here)")
        lines += ["", f"## {title}", "", f"Methods here read {g.reads}. Ranked by {ranked_by}.", "",
                  "| rank | method | median | " + head + " |", "|---|---|---|" + "---|" * len(scen)]
        rank = 0
        for m in order:
            value, k = med[m]
            rank_txt = str(rank := rank + 1) if math.isfinite(key[m]) else "-"
            med_txt = "-" if not math.isfinite(value) else _fmt(value) + ("" if k == len(scen) else f" (of {k})")
            row = [rank_txt, m, med_txt]
            for s in scen:
                c = by.get((m, s))
                txt = "" if c is None else cell_text(c, summ[(m, s)])
                row.append(f"**{txt}**" if best[s] == m and c is not None and not c.error else txt)
            lines.append("| " + " | ".join(row) + " |")
    notes = _notes(cells, len(scen))
    if notes:
        lines += ["", "Notes:", *notes]
    return "\n".join(lines) + "\n"


def league_csv(cells: list[Cell]) -> str:
    """Every cell, one row: the group, the mean and interval (NaN when diverged), each seed's RMS, where each
    diverged seed left the bound (seed@t/step), the error."""
    out = ["method,group,scenario,mean,ci_low,ci_high,n,values,diverged,error"]
    group = {m: group_of(m).title for m in dict.fromkeys(c.method for c in cells)}  # a registry lookup per method
    for c in cells:
        mean, lo, hi = c.summary()
        vals = ";".join(f"{v:.6g}" for v in c.values)
        div = ";".join(f"{seed}@{t:.3f}s/{step}" for seed, t, step, _, _ in c.diverged)
        err = c.error.replace('"', "'")
        out.append(f"{c.method},{group[c.method]},{c.scenario},{mean:.6g},{lo:.6g},{hi:.6g},"
                   f"{len(c.values)},{vals},{div},\"{err}\"")
    return "\n".join(out) + "\n"
