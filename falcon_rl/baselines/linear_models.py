"""Reduced linear models about straight-and-level trim, for LQR design.

Two state sets, each with the actuator states included (the plant the controller really drives):

- longitudinal (altitude task), inputs [elevator, throttle] (normalised commands):
      x = [u, w, q, theta, h, d_e, d_e_rate, d_t]
- full (attitude task), inputs [elevator, aileron, rudder, throttle]:
      x = [u, v, w, p, q, r, phi, theta, d_e, d_a, d_r, d_e_rate, d_a_rate, d_r_rate, d_t]
  (height is left out: nothing but the slow density gradient depends on it, so it would add an
  uncontrollable-in-practice integrator at z = 1; the attitude task regulates climb rate instead,
  whose linear output row is ``climb_rate_row``)

Each reduced state maps to a full simulator state (heading 0, the other channels at trim); the
simulator's Jacobians about trim (``physics.linearize``, float64 autograd) are carried through
that map by the chain rule, and Euler kinematics give phi_dot, theta_dot. The reduced states are
named (``STATE_COMPONENTS`` ties each to a field of ``physics.state``), and ``reduced_state``
reads them off the env's ("state", ...) fields. Discretisation is exact for a zero-order hold:
expm([[A, B], [0, 0]] dt).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import scipy.linalg
import torch

from ..airframe import SURFACES, Airframe
from ..physics import state as S
from ..physics.linearize import linearize
from ..physics.rotations import euler_to_quaternion
from ..physics.trim import TrimResult, trim_level

LONGITUDINAL_STATES = ("u", "w", "q", "theta", "h", "elevator", "elevator_rate", "throttle")
LONGITUDINAL_INPUTS = (S.ELEVATOR, S.THROTTLE)
FULL_STATES = ("u", "v", "w", "p", "q", "r", "phi", "theta", "elevator", "aileron", "rudder",
               "elevator_rate", "aileron_rate", "rudder_rate", "throttle")
FULL_INPUTS = (S.ELEVATOR, S.AILERON, S.RUDDER, S.THROTTLE)
#: Position of each reduced state in its model's state vector.
LONGITUDINAL_INDEX: dict[str, int] = {name: i for i, name in enumerate(LONGITUDINAL_STATES)}
FULL_INDEX: dict[str, int] = {name: i for i, name in enumerate(FULL_STATES)}
#: Reduced states that are one component of a simulator state field: name -> (field, component).
#: "throttle" stands for every motor (all at one setting). The others: "h" = -z of position_ned,
#: "phi", "theta" = Euler angles of the attitude at heading 0.
STATE_COMPONENTS: dict[str, tuple[str, int]] = {
    "u": ("velocity_body", S.X), "v": ("velocity_body", S.Y), "w": ("velocity_body", S.Z),
    "p": ("angular_rate_body", S.ROLL), "q": ("angular_rate_body", S.PITCH),
    "r": ("angular_rate_body", S.YAW),
    **{name: ("surface_position", i) for i, name in enumerate(SURFACES)},
    **{f"{name}_rate": ("surface_rate", i) for i, name in enumerate(SURFACES)},
    "throttle": ("throttle", 0),
}


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


def reduced_state(state: Mapping[str, torch.Tensor], names: tuple[str, ...]) -> torch.Tensor:
    """Reduced state [N, n] from the env's named state fields (the ("state", ...) entries
    velocity_body, angular_rate_body, surface_position, throttle, euler, height; surface_rate
    counts as zero when absent)."""
    columns = []
    for name in names:
        if name in STATE_COMPONENTS:
            field, i = STATE_COMPONENTS[name]
            value = state.get(field, None)
            if value is None:  # surface_rate of an env that does not publish it
                value = torch.zeros_like(state["surface_position"])
            columns.append(value[:, i])
        elif name == "h":
            columns.append(state["height"])
        else:
            columns.append(state["euler"][:, {"phi": S.ROLL, "theta": S.PITCH}[name]])
    return torch.stack(columns, dim=-1)


def _full_state(xr: torch.Tensor, names: tuple[str, ...], trim_x: torch.Tensor) -> torch.Tensor:
    """Reduced state [n] -> simulator state [S]: heading 0, unlisted channels at trim."""
    layout = S.StateLayout(trim_x.shape[-1] - S.THROTTLE_START)
    fields = {name: value.clone() for name, value in layout.unpack(trim_x[None]).items()}
    for i, name in enumerate(names):
        if name in STATE_COMPONENTS:
            field, component = STATE_COMPONENTS[name]
            if field == "throttle":
                fields[field] = xr[i].expand(1, layout.num_motors)
            else:
                fields[field][0, component] = xr[i]
    if "h" in names:
        fields["position_ned"][0, S.DOWN] = -xr[names.index("h")]
    zero = torch.zeros_like(xr[0])
    euler = torch.stack([xr[names.index(a)] if a in names else zero for a in ("phi", "theta")] + [zero])
    fields["quaternion"] = euler_to_quaternion(euler[None])
    return layout.pack(fields)[0]


def _rate_rows(names: tuple[str, ...], size: int) -> torch.Tensor:
    """Rows [n, S] that read the reduced rates off the simulator's state derivative (zero rows for
    the Euler angles, whose rates are kinematic)."""
    rows = torch.zeros(len(names), size, dtype=torch.float64)
    for i, name in enumerate(names):
        if name in STATE_COMPONENTS:
            field, component = STATE_COMPONENTS[name]
            index = S.THROTTLE_START + component if field == "throttle" else S.STATE_INDEX[field][component]
            rows[i, index] = 1.0
        elif name == "h":
            rows[i, S.DOWN_INDEX] = -1.0
    return rows


def _euler_rates(xr: torch.Tensor, names: tuple[str, ...], trim_x: torch.Tensor) -> torch.Tensor:
    """Kinematic Euler-angle rates [n] (phi_dot, theta_dot in their rows, 0 elsewhere)."""
    x = _full_state(xr, names, trim_x)
    p, q, r = x[S.ANGULAR_RATE].unbind()
    phi = xr[names.index("phi")] if "phi" in names else torch.zeros_like(p)
    theta = xr[names.index("theta")]
    rates = {"phi": p + (q * torch.sin(phi) + r * torch.cos(phi)) * torch.tan(theta),
             "theta": q * torch.cos(phi) - r * torch.sin(phi)}
    return torch.stack([rates.get(name, torch.zeros_like(p)) for name in names])


def linear_model(airframe: Airframe, airspeed: float, height: float, full: bool = False,
                 ground_effect: bool | str = True) -> LinearModel:
    """Trim at (airspeed, height) and linearise the longitudinal (or full) reduced model."""
    trim = trim_level(airframe, airspeed, height, ground_effect=ground_effect)
    return linear_model_at(airframe, trim, 0, full, ground_effect)


def linear_model_at(airframe: Airframe, trim: TrimResult, index: int, full: bool = False,
                    ground_effect: bool | str = True) -> LinearModel:
    """Linearise about condition ``index`` of an already solved (batched) trim.

    The simulator's Jacobians come from :func:`physics.linearize.linearize`; the reduced model is
    their change of coordinates, x = E(x_r) about trim (chain rule):

        A_r = P A E' + d(Euler kinematics)/dx_r,   B_r = P B[:, inputs]

    with E' = dE/dx_r [S, n] and P [n, S] the rows that read the reduced rates off x_dot.
    """
    names = FULL_STATES if full else LONGITUDINAL_STATES
    inputs = list(FULL_INPUTS if full else LONGITUDINAL_INPUTS)
    lin = linearize(airframe, trim, index, ground_effect=ground_effect)
    tx = lin.x_trim
    # Level trim: pitch = alpha, wings level, heading 0.
    euler = torch.zeros(1, 3, dtype=tx.dtype)
    euler[0, S.PITCH] = trim.alpha[index]
    trim_fields = {**S.StateLayout(airframe.num_motors).unpack(tx[None]), "height": S.height(tx)[None],
                   "euler": euler}
    x0 = reduced_state(trim_fields, names)[0]
    embed = torch.autograd.functional.jacobian(lambda xr: _full_state(xr, names, tx), x0)  # [S, n]
    kinematics = torch.autograd.functional.jacobian(lambda xr: _euler_rates(xr, names, tx), x0)  # [n, n]
    rows = _rate_rows(names, tx.shape[0])
    A = rows @ lin.A @ embed + kinematics
    B = rows @ lin.B[:, inputs]
    u0 = lin.u_trim[inputs].clone()
    return LinearModel(A.numpy(), B.numpy(), x0.numpy(), u0.numpy(), lin.u_trim.numpy(), names, trim)


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
