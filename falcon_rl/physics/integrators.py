"""Fixed-step integrators over ``dynamics.derivative`` (command held over the step)."""

from __future__ import annotations

from collections.abc import Callable

import torch

Derivative = Callable[[torch.Tensor], torch.Tensor]


def euler_step(f: Derivative, x: torch.Tensor, dt: float) -> torch.Tensor:
    """x + dt f(x). x: [N, S]."""
    return x + dt * f(x)


def rk4_step(f: Derivative, x: torch.Tensor, dt: float) -> torch.Tensor:
    """Classic fourth-order Runge-Kutta. x: [N, S]."""
    k1 = f(x)
    k2 = f(x + 0.5 * dt * k1)
    k3 = f(x + 0.5 * dt * k2)
    k4 = f(x + dt * k3)
    return x + (dt / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)


INTEGRATORS: dict[str, Callable[[Derivative, torch.Tensor, float], torch.Tensor]] = {
    "euler": euler_step,
    "rk4": rk4_step,
}
