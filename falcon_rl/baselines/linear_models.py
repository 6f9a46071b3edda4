"""Reduced linear models about straight-and-level trim, for LQR design.

Two state sets, each with the actuator states included (the plant the controller really drives):

- longitudinal (altitude task), inputs [elevator, throttle] (normalised commands):
      x = [u, w, q, theta, h, d_e, d_e_rate, d_t]
- full (attitude task), inputs [elevator, aileron, rudder, throttle]:
      x = [u, v, w, p, q, r, phi, theta, d_e, d_a, d_r, d_e_rate, d_a_rate, d_r_rate, d_t]
  (height is left out: nothing but the slow density gradient depends on it, so it would add an
  uncontrollable-in-practice integrator at z = 1; the attitude task regulates climb rate instead,
  whose linear output row is ``climb_rate_row``)

Each reduced state maps to a full simulator state (heading 0, the other channels at trim), the
torch dynamics give the full derivative, and Euler kinematics give phi_dot, theta_dot; autograd
differentiates that map at trim in float64. Discretisation is exact for a zero-order hold:
expm([[A, B], [0, 0]] dt).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg
import torch

from ..airframe import Airframe
from ..physics import state as S
from ..physics.dynamics import derivative
from ..physics.params import build_params
from ..physics.rotations import euler_to_quaternion
from ..physics.trim import TrimResult, trim_level

LONGITUDINAL_STATES = ("u", "w", "q", "theta", "h", "elevator", "elevator_rate", "throttle")
LONGITUDINAL_INPUTS = (0, 3)
FULL_STATES = ("u", "v", "w", "p", "q", "r", "phi", "theta", "elevator", "aileron", "rudder",
               "elevator_rate", "aileron_rate", "rudder_rate", "throttle")
FULL_INPUTS = (0, 1, 2, 3)


@dataclass
class LinearModel:
    """Continuous reduced model x' = A (x - x0) + B (u - u0) about a trim."""

    A: np.ndarray  # [n, n]
    B: np.ndarray  # [n, m]
    x_trim: np.ndarray  # [n]
    u_trim: np.ndarray  # [m] normalised commands of the input channels
    full_command_trim: np.ndarray  # [4]
    states: tuple[str, ...]
    trim: TrimResult

    def discretize(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """Zero-order-hold (A_d [n, n], B_d [n, m]) at step ``dt``."""
        n, m = self.B.shape
        block = np.zeros((n + m, n + m))
        block[:n, :n] = self.A
        block[:n, n:] = self.B
        phi = scipy.linalg.expm(block * dt)
        return phi[:n, :n], phi[:n, n:]


def _full_state(xr: torch.Tensor, trim_x: torch.Tensor, full: bool) -> torch.Tensor:
    """Reduced state [n] -> simulator state [S] (heading 0, unlisted channels at trim)."""
    x = trim_x.clone()
    if full:
        u, v, w, p, q, r, phi, theta = xr[:8]
        h = -trim_x[2]
        surfaces, rates, throttle = xr[8:11], xr[11:14], xr[14]
        euler = torch.stack([phi, theta, torch.zeros_like(phi)])
        vel, omega = torch.stack([u, v, w]), torch.stack([p, q, r])
    else:
        u, w, q, theta, h, de, de_rate, throttle = xr
        zero = torch.zeros_like(u)
        euler = torch.stack([zero, theta, zero])
        vel, omega = torch.stack([u, trim_x[8], w]), torch.stack([zero, q, zero])
        surfaces = torch.stack([de, trim_x[14], trim_x[15]])
        rates = torch.stack([de_rate, zero, zero])
    x = torch.cat([torch.stack([trim_x[0], trim_x[1], -h]), euler_to_quaternion(euler[None])[0], vel,
                   omega, surfaces, rates, throttle.expand(x.shape[0] - S.THROTTLE_START)])
    return x


def _reduced_derivative(xr: torch.Tensor, ur: torch.Tensor, trim_x: torch.Tensor,
                        command_trim: torch.Tensor, params, full: bool) -> torch.Tensor:
    x = _full_state(xr, trim_x, full)
    command = command_trim.clone()
    command[list(FULL_INPUTS if full else LONGITUDINAL_INPUTS)] = ur
    xdot = derivative(x[None], command[None], params)[0]
    height_rate = -xdot[2]
    throttle_rate = xdot[S.THROTTLE_START]
    if full:
        phi, theta = xr[6], xr[7]
        p, q, r = xr[3], xr[4], xr[5]
        phi_dot = p + (q * torch.sin(phi) + r * torch.cos(phi)) * torch.tan(theta)
        theta_dot = q * torch.cos(phi) - r * torch.sin(phi)
        return torch.cat([xdot[S.VELOCITY], xdot[S.ANGULAR_RATE], torch.stack([phi_dot, theta_dot]),
                          xdot[S.SURFACE_POSITION], xdot[S.SURFACE_RATE], throttle_rate[None]])
    return torch.stack([xdot[7], xdot[9], xdot[11], xr[2], height_rate, xdot[13], xdot[16],
                        throttle_rate])


def linear_model(airframe: Airframe, airspeed: float, height: float, full: bool = False,
                 ground_effect: bool | str = True) -> LinearModel:
    """Trim at (airspeed, height) and linearise the longitudinal (or full) reduced model."""
    trim = trim_level(airframe, airspeed, height, ground_effect=ground_effect)
    return linear_model_at(airframe, trim, 0, full, ground_effect)


def linear_model_at(airframe: Airframe, trim: TrimResult, index: int, full: bool = False,
                    ground_effect: bool | str = True) -> LinearModel:
    """Linearise about condition ``index`` of an already solved (batched) trim."""
    params = build_params(airframe, 1, dtype=torch.float64, ground_effect=ground_effect)
    tx, tu = trim.state[index], trim.commands[index]
    theta = float(trim.alpha[index])
    height = float(trim.height[index])
    if full:
        surf, rates = tx[S.SURFACE_POSITION], tx[S.SURFACE_RATE]
        x0 = torch.cat([tx[S.VELOCITY], tx[S.ANGULAR_RATE], torch.tensor([0.0, theta], dtype=torch.float64),
                        surf, rates, tx[S.THROTTLE_START:S.THROTTLE_START + 1]])
        inputs = FULL_INPUTS
    else:
        x0 = torch.tensor([float(tx[7]), float(tx[9]), 0.0, theta, height, float(tx[13]), 0.0,
                           float(tx[S.THROTTLE_START])], dtype=torch.float64)
        inputs = LONGITUDINAL_INPUTS
    u0 = tu[list(inputs)].clone()
    A, B = torch.autograd.functional.jacobian(
        lambda xr, ur: _reduced_derivative(xr, ur, tx, tu, params, full), (x0, u0))
    return LinearModel(A.numpy(), B.numpy(), x0.numpy(), u0.numpy(), tu.numpy(),
                       FULL_STATES if full else LONGITUDINAL_STATES, trim)


def climb_rate_row(model: LinearModel) -> np.ndarray:
    """Linear output row [n] of hdot = u sin(theta) - v sin(phi) cos(theta) - w cos(phi) cos(theta)
    about the trim of a full model."""
    names = model.states

    def climb(xr: torch.Tensor) -> torch.Tensor:
        u, v, w = xr[names.index("u")], xr[names.index("v")], xr[names.index("w")]
        phi, theta = xr[names.index("phi")], xr[names.index("theta")]
        return (u * torch.sin(theta) - v * torch.sin(phi) * torch.cos(theta)
                - w * torch.cos(phi) * torch.cos(theta))

    x0 = torch.as_tensor(model.x_trim, dtype=torch.float64)
    return torch.autograd.functional.jacobian(climb, x0).numpy()
