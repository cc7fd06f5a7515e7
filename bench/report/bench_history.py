"""The speed history: one line per ``make bench`` in ``results/bench_history.jsonl``.

``make bench`` runs the pytest-benchmark suite (``tests/bench``) into ``.benchmarks/latest.json`` and then

    python -m bench.report.bench_history .benchmarks/latest.json [--out results/bench_history.jsonl]

appends one line: the commit (``git rev-parse HEAD``, ``+dirty`` when the tree has uncommitted changes, as
:func:`bench.reproduce.provenance.git_commit` writes it), the date the benchmarks ran (pytest-benchmark's
``datetime``, UTC, to the second), the CPU model, the Python version and per benchmark its ``mean`` and
``stddev`` (seconds) and ``rounds``::

    {"benchmarks": {"test_integrate_se2": {"mean": 0.0123, "rounds": 41, "stddev": 0.0004}, ...},
     "commit": "5c2a280...", "cpu": "AMD EPYC", "date": "2026-12-03T14:05:00+00:00", "python": "3.11.2"}

The speed page of the dashboard (:mod:`bench.report.speed_page`) charts each benchmark's mean over these
lines.  (The ``bench`` field of ``history.jsonl`` is whatever ``.benchmarks/latest.json`` held when a
reproduce ran, usually nothing; it is not charted.)  The file is rewritten atomically with the new line
appended; a malformed input is a :class:`bench.spec.SpecError` naming the file, the field and the value.
"""
from __future__ import annotations

import argparse
import json
import math
import re
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Sequence

from bench.report.io import atomic_write_text, dumps_json, jsonl_objects
from bench.spec import SpecError

__all__ = ["BenchStat", "BenchRun", "read_benchmark_json", "record_bench", "load_bench_history", "main"]


@dataclass(frozen=True)
class BenchStat:
    """One benchmark of one ``make bench``: seconds per call."""

    mean: float
    stddev: float
    rounds: int


@dataclass(frozen=True)
class BenchRun:
    """One line of bench_history.jsonl."""

    index: int
    commit: str
    date: str
    cpu: str
    python: str
    benchmarks: Mapping[str, BenchStat]

    @property
    def day(self) -> str:
        return self.date[:10]

    def to_json(self) -> dict[str, Any]:
        return {"commit": self.commit, "date": self.date, "cpu": self.cpu, "python": self.python,
                "benchmarks": {k: {"mean": v.mean, "stddev": v.stddev, "rounds": v.rounds}
                               for k, v in sorted(self.benchmarks.items())}}


def _number(path: Path, where: str, value: Any, positive: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) \
            or value < 0 or (positive and value == 0):
        raise SpecError(path, where, value, "a finite non-negative number of seconds" if not positive
                        else "a positive number")
    return float(value)


def _stat(path: Path, where: str, obj: Any) -> BenchStat:
    if not isinstance(obj, dict):
        raise SpecError(path, where, obj, "an object with mean, stddev, rounds")
    for key in ("mean", "stddev", "rounds"):
        if key not in obj:
            raise SpecError(path, f"{where}.{key}", None, "required field is missing")
    rounds = obj["rounds"]
    if isinstance(rounds, bool) or not isinstance(rounds, int) or rounds < 1:
        raise SpecError(path, f"{where}.rounds", rounds, "a positive whole number")
    stddev = obj["stddev"]
    if stddev is None and rounds == 1:  # one round has no spread
        stddev = 0.0
    return BenchStat(_number(path, f"{where}.mean", obj["mean"], positive=True),
                     _number(path, f"{where}.stddev", stddev), rounds)


def _cpu_model() -> str:
    """This machine's CPU model (``/proc/cpuinfo``'s model name, else platform.processor())."""
    import platform

    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.lower().startswith(("model name", "hardware", "cpu model")):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine() or "unknown"


