"""SciPy engine (``backend="scipy"``): the accuracy reference, one env in float64.

Each step integrates ``dynamics.derivative`` over dt with ``scipy.integrate.solve_ivp`` (RK45,
rtol = atol = 1e-10), the command held, then projects (quaternion norm, actuator saturation).
Turbulence, when on, advances like the torch engine's (once per step, before the integration).
"""

from __future__ import annotations

import numpy as np
import torch

from .dynamics import derivative, hold_command, project
from .torch_backend import TorchEngine

#: solve_ivp tolerances (relative and absolute).
TOLERANCE = 1e-10


class ScipyEngine(TorchEngine):
    """One env, float64, ``solve_ivp`` over each step."""

    OPTIONS = ()

    @classmethod
    def placement(cls, num_envs: int, device: torch.device, dtype: torch.dtype
                  ) -> tuple[torch.device, torch.dtype]:
        if num_envs != 1:
            raise ValueError("the scipy reference backend runs exactly one env")
        return torch.device("cpu"), torch.float64

    def integrate_step(self) -> torch.Tensor:
        from scipy.integrate import solve_ivp

        command, air, params = self.command.clone(), self.air, self.params

        def f(_t: float, y: np.ndarray) -> np.ndarray:
            xx = torch.from_numpy(y).reshape(1, -1)
            return derivative(xx, command, params, air).reshape(-1).numpy()

        x0 = hold_command(self.x, command, params)[0].numpy()
        sol = solve_ivp(f, (0.0, self.dt), x0, method="RK45", rtol=TOLERANCE, atol=TOLERANCE)
        if not sol.success:
            raise RuntimeError(f"solve_ivp failed: {sol.message}")
        return project(torch.from_numpy(sol.y[:, -1]).reshape(1, -1), params)
