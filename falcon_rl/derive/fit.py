"""Least-squares fit of the sweep to falcon-rl's monomial tables, orders chosen on held-out points.

Each coefficient is a sum of term groups; a group is a family of monomials whose size is its
order, e.g. ``alpha`` of order 4 is alpha^0..alpha^4 and ``elevator`` of order 1 is d_e and
alpha d_e (plus d_e^2 and d_e^3, always in). Orders are chosen group by group: every candidate
is fitted on the training points and scored by the RMS error on the held-out points; the best
score wins (ties to the lower order), so the choice is deterministic. Points may
carry weights (``derive`` weights the post-stall points down so that the tables are most
accurate where the aircraft flies).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

Exponents = tuple[int, int, int, int, int]  # alpha, beta, elevator, aileron, rudder

# (group name, candidate orders, builder order -> exponents)
GROUPS: dict[str, tuple[tuple[int, ...], object]] = {
    "alpha": ((1, 2, 3, 4, 5, 6), lambda n: [(i, 0, 0, 0, 0) for i in range(n + 1)]),
    "beta2": ((0, 1, 2), lambda n: [(i, 2, 0, 0, 0) for i in range(n + 1)]),
    "elevator": ((0, 1, 2), lambda n: [(i, 0, 1, 0, 0) for i in range(n + 1)] + [(0, 0, 2, 0, 0),
                                                                                (0, 0, 3, 0, 0)]),
    "lateral_controls2": ((0,), lambda n: [(0, 0, 0, 2, 0), (0, 0, 0, 0, 2)]),
    "beta": ((0, 1, 2, 3), lambda n: [(i, 1, 0, 0, 0) for i in range(n + 1)] + [(0, 3, 0, 0, 0)]),
    "aileron": ((0, 1, 2), lambda n: [(i, 0, 0, 1, 0) for i in range(n + 1)]),
    "rudder": ((0, 1, 2), lambda n: [(i, 0, 0, 0, 1) for i in range(n + 1)]),
}
LONGITUDINAL = ("alpha", "beta2", "elevator", "lateral_controls2")
LATERAL = ("beta", "aileron", "rudder")
COEFFICIENT_GROUPS = {"CL": LONGITUDINAL, "CD": LONGITUDINAL, "Cm": LONGITUDINAL,
                      "CY": LATERAL, "Cl": LATERAL, "Cn": LATERAL}
PARSIMONY = 1.0


@dataclass
class CoefficientFit:
    """Fitted table of one coefficient and its residuals (same units as the coefficient)."""

    terms: list[Exponents]
    coefs: np.ndarray
    orders: dict[str, int]
    rms_train: float  # weighted
    rms_held_out: float  # weighted
    max_abs_held_out: float
    range_of_data: float
    rms_held_out_full_weight: float  # unweighted, over the held-out points of weight >= 1


def design(x: np.ndarray, terms: list[Exponents]) -> np.ndarray:
    """Monomial design matrix [N, T] for x [N, 5]."""
    e = np.asarray(terms, dtype=float)  # [T, 5]
    return np.prod(x[:, None, :] ** e[None, :, :], axis=-1)


def evaluate(x: np.ndarray, terms: list[Exponents], coefs: np.ndarray) -> np.ndarray:
    return design(x, terms) @ coefs


def _terms(groups: tuple[str, ...], orders: dict[str, int]) -> list[Exponents]:
    out: list[Exponents] = []
    for g in groups:
        for t in GROUPS[g][1](orders[g]):  # type: ignore[operator]
            if t not in out:
                out.append(t)
    return out


def _rms(resid: np.ndarray, w: np.ndarray) -> float:
    return float(np.sqrt(np.sum(w * resid**2) / np.sum(w)))


def _solve(x, y, held, terms, w) -> tuple[np.ndarray, float]:
    root = np.sqrt(w[~held])[:, None]
    coefs = np.linalg.lstsq(design(x[~held], terms) * root, y[~held] * root[:, 0], rcond=None)[0]
    return coefs, _rms(evaluate(x[held], terms, coefs) - y[held], w[held])


def fit_coefficient(x: np.ndarray, y: np.ndarray, held: np.ndarray, groups: tuple[str, ...],
                    weights: np.ndarray | None = None) -> CoefficientFit:
    """Fit one coefficient: choose each group's order on the held-out points, then refit.

    x: [N, 5], y: [N], held: [N] bool, weights: [N] (default 1) for the fit and the scores.
    """
    w = np.ones(len(y)) if weights is None else np.asarray(weights, dtype=float)
    orders = {g: GROUPS[g][0][0] for g in groups}  # type: ignore[index]
    for g in groups:
        scores = []
        for n in GROUPS[g][0]:  # type: ignore[union-attr]
            trial = {**orders, g: n}
            scores.append((n, _solve(x, y, held, _terms(groups, trial), w)[1]))
        best = min(s for _, s in scores)
        orders[g] = next(n for n, s in scores if s <= PARSIMONY * best + 1e-12)
    terms = _terms(groups, orders)
    coefs, rms_held = _solve(x, y, held, terms, w)
    train_resid = evaluate(x[~held], terms, coefs) - y[~held]
    held_resid = evaluate(x[held], terms, coefs) - y[held]
    full = w[held] >= 1.0  # the in-range points (weights are 1 or more there, below 1 outside)
    return CoefficientFit(terms, coefs, orders, _rms(train_resid, w[~held]), rms_held,
                          float(np.abs(held_resid).max()), float(np.ptp(y)),
                          _rms(held_resid[full], np.ones(int(full.sum()))))


def fit_tables(x: np.ndarray, coefficients: np.ndarray, held: np.ndarray, weights: np.ndarray | None = None
               ) -> dict[str, CoefficientFit]:
    """Fit all six coefficients ([N, 6] columns C_L, C_D, C_Y, C_l, C_m, C_n)."""
    names = ("CL", "CD", "CY", "Cl", "Cm", "Cn")
    return {n: fit_coefficient(x, coefficients[:, k], held, COEFFICIENT_GROUPS[n], weights)
            for k, n in enumerate(names)}
