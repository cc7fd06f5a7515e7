"""The gap workflow on several measured runs at once: one model, one set of effects, fitted to all of them.

A real log rarely offers one long stretch that covers the robot's whole command space: the DRIVE Husky table is
201 six-second command steps, and its calibration half has no more than 6 of them in a row.  Fitted to one
stretch the workflow sees two spin turns and names what explains those; fitted to several steps, each replayed on
its own from its own measured initial state (as the held-out steps are scored), it sees straight runs, gentle and
tight turns together.

:class:`SegmentSpace` is a :class:`~bench.gap.residuals.ResidualSpace` whose channels are the segments'
concatenated: segment ``k``'s samples on the time axis shifted by ``offsets[k]`` (each segment starts on a
boundary of the ``block``-s time blocks, so the two-fold cross-validation and the block jackknife cut within
segments, never across one), its pose aligned on its own start (:meth:`SegmentSpace.align_pose`), each channel
normalised by the noise scale pooled over the segments (the RMS of theirs, weighted by sample counts).  The cost
is then the mean over every segment's samples, comparable with ``J_noise`` as for one run.

:class:`SegmentEvaluator` has the :class:`~bench.gap.fit.Evaluator` interface the selection uses (``scn``,
``space``, ``signals``, ``z``, ``cost``, ``trace``, ``prefetch``, ``store``, ``workers``, ``n_sims``): a model
configuration is simulated once per segment (in the process pool when ``workers > 1``) and its signals are
concatenated as the measured channels are.  Every effect of the catalogue is a spec change or a sensor error,
the same for every segment, so one configuration is one model of the robot.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np

from bench.gap.catalogue import ModelConfig
from bench.gap.fit import Evaluator, _pool, _trace_task
from bench.gap.residuals import ResidualSpace


@dataclass(frozen=True)
class SegmentSpace(ResidualSpace):
    """Residual space of several runs, concatenated per channel (module docstring)."""

    parts: tuple[ResidualSpace, ...] = ()
    offsets: tuple[float, ...] = ()

    def split(self, model: Mapping[str, np.ndarray]) -> list[dict[str, np.ndarray]]:
        """``model`` (concatenated channels) cut into one dict per segment."""
        out: list[dict[str, np.ndarray]] = [{} for _ in self.parts]
        for c in self.channels:
            if c not in model:
                continue
            k0 = 0
            for i, p in enumerate(self.parts):
                n = p.meas[c].size
                out[i][c] = np.asarray(model[c])[k0:k0 + n]
                k0 += n
        return out

    def join(self, parts: Sequence[Mapping[str, np.ndarray]]) -> dict[str, np.ndarray]:
        """Per-segment channel dicts concatenated in segment order (the channels of this space)."""
        return {c: np.concatenate([np.asarray(p[c], float) for p in parts]) for c in self.channels
                if all(c in p for p in parts)}

    def run_starts(self, channel: str) -> tuple[int, ...]:
        """Index of each segment's first sample in ``channel``."""
        sizes = [p.meas[channel].size for p in self.parts]
        return tuple(int(k) for k in np.cumsum([0] + sizes[:-1]))

    def align_pose(self, model: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Each segment's pose aligned on its own start (:meth:`ResidualSpace.align_pose` of its part)."""
        aligned = [p.align_pose(m) for p, m in zip(self.parts, self.split(model))]
        out = dict(model)
        out.update(self.join(aligned))
        return out


def segment_space(parts: Sequence[ResidualSpace]) -> SegmentSpace:
    """The :class:`SegmentSpace` of ``parts`` (one per run): the channels every part has; time offsets on block
    boundaries; noise scales pooled (RMS weighted by sample counts)."""
    if not parts:
        raise ValueError("no segment to fit")
    first = parts[0]
    chans = tuple(c for c in first.channels if all(c in p.channels for p in parts))
    if not chans:
        return SegmentSpace((), {}, {}, {}, {}, {}, {}, first.regime_names, (), parts=tuple(parts))
    offsets, start = [], 0.0
    for p in parts:
        offsets.append(start)
        end = start + max(float(p.t[c][-1]) for c in p.channels)
        start = math.ceil((end + 1e-9) / first.block) * first.block
        start += first.block if start - end < 0.5 * first.block else 0.0  # at least half a block between segments
    t = {c: np.concatenate([p.t[c] + o for p, o in zip(parts, offsets)]) for c in chans}
    meas = {c: np.concatenate([np.asarray(p.meas[c], float) for p in parts]) for c in chans}
    regime = {c: np.concatenate([p.regime[c] for p in parts]) for c in chans}

    def pooled(attr: str, c: str) -> float:
        n = np.array([p.meas[c].size for p in parts], float)
        v = np.array([getattr(p, attr)[c] for p in parts], float)
        return float(math.sqrt(np.sum(n * v**2) / np.sum(n)))

    sigma_hat = {c: pooled("sigma_hat", c) for c in chans}
    sigma = {c: pooled("sigma", c) for c in chans}
    missing = tuple(sorted(set().union(*(p.missing for p in parts)) | {c for p in parts for c in p.channels
                                                                           if c not in chans}))
    return SegmentSpace(chans, t, meas, sigma_hat, sigma, {c: first.weight[c] for c in chans}, regime,
                        first.regime_names, missing, block=first.block, parts=tuple(parts), offsets=tuple(offsets))


class SegmentEvaluator:
    """Cached model evaluations over several segments (module docstring); the interface of
    :class:`~bench.gap.fit.Evaluator` that :mod:`bench.gap.select` and :mod:`bench.gap.fit` use."""

    def __init__(self, parts: Sequence[Evaluator], workers: int = 1):
        self.parts = list(parts)
        for ev in self.parts:
            ev.workers = 1  # the segments' simulations are batched here (the parts are this evaluator's own)
        self.space = segment_space([ev.space for ev in self.parts])
        self.scn = self.parts[0].scn  # effects change spec fields the segments share (platform, terrain, sensors)
        self.workers = max(1, int(workers))
        self.n_sims = 0

    def trace(self, overrides: tuple) -> tuple[dict[str, np.ndarray], ...]:
        out = []
        for ev in self.parts:
            before = ev.n_sims
            out.append(ev.trace(overrides))
            self.n_sims += ev.n_sims - before
        return tuple(out)

    def prefetch(self, configs: Sequence[ModelConfig]) -> None:
        """Simulate every segment of the configurations not cached yet (in parallel when workers > 1)."""
        todo = []
        for c in configs:
            for i, ev in enumerate(self.parts):
                if c.overrides not in ev._cache and (i, c.overrides) not in todo:
                    todo.append((i, c.overrides))
        if not todo:
            return
        tasks = [(self.parts[i].trace_fn, self.parts[i].scn, o) for i, o in todo]
        if self.workers > 1 and len(todo) > 1:
            with _pool(min(self.workers, len(todo))) as ex:
                results = list(ex.map(_trace_task, tasks))
        else:
            results = [_trace_task(a) for a in tasks]
        for (i, o), r in zip(todo, results):
            self.parts[i].store({o: r})
            self.parts[i].n_sims += 1
            self.n_sims += 1

    def store(self, traces: Mapping[tuple, Sequence[dict[str, np.ndarray]]]) -> None:
        for k, per in traces.items():
            for ev, tr in zip(self.parts, per):
                ev.store({k: tr})

    def signals(self, cfg: ModelConfig) -> dict[str, np.ndarray]:
        self.prefetch([cfg])
        return self.space.join([ev.signals(cfg) for ev in self.parts])

    def z(self, cfg: ModelConfig) -> np.ndarray:
        return self.space.zvec(self.signals(cfg))

    def cost(self, cfg: ModelConfig) -> float:
        z = self.z(cfg)
        return float(z @ z)


def segment_evaluator(runs: Sequence[Any], scenario: Any, workers: int,
                      channels: Sequence[str] | None = None) -> SegmentEvaluator:
    """A :class:`SegmentEvaluator` of the measured ``runs`` (truth columns dropped) against ``scenario``'s
    testbed model, each run replayed from its own measured initial state; ``channels`` restricts the residual
    channels.  Runs that share no residual channel are a one-line :class:`~bench.run.RunError`."""
    from bench.gap.model import measured_grid, replay_scenario, testbed_trace
    from bench.gap.regimes import regimes_for
    from bench.gap.residuals import build_space
    from bench.run import RunError

    parts = []
    for run in runs:
        run = run.without_truth()
        run.validate()
        rscn, init = replay_scenario(run, scenario)
        space = build_space(run, regimes_for(scenario.platform), channels=tuple(channels) if channels else None,
                            required=True)
        parts.append(Evaluator(rscn, measured_grid(run, space.t, init, scenario), space, testbed_trace, workers=1))
    out = SegmentEvaluator(parts, workers=workers)
    if not out.space.channels:
        raise RunError(runs[0].where, "<channels>", [list(p.space.channels) for p in parts],
                       "the runs share no residual channel")
    return out


__all__ = ["SegmentSpace", "SegmentEvaluator", "segment_space", "segment_evaluator"]
