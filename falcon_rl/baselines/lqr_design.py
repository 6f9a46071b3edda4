"""Discrete LQR with integral action (LQRI), Bryson-scaled, gain-scheduled over trim points.

For a reduced model (``linear_models``) discretised at the control step dt, tracked outputs
y = C x get integrators augmented *with* dt (reference/physics.md section 6):

    z[k+1] = z[k] + dt (C x[k] - r[k])
    A_aug = [[A_d, 0], [dt C, I]],  B_aug = [[B_d], [0]]

and python-control's ``dlqr`` (SciPy DARE, method pinned) gives u = u_trim - K [x - x_ref; z].
Weights follow Bryson's rule, Q_ii = 1 / x_i,max^2 and R_jj = 1 / u_j,max^2, so one set of maxima
serves every airframe. The closed-loop eigenvalues of A_aug - B_aug K are checked to lie inside
the unit circle.

Inert states are left out of the design and get zero gain: a state whose row and column of A, row
of B and column of C are all zero neither moves nor acts on anything (the surface-rate state of a
first-order actuator). It would be an uncontrollable mode on the unit circle (z = 1), for which the
Riccati equation has no stabilising solution.
"""

from __future__ import annotations

from dataclasses import dataclass

import control
import numpy as np

from .linear_models import LinearModel


class LQRDesignError(RuntimeError):
    """The Riccati equation had no stabilising solution for a trim point."""


@dataclass
class LQRGain:
    K: np.ndarray  # [m, n + k]
    closed_loop_eigenvalues: np.ndarray  # [n + k] complex, z-plane
    spectral_radius: float  # largest closed-loop |z| of the designed (non-inert) modes


def bryson(maxima: dict[str, float], names: tuple[str, ...], default: float = 1e3) -> np.ndarray:
    """Diagonal weights 1 / max^2 for ``names``; unnamed entries get 1 / default^2 (free)."""
    return np.diag([1.0 / maxima.get(n, default) ** 2 for n in names])


def inert_states(model: LinearModel, outputs: np.ndarray) -> np.ndarray:
    """Mask [n] of the states that neither move nor act on anything nor are tracked (all zero in
    their row and column of A, their row of B and their column of ``outputs`` [k, n])."""
    A, B = model.A, model.B
    return ((A == 0).all(axis=1) & (A == 0).all(axis=0) & (B == 0).all(axis=1)
            & (outputs == 0).all(axis=0))


def design_lqri(model: LinearModel, dt: float, outputs: np.ndarray, state_max: dict[str, float],
                input_max: np.ndarray, integral_max: np.ndarray) -> LQRGain:
    """LQRI gain [m, n + k] for tracked outputs ``outputs`` [k, n] (rows of C) at control step ``dt``;
    inert states (:func:`inert_states`) get zero gain and keep their eigenvalue 1."""
    inert = inert_states(model, outputs)
    active = ~inert
    Ad, Bd = model.discretize(dt)
    Ad, Bd, outputs = Ad[np.ix_(active, active)], Bd[active], outputs[:, active]
    names = tuple(name for name, keep in zip(model.states, active, strict=True) if keep)
    n, m = Bd.shape
    k = outputs.shape[0]
    A_aug = np.zeros((n + k, n + k))
    A_aug[:n, :n] = Ad
    A_aug[n:, :n] = dt * outputs
    A_aug[n:, n:] = np.eye(k)
    B_aug = np.vstack([Bd, np.zeros((k, m))])
    Q = np.zeros((n + k, n + k))
    Q[:n, :n] = bryson(state_max, names)
    Q[n:, n:] = np.diag(1.0 / np.asarray(integral_max) ** 2)
    R = np.diag(1.0 / np.asarray(input_max) ** 2)
    try:
        K, _, eig = control.dlqr(A_aug, B_aug, Q, R, method="scipy")
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise LQRDesignError(f"no stabilising LQR at trim {model.trim.row(0)}: {exc}") from exc
    radius = float(np.abs(eig).max())
    if radius >= 1.0:
        raise LQRDesignError(f"closed loop unstable (spectral radius {radius:.4f})")
    gain = np.zeros((m, inert.size + k))
    gain[:, np.concatenate([active, np.ones(k, dtype=bool)])] = np.asarray(K)
    eigenvalues = np.concatenate([np.asarray(eig), np.ones(int(inert.sum()), dtype=complex)])
    return LQRGain(gain, eigenvalues, radius)
