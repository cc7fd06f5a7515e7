"""Mandow 2007 Sec. III: the genetic algorithm that minimises J(K) of eq. (13), and a second optimiser.

The published GA codes each parameter of K as an 8-bit string (40-bit chromosomes, Sec. IV-C); here
pygad with a fixed seed (:func:`identify_ga`).  Beside it (not in the paper), scipy's differential
evolution on continuous K within the same ranges (:func:`identify_de`).

Implementation choice the paper leaves open (documented, configurable): gene ranges are not published:
:meth:`GeneRanges.for_track` (x_ICR in [0.4 B, 1.2 B] per side, y_ICRv in [-B/4, B/4], alpha in
[0.75, 1.15]); 8 bits each, decoded linearly; Gray coding is on by default (the paper does not state the
bit code; plain binary via ``GaSettings(gray_code=False)``).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np
from numpy.typing import ArrayLike

from bench.run import Run
from methods.mandow2007.kinematics import PARAM_NAMES, IcrParams
from methods.mandow2007.segments import Segments, build_segments, segment_cost

GENE_BITS = 8  # Sec. IV-C: "each parameter has been coded as an 8 bit string"


@dataclass(frozen=True)
class GeneRanges:
    """Search ranges per parameter (lo, hi) in Mandow's axes; not given in the paper."""

    x_icr_l: tuple[float, float]
    x_icr_r: tuple[float, float]
    y_icr_v: tuple[float, float]
    alpha_l: tuple[float, float] = (0.75, 1.15)
    alpha_r: tuple[float, float] = (0.75, 1.15)

    @classmethod
    def for_track(cls, track: float) -> "GeneRanges":
        """x_ICR within [0.4 B, 1.2 B] per side, y_ICRv within +-B/4, alpha within [0.75, 1.15]."""
        return cls((-1.2 * track, -0.4 * track), (0.4 * track, 1.2 * track), (-0.25 * track, 0.25 * track))

    def bounds(self) -> np.ndarray:
        b = np.array([getattr(self, n) for n in PARAM_NAMES], float)
        if np.any(b[:, 1] <= b[:, 0]):
            raise ValueError(f"gene ranges need lo < hi: {self}")
        return b

    def quantum(self, bits: int = GENE_BITS) -> np.ndarray:
        b = self.bounds()
        return (b[:, 1] - b[:, 0]) / (2**bits - 1)


@dataclass(frozen=True)
class GaSettings:
    """pygad settings for the 40-bit GA (the paper gives only the chromosome)."""

    population: int = 100
    generations: int = 300
    parents_mating: int = 50
    parent_selection: str = "tournament"
    tournament_size: int = 3
    crossover: str = "uniform"
    mutation_probability: float = 0.025  # per-bit flip probability (1/40: one bit per chromosome)
    gray_code: bool = True
    elitism: int = 2
    stop_saturate: int | None = 60  # stop after this many generations without improvement
    seed: int = 2007


@dataclass(frozen=True)
class DeSettings:
    """scipy.optimize.differential_evolution settings (vectorised objective)."""

    popsize: int = 10  # x 5 parameters = 50 members
    maxiter: int = 300
    tol: float = 1e-8
    atol: float = 0.0
    strategy: str = "best1bin"
    polish: bool = True
    seed: int = 2007


@dataclass(frozen=True)
class Identification:
    """Result of an asymmetric identification (eq. (13) minimised over K)."""

    optimiser: str
    params: IcrParams
    cost: float
    n_segments: int
    n_evaluations: int
    iterations: int
    seed: int
    runs: tuple[str, ...]
    bounds: tuple[tuple[float, float], ...]
    quantum: tuple[float, ...] | None = None
    cost_history: tuple[float, ...] = field(default=(), repr=False)

    def as_dict(self) -> dict[str, Any]:
        d = dataclasses.asdict(self)
        d["params"] = self.params.as_dict()
        return d


def decode_chromosomes(bits: ArrayLike, ranges: GeneRanges, gray_code: bool = True) -> np.ndarray:
    """40-bit chromosomes (P, 40) -> parameters (P, 5): 8 bits per parameter (MSB first), optionally
    Gray-coded, mapped linearly onto ``ranges`` (code 0 -> lo, 255 -> hi)."""
    b = np.atleast_2d(np.asarray(bits)).astype(np.int64)
    if b.shape[1] != 5 * GENE_BITS:
        raise ValueError(f"chromosomes must have {5 * GENE_BITS} bits, got shape {b.shape}")
    code = b.reshape(b.shape[0], 5, GENE_BITS) @ (1 << np.arange(GENE_BITS - 1, -1, -1))
    if gray_code:
        shift = 1
        while shift < GENE_BITS:
            code = code ^ (code >> shift)
            shift *= 2
    lo_hi = ranges.bounds()
    return lo_hi[:, 0] + code * (lo_hi[:, 1] - lo_hi[:, 0]) / (2**GENE_BITS - 1)


