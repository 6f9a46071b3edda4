"""Linearisation of the flight model about a trim point with autograd Jacobians.

    x_dot ~ A (x - x_trim) + B (u - u_trim),   A = df/dx [S, S],  B = df/du [S, 4]

x is the full state vector of ``state.py`` (quaternion included, so A has a zero mode along the
quaternion norm); u are the normalised commands in [-1, 1]. Evaluated in float64. This is the one
linearisation of the flight model: the reduced LQR models (``baselines.linear_models``) are these
Jacobians carried into their coordinates by the chain rule.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch

from ..airframe import Airframe
from .dynamics import AirInputs, derivative
from .params import ModelParams, build_params
from .trim import TrimResult


@dataclass
class Linearization:
    A: torch.Tensor  # [S, S]
    B: torch.Tensor  # [S, 4]
    x_trim: torch.Tensor  # [S]
    u_trim: torch.Tensor  # [4]


def linearize(airframe: Airframe, trim: TrimResult, index: int = 0,
              ground_effect: bool | str = True, params: ModelParams | None = None,
              air: AirInputs | None = None) -> Linearization:
    """Continuous-time Jacobians of ``dynamics.derivative`` at trim condition ``index``."""
    p = params if params is not None else build_params(airframe, 1, dtype=torch.float64,
                                                       ground_effect=ground_effect)
    x0 = trim.state[index].to(torch.float64)
    u0 = trim.commands[index].to(torch.float64)

    def f(x: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        return derivative(x.unsqueeze(0), u.unsqueeze(0), p, air).squeeze(0)

    A, B = torch.autograd.functional.jacobian(f, (x0, u0))
    return Linearization(A.detach(), B.detach(), x0, u0)


def finite_difference_jacobians(airframe: Airframe, trim: TrimResult, index: int = 0,
                                ground_effect: bool | str = True, eps: float = 1e-6
                                ) -> tuple[torch.Tensor, torch.Tensor]:
    """Central differences of the same derivative (for checking :func:`linearize`)."""
    p = build_params(airframe, 1, dtype=torch.float64, ground_effect=ground_effect)
    x0 = trim.state[index].to(torch.float64)
    u0 = trim.commands[index].to(torch.float64)

    def f(x: torch.Tensor, u: torch.Tensor) -> torch.Tensor:
        return derivative(x.unsqueeze(0), u.unsqueeze(0), p).squeeze(0)

    def jac(n: int, shift) -> torch.Tensor:
        cols = []
        for i in range(n):
            e = torch.zeros(n, dtype=torch.float64)
            e[i] = eps
            cols.append((shift(e) - shift(-e)) / (2 * eps))
        return torch.stack(cols, dim=-1)

    A = jac(x0.numel(), lambda d: f(x0 + d, u0))
    B = jac(u0.numel(), lambda d: f(x0, u0 + d))
    return A, B