def read_benchmark_json(path: str | Path) -> tuple[str, str, str, dict[str, BenchStat]]:
    """(date, CPU model, Python version, {benchmark name: stats}) of a pytest-benchmark JSON file
    (``--benchmark-json``).  A benchmark is named by its test name (``test_x[param]``), by its full
    name where two files share a test name."""
    path = Path(path)
    if not path.is_file():
        raise SpecError(path, "<file>", str(path), "no benchmark JSON: run `make bench` "
                                                   "(pytest --benchmark-json=.benchmarks/latest.json)")
    try:
        doc = json.loads(path.read_text())
    except ValueError as exc:
        raise SpecError(path, "<file>", str(path), f"malformed JSON: {exc}") from None
    if not isinstance(doc, dict) or not isinstance(doc.get("benchmarks"), list):
        raise SpecError(path, "benchmarks", None if not isinstance(doc, dict) else doc.get("benchmarks"),
                        "a pytest-benchmark JSON file (a list of benchmarks)")
    date = doc.get("datetime")
    if not isinstance(date, str) or len(date) < 19:
        raise SpecError(path, "datetime", date, "an ISO date (pytest-benchmark writes it)")
    date = re.sub(r"(T\d\d:\d\d:\d\d)\.\d+", r"\1", date, count=1)  # to the second
    info = doc.get("machine_info") or {}
    cpu = ((info.get("cpu") or {}).get("brand_raw") if isinstance(info, dict) else None) or _cpu_model()
    python = str(info.get("python_version", "")) if isinstance(info, dict) else ""
    names: dict[str, list[str]] = {}
    for i, b in enumerate(doc["benchmarks"]):
        if not isinstance(b, dict) or not isinstance(b.get("name"), str):
            raise SpecError(path, f"benchmarks[{i}].name", b.get("name") if isinstance(b, dict) else b,
                            "a benchmark with a name")
        names.setdefault(b["name"], []).append(str(b.get("fullname", b["name"])))
    stats: dict[str, BenchStat] = {}
    for i, b in enumerate(doc["benchmarks"]):
        key = b["name"] if len(names[b["name"]]) == 1 else str(b.get("fullname", b["name"]))
        stats[key] = _stat(path, f"benchmarks[{i}].stats ({b['name']})", b.get("stats"))
    if not stats:
        raise SpecError(path, "benchmarks", [], "no benchmark ran (pytest --benchmark-only found none)")
    return date, str(cpu), python, stats


def load_bench_history(path: str | Path) -> list[BenchRun]:
    """The lines of bench_history.jsonl in file order (no file: an empty list)."""
    path = Path(path)
    if not path.is_file():
        return []
    out: list[BenchRun] = []
    for lineno, obj in jsonl_objects(path, ("commit", "date", "benchmarks")):
        if not isinstance(obj["benchmarks"], dict):
            raise SpecError(path, f"line {lineno}: benchmarks", obj["benchmarks"], "an object {name: stats}")
        stats = {str(k): _stat(path, f"line {lineno}: benchmarks.{k}", v) for k, v in obj["benchmarks"].items()}
        out.append(BenchRun(index=len(out), commit=str(obj["commit"]), date=str(obj["date"]),
                            cpu=str(obj.get("cpu", "")), python=str(obj.get("python", "")), benchmarks=stats))
    return out


def record_bench(latest: str | Path, out: str | Path, commit: str | None = None) -> BenchRun:
    """Append the benchmarks of ``latest`` (pytest-benchmark JSON) as one line to ``out``; the commit is
    the checkout's (:func:`bench.reproduce.provenance.git_commit`) unless given."""
    date, cpu, python, stats = read_benchmark_json(latest)
    if commit is None:
        from bench.reproduce.provenance import git_commit

        commit = git_commit()
    out = Path(out)
    previous = load_bench_history(out)  # a malformed file is refused before anything is written
    run = BenchRun(index=len(previous), commit=commit, date=date, cpu=cpu, python=python, benchmarks=stats)
    text = out.read_text() if out.is_file() else ""
    if text and not text.endswith("\n"):
        text += "\n"
    atomic_write_text(out, text + dumps_json(run.to_json(), sort_keys=True) + "\n")
    return run


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.report.bench_history",
                                 description="append a pytest-benchmark JSON file to the speed history")
    ap.add_argument("latest", type=Path, help="pytest-benchmark JSON (make bench: .benchmarks/latest.json)")
    ap.add_argument("--out", type=Path, default=None, help="history file (default results/bench_history.jsonl)")
    ap.add_argument("--commit", default=None, help="commit id to record (default: git rev-parse HEAD, +dirty)")
    a = ap.parse_args(argv)
    if a.out is None:
        from bench.paths import default_results

        a.out = default_results() / "bench_history.jsonl"
    try:
        run = record_bench(a.latest, a.out, a.commit)
    except SpecError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"appended {len(run.benchmarks)} benchmarks at {run.commit[:12]} ({run.cpu}) to {a.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
