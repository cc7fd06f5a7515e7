"""``skidbench list``, ``simulate``, ``validate-testbed``, ``estimate``: the testbed and the methods on a run log.

    skidbench list [--json]
    skidbench simulate SCENARIO --seed N [--set key=value ...] -o run.parquet
    skidbench validate-testbed [--json] [--quick] [--calibration]
    skidbench estimate METHOD RUN.parquet [--calibrate RUN ...] -o est.csv

Registered into :data:`bench.cli.COMMANDS` on import.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from bench.cli import _progress, command, count, parse_sets
from bench.report.io import dumps_json


# ------------------------------------------------------------------------------------------ list
def _list_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--json", action="store_true")


def _list(a: argparse.Namespace) -> int:
    from bench import registry
    from bench.spec import list_scenarios, registered

    methods = []
    for name, ep in registry.discover().items():
        try:
            m = ep.load()()
            methods.append({"name": name, "paper": getattr(m, "paper", ""), "requires": sorted(m.requires)})
        except Exception as exc:  # a broken third-party plugin must not hide the others
            methods.append({"name": name, "paper": f"(failed to load: {exc})", "requires": []})
    out = {
        "scenarios": list_scenarios(),
        "platforms": registered("platform"),
        "terrains": registered("terrain"),
        "methods": methods,
    }
    if a.json:
        print(dumps_json(out, indent=2))
        return 0
    from rich.console import Console
    from rich.table import Table

    con = Console()
    for key in ("scenarios", "platforms", "terrains"):
        con.print(f"[bold]{key}[/bold]: " + ", ".join(out[key]))
    from rich.table import Column

    tab = Table(Column("method", no_wrap=True), "paper", "requires")  # a method's name whole: it is what one types
    for m in methods:
        tab.add_row(m["name"], m["paper"], ", ".join(m["requires"]))
    con.print(tab)
    return 0


command("list", "scenarios, platforms, terrains and registered methods")((_list_args, _list))


# ------------------------------------------------------------------------------------------ simulate
def _sim_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("scenario", help="scenario name (scenarios/<name>.toml) or path")
    p.add_argument("--seed", type=count(0), default=0)
    p.add_argument("--set", dest="sets", action="append", metavar="KEY=VALUE",
                   help="override any spec field, e.g. --set terrain.mu_sa=0.5")
    p.add_argument("-o", "--output", required=True, type=Path)


def _simulate(a: argparse.Namespace) -> int:
    from bench.sim import simulate
    from bench.spec import load_scenario

    scn = load_scenario(a.scenario, parse_sets(a.sets))
    with _progress() as prog:
        task = prog.add_task(f"simulate {scn.id} seed {a.seed}", total=1.0)
        run = simulate(scn, a.seed, progress=lambda f: prog.update(task, completed=f))
    run.to_parquet(a.output)
    print(f"wrote {a.output} ({len(run.data)} rows, hash {run.content_hash()[:12]})")
    return 0


command("simulate", "simulate a scenario with a seed into a Parquet run log")((_sim_args, _simulate))


# ------------------------------------------------------------------------------------------ validate
def _val_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--json", action="store_true", help="print the checks as JSON")
    p.add_argument("--quick", action="store_true", help="fewer speeds in the calibration chi grid")
    p.add_argument("--calibration", action="store_true",
                   help="also compute the calibration checks (the papers' figures on the testbed; no verdict)")


def _validate(a: argparse.Namespace) -> int:
    from dataclasses import asdict

    from bench.sim.validate import KNOWN_DEFECTS, run_calibration, run_checks, unexpected_failures

    log = (lambda s: print(s, file=sys.stderr)) if not a.json else (lambda s: None)
    checks = run_checks(progress=log, quick=a.quick)
    calib = run_calibration(progress=log, quick=a.quick) if a.calibration else []
    known = {c.name: KNOWN_DEFECTS[c.name] for c in checks if not c.passed and c.name in KNOWN_DEFECTS}
    if a.json:
        print(dumps_json({"passed": all(c.passed for c in checks), "known_defects": known,
                          "unexpected_failures": [c.name for c in unexpected_failures(checks)],
                          "checks": [asdict(c) for c in checks], "calibration": [asdict(c) for c in calib]}, indent=1))
    else:
        from rich.console import Console
        from rich.table import Table

        tab = Table("check", "result", "measured", "expected", "source")
        for c in checks:
            meas = c.measured if not isinstance(c.measured, (dict, list)) else json.dumps(c.measured)[:60] + "..."
            result = ("[green]pass[/green]" if c.passed else "[yellow]FAIL: known defect[/yellow]" if c.name in known
                      else "[red]FAIL[/red]")
            tab.add_row(c.name, result, str(meas), c.expected, c.source)
        for c in calib:
            meas = c.measured if not isinstance(c.measured, (dict, list)) else json.dumps(c.measured)[:60] + "..."
            tab.add_row(c.name, "calibration", str(meas), f"paper: {c.paper}", c.source)
        Console().print(tab)
        for name, why in known.items():
            print(f"{name}: a known testbed defect, not a broken install: {why}")
    return 1 if unexpected_failures(checks) else 0


command("validate-testbed", "physics checks of the testbed against closed forms "
        "(--calibration: the papers' figures, no verdict)")((_val_args, _validate))


# ------------------------------------------------------------------------------------------ estimate
def _est_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("method")
    p.add_argument("run", type=Path)
    p.add_argument("--calibrate", nargs="*", type=Path, default=[], help="calibration runs (never the scored run)")
    p.add_argument("-o", "--output", required=True, type=Path)


def _estimate(a: argparse.Namespace) -> int:
    from bench import registry
    from bench.report.io import atomic_write_text
    from bench.run import Run

    method = registry.get(a.method)
    if a.calibrate:
        method = registry.calibrate(method, [Run.from_parquet(p).validate() for p in a.calibrate])
    run = Run.from_parquet(a.run).validate()
    try:
        est = registry.estimate(method, run)
    except registry.NotCalibratedError as exc:
        if a.calibrate:  # calibrated and still not: the method's defect, to see whole
            raise
        # the method's parameters come from calibration runs (Mandow's GA, Liu's ICR fit, ...); any other exception
        # is the method's own defect, shown whole
        print(f"error: {a.run}: {a.method} cannot estimate uncalibrated ({exc}); give calibration runs with "
              "--calibrate RUN [RUN ...]", file=sys.stderr)
        return 2
    atomic_write_text(a.output, est.data.to_csv(index=False))
    print(f"wrote {a.output} ({len(est.data)} rows)")
    return 0


command("estimate", "run a method on a run log")((_est_args, _estimate))
