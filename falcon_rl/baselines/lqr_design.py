"""Discrete LQR with integral action (LQRI), Bryson-scaled, gain-scheduled over trim points.

For a reduced model (``linear_models``) discretised at the control step dt, tracked outputs
y = C x get integrators augmented *with* dt (reference/physics.md section 6):

    z[k+1] = z[k] + dt (C x[k] - r[k])
    A_aug = [[A_d, 0], [dt C, I]],  B_aug = [[B_d], [0]]

and python-control's ``dlqr`` (SciPy DARE, method pinned) gives u = u_trim - K [x - x_ref; z].
Weights follow Bryson's rule, Q_ii = 1 / x_i,max^2 and R_jj = 1 / u_j,max^2, so one set of maxima
serves every airframe. The closed-loop eigenvalues of A_aug - B_aug K are checked to lie inside
the unit circle.
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
    spectral_radius: float


def bryson(maxima: dict[str, float], names: tuple[str, ...], default: float = 1e3) -> np.ndarray:
    """Diagonal weights 1 / max^2 for ``names``; unnamed entries get 1 / default^2 (free)."""
    return np.diag([1.0 / maxima.get(n, default) ** 2 for n in names])


def design_lqri(model: LinearModel, dt: float, outputs: np.ndarray, state_max: dict[str, float],
                input_max: np.ndarray, integral_max: np.ndarray) -> LQRGain:
    """LQRI gain for tracked outputs ``outputs`` [k, n] (rows of C) at control step ``dt``."""
    Ad, Bd = model.discretize(dt)
    n, m = Bd.shape
    k = outputs.shape[0]
    A_aug = np.zeros((n + k, n + k))
    A_aug[:n, :n] = Ad
    A_aug[n:, :n] = dt * outputs
    A_aug[n:, n:] = np.eye(k)
    B_aug = np.vstack([Bd, np.zeros((k, m))])
    Q = np.zeros((n + k, n + k))
    Q[:n, :n] = bryson(state_max, model.states)
    Q[n:, n:] = np.diag(1.0 / np.asarray(integral_max) ** 2)
    R = np.diag(1.0 / np.asarray(input_max) ** 2)
    try:
        K, _, eig = control.dlqr(A_aug, B_aug, Q, R, method="scipy")
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise LQRDesignError(f"no stabilising LQR at trim {model.trim.row(0)}: {exc}") from exc
    radius = float(np.abs(eig).max())
    if radius >= 1.0:
        raise LQRDesignError(f"closed loop unstable (spectral radius {radius:.4f})")
    return LQRGain(np.asarray(K), np.asarray(eig), radius)
