"""Progress of ``skidbench reproduce``: one bar per stage (each paper, each extra), with an ETA.

Stages report events, from this process or from the pool processes they run in (through a queue: :class:`Sink`):

    ("start", stage)                      the stage began
    ("step", stage, done, total, label)   e.g. a paper's table 3 of 7
    ("sim", stage, done, total)           runs simulated for the stage so far
    ("done", stage, from_cache)           the stage ended

A bar measures the stage's expected time when the last run (``timing.json`` of the results folder) says how long it
took, so its ETA is that time less the elapsed (held at 99 % when the stage takes longer); otherwise the bar counts
the stage's steps (its ETA then from their rate), and a stage without steps shows a pulsing bar with its elapsed
time.  The description says what the stage is doing (table, runs simulated).  A stage that comes from the result
cache ends at once at 100 %; no bar is left at 0 % (the rerun of a fully cached reproduction showed a "runs" bar
stuck at 0 %: nothing was simulated, so nothing ever updated it).
"""
from __future__ import annotations

import json
import queue
import threading
import time
from pathlib import Path
from typing import Any, Callable, Mapping

__all__ = ["StageBars", "Sink", "expected_seconds", "pump"]

MIN_EXPECTED = 2.0  # [s] a stage expected to take less gets a step bar (an ETA of a second tells nothing)


def expected_seconds(results_dir: Path, quick: bool) -> dict[str, float]:
    """Seconds per stage of the last run that computed it (``timing.json``: this run's stage when it did not come from
    the cache, else the last cold run's)."""
    path = Path(results_dir) / ("timing_quick.json" if quick else "timing.json")
    try:
        doc = json.loads(path.read_text())
    except (OSError, ValueError):
        return {}
    out: dict[str, float] = {}
    for run in (doc.get("last_cold") or {}, doc.get("this_run") or {}):  # this run's wins where it computed
        for name, st in (run.get("stages") or {}).items():
            if isinstance(st, dict) and not st.get("from_cache") and isinstance(st.get("seconds"), (int, float)):
                out[name] = float(st["seconds"])
    return out


class StageBars:
    """Bars of a :class:`rich.progress.Progress`, one per stage, driven by :meth:`event` and :meth:`tick`."""

    def __init__(self, progress: Any, expected: Mapping[str, float] | None = None,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.progress = progress
        self.expected = dict(expected or {})
        self.clock = clock
        self.tasks: dict[str, int] = {}
        self.started: dict[str, float] = {}
        self.detail: dict[str, str] = {}
        self.steps: dict[str, tuple[int, int]] = {}
        self.finished: set[str] = set()

    def _timed(self, stage: str) -> bool:
        return self.expected.get(stage, 0.0) >= MIN_EXPECTED

    def _describe(self, stage: str) -> str:
        d = self.detail.get(stage)
        return f"{stage}: {d}" if d else stage

    def _start(self, stage: str) -> None:
        if stage in self.tasks:
            return
        self.started[stage] = self.clock()
        total = self.expected[stage] if self._timed(stage) else None
        self.tasks[stage] = self.progress.add_task(stage, total=total)

    def event(self, kind: str, stage: str, *args: Any) -> None:
        """Apply one event (see the module docstring)."""
        self._start(stage)
        task = self.tasks[stage]
        if kind == "step":
            done, total, label = args
            self.steps[stage] = (int(done), int(total))
            self.detail[stage] = f"{label} ({done}/{total})" if label else f"{done}/{total}"
            if not self._timed(stage):
                self.progress.update(task, completed=done, total=total)
        elif kind == "sim":
            done, total = args
            self.detail[stage] = f"simulating runs {done}/{total}"
            if not self._timed(stage) and stage not in self.steps:
                self.progress.update(task, completed=done, total=total)
        elif kind == "done":
            from_cache = bool(args[0]) if args else False
            took = self.clock() - self.started[stage]
            self.detail[stage] = "from the result cache" if from_cache else f"done in {took:.1f} s"
            self.finished.add(stage)
            total = next(t.total for t in self.progress.tasks if t.id == task) or 1
            self.progress.update(task, total=total, completed=total)
        elif kind != "start":
            raise ValueError(f"unknown progress event {kind!r}")
        self.progress.update(task, description=self._describe(stage))
        self.tick()

    def tick(self) -> None:
        """Advance the time-measured bars of the running stages."""
        now = self.clock()
        for stage, task in self.tasks.items():
            if stage in self.finished or not self._timed(stage):
                continue
            exp = self.expected[stage]
            self.progress.update(task, completed=min(now - self.started[stage], 0.99 * exp))


class Sink:
    """A picklable event sender for pool processes: calls put a tuple on a ``multiprocessing.Manager`` queue
    (``None``: events are dropped)."""

    def __init__(self, q: Any = None, stage: str | None = None) -> None:
        self.q, self.stage = q, stage

    def __call__(self, kind: str, stage: str, *args: Any) -> None:
        if self.q is not None:
            self.q.put((kind, stage, *args))

    def for_stage(self, stage: str) -> "Sink":
        return Sink(self.q, stage)

    def sim(self, done: int, total: int) -> None:
        """A :class:`bench.reproduce.runner.Runner` progress callback for this sink's stage."""
        if self.stage is not None:
            self("sim", self.stage, done, total)

    def step(self, done: int, total: int, label: str = "") -> None:
        if self.stage is not None:
            self("step", self.stage, done, total, label)


def pump(q: Any, bars: StageBars, stop: threading.Event, lock: threading.Lock, period: float = 0.5) -> None:
    """Thread body: apply the queue's events to ``bars`` until ``stop`` is set and the queue is empty."""
    while True:
        try:
            ev = q.get(timeout=period)
        except queue.Empty:
            if stop.is_set():
                return
            with lock:
                bars.tick()
            continue
        except (EOFError, OSError, BrokenPipeError):  # the manager went away
            return
        with lock:
            bars.event(*ev)
