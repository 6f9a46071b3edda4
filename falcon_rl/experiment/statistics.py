"""Statistics over the replicates of a table entry (training seeds of a learned controller, repeated
draws of MPPI): the per-seed rows are kept, and each metric is summarized by an :class:`Aggregate`.

- mean, and the sample standard deviation (ddof=1; 0 for one value);
- a 95 % percentile-bootstrap confidence interval of the mean: ``resamples`` (10,000) resamples with
  replacement drawn by ``numpy.random.default_rng(seed)``, the 2.5 and 97.5 percentiles of their means
  (``numpy.percentile``, linear interpolation); one value gives the interval [value, value];
- the interquartile mean as rliable computes it: ``scipy.stats.trim_mean(values, 0.25)``, which sorts
  the values, drops ``int(0.25 n)`` from each end and averages the rest (with fewer than four values
  nothing is dropped and it is the mean).

NaN values (an episode set that did not survive, a metric left undefined; also infinities and None,
which is how a cached result stores them) are left out and counted in ``n_excluded``; a metric with no
finite value gives an aggregate marked ``empty`` (all numbers NaN), which the tables show as an empty
cell.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import stats

from .cells import Cell

#: Bootstrap resamples of the confidence interval.
RESAMPLES = 10_000
#: Coverage of the confidence interval.
CONFIDENCE = 0.95
#: Values per bootstrap batch (bounds the memory of many resamples of many values).
_BATCH_VALUES = 4_000_000


@dataclass(frozen=True)
class Aggregate:
    """Summary of one metric over replicates; see the module docstring."""

    mean: float
    std: float
    n: int
    ci_low: float
    ci_high: float
    iqm: float
    n_excluded: int = 0

    @property
    def empty(self) -> bool:
        """No finite value: the paper leaves such a cell empty."""
        return self.n == 0

    def to_dict(self) -> dict[str, Any]:
        """JSON form (NaN as None)."""
        def number(value: float) -> float | None:
            return value if math.isfinite(value) else None

        return {"mean": number(self.mean), "std": number(self.std), "n": self.n,
                "n_excluded": self.n_excluded, "ci_low": number(self.ci_low), "ci_high": number(self.ci_high),
                "iqm": number(self.iqm),
                "empty": self.empty}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Aggregate:
        """Inverse of :meth:`to_dict`."""
        def number(value: Any) -> float:
            return math.nan if value is None else float(value)

        return cls(number(data["mean"]), number(data["std"]), int(data["n"]), number(data["ci_low"]),
                   number(data["ci_high"]), number(data["iqm"]), int(data.get("n_excluded", 0)))


def bootstrap_ci(values: np.ndarray, resamples: int = RESAMPLES, confidence: float = CONFIDENCE,
                 seed: int = 0) -> tuple[float, float]:
    """Percentile-bootstrap interval of the mean of ``values`` (finite, at least one)."""
    n = len(values)
    if n == 1:
        return float(values[0]), float(values[0])
    rng = np.random.default_rng(seed)
    batch = max(1, _BATCH_VALUES // n)
    means = np.concatenate([values[rng.integers(0, n, size=(min(batch, resamples - start), n))].mean(axis=1)
                            for start in range(0, resamples, batch)])
    tail = 100.0 * (1.0 - confidence) / 2.0
    low, high = np.percentile(means, [tail, 100.0 - tail])
    return float(low), float(high)


def aggregate(values: Iterable[float], resamples: int = RESAMPLES, confidence: float = CONFIDENCE,
              seed: int = 0) -> Aggregate:
    """Mean, std (ddof=1), bootstrap CI and IQM of the finite ``values`` (the others left out, counted)."""
    if resamples < 1:
        raise ValueError(f"resamples must be >= 1, got {resamples}")
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must lie in (0, 1), got {confidence}")
    array = np.asarray([math.nan if v is None else v for v in values], dtype=float).reshape(-1)
    finite = array[np.isfinite(array)]
    excluded = int(array.size - finite.size)
    if finite.size == 0:
        return Aggregate(math.nan, math.nan, 0, math.nan, math.nan, math.nan, excluded)
    std = float(np.std(finite, ddof=1)) if finite.size > 1 else 0.0
    low, high = bootstrap_ci(finite, resamples, confidence, seed)
    return Aggregate(float(np.mean(finite)), std, int(finite.size), low, high,
                     float(stats.trim_mean(finite, 0.25)), excluded)


@dataclass
class CellGroup:
    """The replicates (seeds, draws) of one table entry: per-replicate rows and the aggregates."""

    study: str
    task: str
    airframe: str
    controller: str
    params: tuple[tuple[str, Any], ...] = ()
    rows: list[dict[str, Any]] = field(default_factory=list)  # {"key", "seed", "draw", "summary"}
    aggregates: dict[str, Aggregate] = field(default_factory=dict)
    missing: list[str] = field(default_factory=list)  # keys of replicates without a result (failed)

    def to_dict(self) -> dict[str, Any]:
        """JSON form: identity, the replicate keys and each metric's aggregate."""
        return {"study": self.study, "task": self.task, "airframe": self.airframe,
                "controller": self.controller, "params": dict(self.params),
                "replicates": [row["key"] for row in self.rows], "missing": list(self.missing),
                "metrics": {name: agg.to_dict() for name, agg in self.aggregates.items()}}


def group_cells(cells: Sequence[Cell], results: Mapping[str, Mapping[str, Any]],
                resamples: int = RESAMPLES, confidence: float = CONFIDENCE, seed: int = 0) -> list[CellGroup]:
    """Gather ``cells`` that differ only in seed and draw (in order of first appearance), keep each
    replicate's summary as a row (``results``: cell key -> result) and aggregate every metric that any
    replicate reports (a replicate lacking it counts as NaN)."""
    groups: dict[tuple[Any, ...], CellGroup] = {}
    seen: set[str] = set()
    for cell in cells:
        key = cell.key()
        if key in seen:
            continue
        seen.add(key)
        group = groups.setdefault(cell.group(), CellGroup(cell.study, cell.task, cell.airframe,
                                                          cell.controller, cell.params))
        if key not in results:
            group.missing.append(key)
            continue
        group.rows.append({"key": key, "seed": cell.seed, "draw": cell.draw,
                           "summary": dict(results[key]["summary"])})
    for group in groups.values():
        names = list(dict.fromkeys(name for row in group.rows for name in row["summary"]))
        group.aggregates = {name: aggregate([row["summary"].get(name, math.nan) for row in group.rows],
                                            resamples, confidence, seed) for name in names}
    return list(groups.values())


__all__ = ["CONFIDENCE", "RESAMPLES", "Aggregate", "CellGroup", "aggregate", "bootstrap_ci", "group_cells"]
