"""The fixed AeroBuildup sweep: alpha through stall, beta, each control surface, and the rates.

Grids are fixed (no randomness) so a derive run is reproducible. Every point is tagged train or
held-out; held-out points sit between the training points and choose the polynomial orders.
Rate derivatives are central differences at the cruise angle of attack.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..constants import DEG
from .aerobuildup import AeroModel

ALPHA_RANGE_DEG = (-10.0, 25.0)
ALPHA_TRAIN_DEG = np.arange(-10.0, 25.5, 1.0)
ALPHA_HELD_DEG = np.arange(-9.5, 25.0, 1.0)
BETA_DEG = (-15.0, -10.0, -5.0, 5.0, 10.0, 15.0)
BETA_HELD_DEG = (-12.5, -7.5, -2.5, 2.5, 7.5, 12.5)
ALPHA_GRID_DEG = (-8.0, -4.0, 0.0, 4.0, 8.0, 12.0, 16.0, 20.0)
ALPHA_GRID_HELD_DEG = (-6.0, 2.0, 10.0, 18.0)
SURFACE_FRACTIONS = (-1.0, -0.75, -0.5, -0.25, 0.25, 0.5, 0.75, 1.0)  # of each deflection limit
SURFACE_HELD_FRACTIONS = (-0.625, 0.375)
RATE_STEP = 0.02  # non-dimensional rate step for the central differences


@dataclass
class Sweep:
    """Sweep points and AeroBuildup coefficients.

    x: [N, 5] (alpha, beta, elevator, aileron, rudder) rad; coefficients: [N, 6];
    held_out: [N] bool; group: [N] str ('alpha', 'beta', 'elevator', 'aileron', 'rudder').
    rate_derivatives: [6, 3] d C / d (p b/2V, q c/2V, r b/2V) at ``rate_alpha``.
    """

    x: np.ndarray
    coefficients: np.ndarray
    held_out: np.ndarray
    group: np.ndarray
    rate_derivatives: np.ndarray
    rate_alpha: float


def _grid(alpha_deg, beta_deg) -> tuple[np.ndarray, np.ndarray]:
    a, b = np.meshgrid(np.asarray(alpha_deg, float), np.asarray(beta_deg, float), indexing="ij")
    return a.ravel() * DEG, b.ravel() * DEG


def run_sweep(model: AeroModel, limits_rad: dict[str, float], cruise_lift_coefficient: float) -> Sweep:
    """Evaluate the fixed grid. ``limits_rad``: deflection limit per surface (rad)."""
    xs, cs, held, groups = [], [], [], []

    def add(alpha, beta, defl, is_held, group):
        zeros = np.zeros((len(alpha), 3))
        c = model.coefficients(alpha, beta, zeros, defl)
        x = np.column_stack([alpha, beta, np.tile(np.asarray(defl), (len(alpha), 1))])
        xs.append(x)
        cs.append(c)
        held.append(np.asarray(is_held, bool))
        groups.append(np.full(len(alpha), group))

    a = np.concatenate([ALPHA_TRAIN_DEG, ALPHA_HELD_DEG]) * DEG
    add(a, np.zeros_like(a), (0.0, 0.0, 0.0), np.arange(len(a)) >= len(ALPHA_TRAIN_DEG), "alpha")
    at, bt = _grid(ALPHA_GRID_DEG, BETA_DEG)
    ah, bh = _grid(ALPHA_GRID_HELD_DEG, BETA_HELD_DEG)
    add(np.concatenate([at, ah]), np.concatenate([bt, bh]), (0.0, 0.0, 0.0),
        np.arange(len(at) + len(ah)) >= len(at), "beta")
    alpha_c = np.asarray(ALPHA_GRID_DEG + ALPHA_GRID_HELD_DEG) * DEG
    grid_held = np.arange(len(alpha_c)) >= len(ALPHA_GRID_DEG)
    for k, kind in enumerate(("elevator", "aileron", "rudder")):
        for frac in SURFACE_FRACTIONS + SURFACE_HELD_FRACTIONS:
            defl = [0.0, 0.0, 0.0]
            defl[k] = frac * limits_rad[kind]
            is_held = grid_held | (frac in SURFACE_HELD_FRACTIONS)
            add(alpha_c, np.zeros_like(alpha_c), tuple(defl), is_held, kind)
    x = np.concatenate(xs)
    coeffs = np.concatenate(cs)
    rate_alpha = _alpha_at_lift(x, coeffs, np.concatenate(groups), cruise_lift_coefficient)
    return Sweep(x, coeffs, np.concatenate(held), np.concatenate(groups),
                 rate_derivatives(model, rate_alpha), rate_alpha)


def _alpha_at_lift(x: np.ndarray, coeffs: np.ndarray, group: np.ndarray, lift: float) -> float:
    """Angle of attack of the clean alpha sweep where C_L = ``lift`` (below C_L,max)."""
    sel = group == "alpha"
    order = np.argsort(x[sel, 0])
    alpha, cl = x[sel, 0][order], coeffs[sel, 0][order]
    top = int(np.argmax(cl))
    return float(np.interp(lift, cl[: top + 1], alpha[: top + 1]))


def rate_derivatives(model: AeroModel, alpha: float) -> np.ndarray:
    """[6, 3] central differences in p b/2V, q c/2V, r b/2V at ``alpha`` (beta and surfaces 0)."""
    rates = np.zeros((6, 3))
    for j in range(3):
        rates[2 * j, j] = RATE_STEP
        rates[2 * j + 1, j] = -RATE_STEP
    c = model.coefficients(np.full(6, alpha), np.zeros(6), rates, (0.0, 0.0, 0.0))
    return np.stack([(c[2 * j] - c[2 * j + 1]) / (2 * RATE_STEP) for j in range(3)], axis=-1)