def identify_ga(seg: Segments, ranges: GeneRanges | None = None, settings: GaSettings = GaSettings()
                ) -> Identification:
    """Sec. III: GA over 40-bit chromosomes (8 bits per parameter) maximising -J(K) of eq. (13).
    pygad with a fixed ``random_seed`` (its own generators: no global random state); the fitness of
    a whole population is one vectorised call (``fitness_batch_size`` = population) over the chromosomes not seen
    before in this run (a chromosome's cost is kept: the population repeats its individuals; the same bits as
    evaluating them again, tested).  ``n_evaluations`` counts the fitness values asked for, as before."""
    import pygad  # local import: only identification needs it

    ranges = ranges or GeneRanges.for_track(seg.track)
    evals = [0]
    history: list[float] = []
    known: dict[bytes, float] = {}  # chromosome -> fitness: a GA population repeats its individuals

    def fitness(_ga: Any, sols: np.ndarray, _idx: Any) -> np.ndarray:
        sols = np.atleast_2d(sols)
        evals[0] += sols.shape[0]
        keys = [row.tobytes() for row in np.ascontiguousarray(sols, dtype=np.int8)]
        first: dict[bytes, int] = {}
        for i, k in enumerate(keys):
            first.setdefault(k, i)
        new = [i for k, i in first.items() if k not in known]
        if new:  # each row's cost is computed alone (row-wise numpy): the same bits in any batch
            got = -segment_cost(seg, decode_chromosomes(sols[new], ranges, settings.gray_code))
            known.update(zip((keys[i] for i in new), got.tolist()))
        return np.array([known[k] for k in keys])

    def bit_flip(offspring: np.ndarray, ga: Any) -> np.ndarray:
        # classical binary-GA mutation, vectorised, drawn from the GA's own seeded generator
        flip = ga.numpy_random_generator.random_sample(offspring.shape) < settings.mutation_probability
        return np.where(flip, 1 - offspring, offspring)

    def on_generation(ga: Any) -> None:
        history.append(float(-np.max(ga.last_generation_fitness)))

    ga = pygad.GA(
        num_generations=settings.generations,
        num_parents_mating=settings.parents_mating,
        fitness_func=fitness,
        fitness_batch_size=settings.population,
        sol_per_pop=settings.population,
        num_genes=5 * GENE_BITS,
        gene_space=[0, 1],
        gene_type=int,
        parent_selection_type=settings.parent_selection,
        K_tournament=settings.tournament_size,
        crossover_type=settings.crossover,
        mutation_type=bit_flip,
        keep_elitism=settings.elitism,
        stop_criteria=None if settings.stop_saturate is None else f"saturate_{settings.stop_saturate}",
        on_generation=on_generation,
        random_seed=settings.seed,
        suppress_warnings=True,
    )
    ga.run()
    best, fit, _ = ga.best_solution(pop_fitness=ga.last_generation_fitness)
    k = decode_chromosomes(best, ranges, settings.gray_code)[0]
    return Identification(
        optimiser="pygad.GA", params=IcrParams.from_array(k), cost=float(-fit), n_segments=seg.n_segments,
        n_evaluations=evals[0], iterations=int(ga.generations_completed), seed=settings.seed,
        runs=seg.run_ids,
        bounds=tuple(map(tuple, ranges.bounds().tolist())), quantum=tuple(ranges.quantum().tolist()),
        cost_history=tuple(history),
    )


def identify_de(seg: Segments, ranges: GeneRanges | None = None, settings: DeSettings = DeSettings()
                ) -> Identification:
    """Second optimiser (not in the paper): scipy differential evolution on continuous K within the
    same ranges, seeded, vectorised objective, L-BFGS-B polish."""
    from scipy.optimize import differential_evolution

    ranges = ranges or GeneRanges.for_track(seg.track)
    evals = [0]
    history: list[float] = []

    def objective(x: np.ndarray) -> np.ndarray | float:
        x = np.asarray(x, float)
        if x.ndim == 1:
            evals[0] += 1
            return float(segment_cost(seg, x))
        evals[0] += x.shape[1]
        return segment_cost(seg, x.T)

    def callback(intermediate_result: Any) -> None:
        history.append(float(intermediate_result.fun))

    res = differential_evolution(
        objective, ranges.bounds(), strategy=settings.strategy, maxiter=settings.maxiter,
        popsize=settings.popsize, tol=settings.tol, atol=settings.atol, rng=np.random.default_rng(settings.seed),
        polish=settings.polish, updating="deferred", vectorized=True, callback=callback,
    )
    return Identification(
        optimiser="scipy.optimize.differential_evolution", params=IcrParams.from_array(res.x), cost=float(res.fun),
        n_segments=seg.n_segments, n_evaluations=evals[0], iterations=int(res.nit), seed=settings.seed,
        runs=seg.run_ids, bounds=tuple(map(tuple, ranges.bounds().tolist())),
        cost_history=tuple(history),
    )


def compare_optimisers(runs: Sequence[Run], ranges: GeneRanges | None = None, ga: GaSettings = GaSettings(),
                       de: DeSettings = DeSettings(), segment_period: float | None = None
                       ) -> dict[str, Identification]:
    """GA (published) and DE (second optimiser) on the same segments: ``{"ga": ..., "de": ...}``."""
    seg = build_segments(runs, segment_period)
    return {"ga": identify_ga(seg, ranges, ga), "de": identify_de(seg, ranges, de)}
