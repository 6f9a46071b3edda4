"""Steady level trim: alpha, beta (or bank), elevator, aileron, rudder and throttle that null all
body accelerations (forces and moments) at a given airspeed and height, ground effect on or off.

Solved by damped Newton iterations in float64 with autograd Jacobians, batched over conditions.
Level flight (flight path horizontal), body rates 0, still air. Lateral convention ``lateral``:
"wings_level" (bank 0, the side force balanced by sideslip; pitch = alpha) or "zero_sideslip" (beta 0,
the side force balanced by a bank phi, pitch theta = atan(cos phi tan alpha): JSBSim's full trim, where an
asymmetric moment such as a propeller's p-factor leaves a small bank).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch

from ..airframe import AERO_COEFFICIENTS, SURFACES, Airframe
from . import state as S
from .actuators import normalised_command
from .dynamics import derivative, evaluate
from .params import ModelParams, build_params
from .rotations import euler_to_quaternion

#: Newton unknowns [K, 6]: (alpha, beta or bank, elevator, aileron, rudder, throttle); every motor at one
#: throttle.
_ALPHA, _BETA, _SURFACES, _THROTTLE = 0, 1, slice(2, 5), 5
_BANK = _BETA
LATERAL_CONVENTIONS = ("wings_level", "zero_sideslip")
_CL, _CD = AERO_COEFFICIENTS.index("CL"), AERO_COEFFICIENTS.index("CD")


class TrimError(RuntimeError):
    """No trim exists (or Newton did not converge) for a requested condition."""


@dataclass
class TrimResult:
    """Trim of K conditions; every field is a float64 tensor with leading dim K."""

    airspeed: torch.Tensor  # [K] m/s
    height: torch.Tensor  # [K] m
    alpha: torch.Tensor  # [K] rad
    beta: torch.Tensor  # [K] rad
    surfaces: torch.Tensor  # [K, 3] rad (elevator, aileron, rudder)
    throttle: torch.Tensor  # [K]
    commands: torch.Tensor  # [K, 4] normalised commands that hold the trim
    state: torch.Tensor  # [K, S] state vector
    thrust: torch.Tensor  # [K] N, all motors
    lift: torch.Tensor  # [K] N
    drag: torch.Tensor  # [K] N
    lift_coefficient: torch.Tensor  # [K]
    drag_coefficient: torch.Tensor  # [K]
    induced_drag_coefficient: torch.Tensor  # [K]
    residual: torch.Tensor  # [K] max |body acceleration| (m/s^2 and rad/s^2)
    bank: torch.Tensor | None = None  # [K] rad (None: wings level)

    def row(self, k: int = 0) -> dict[str, float]:
        """Condition k as plain floats with units in the names (CLI/JSON)."""
        return {
            "airspeed_mps": float(self.airspeed[k]),
            "height_m": float(self.height[k]),
            "alpha_deg": float(torch.rad2deg(self.alpha[k])),
            "beta_deg": float(torch.rad2deg(self.beta[k])),
            "elevator_deg": float(torch.rad2deg(self.surfaces[k, S.ELEVATOR])),
            "aileron_deg": float(torch.rad2deg(self.surfaces[k, S.AILERON])),
            "rudder_deg": float(torch.rad2deg(self.surfaces[k, S.RUDDER])),
            "throttle": float(self.throttle[k]),
            "thrust_n": float(self.thrust[k]),
            "drag_n": float(self.drag[k]),
            "lift_n": float(self.lift[k]),
            "lift_coefficient": float(self.lift_coefficient[k]),
            "drag_coefficient": float(self.drag_coefficient[k]),
            "induced_drag_coefficient": float(self.induced_drag_coefficient[k]),
        }


def level_state(unknowns: torch.Tensor, airspeed: torch.Tensor, height: torch.Tensor,
                num_motors: int, lateral: str = "wings_level") -> torch.Tensor:
    """State [K, S] for unknowns [K, 6] = (alpha, beta or bank (``lateral``), d_e, d_a, d_r, throttle)."""
    alpha = unknowns[:, _ALPHA]
    k = unknowns.shape[0]
    zeros = torch.zeros(k, dtype=unknowns.dtype, device=unknowns.device)
    if lateral == "zero_sideslip":
        beta, bank = zeros, unknowns[:, _BANK]
        pitch = torch.atan(torch.cos(bank) * torch.tan(alpha))
    else:
        beta, bank, pitch = unknowns[:, _BETA], zeros, alpha
    vel = airspeed[:, None] * torch.stack(
        [torch.cos(alpha) * torch.cos(beta), torch.sin(beta), torch.sin(alpha) * torch.cos(beta)],
        dim=-1)
    return S.StateLayout(num_motors).pack({
        "position_ned": torch.stack([zeros, zeros, -height], dim=-1),
        "quaternion": euler_to_quaternion(torch.stack([bank, pitch, zeros], dim=-1)),
        "velocity_body": vel,
        "angular_rate_body": torch.zeros_like(vel),
        "surface_position": unknowns[:, _SURFACES],
        "throttle": unknowns[:, _THROTTLE, None].expand(k, num_motors),
    })


def _residual(unknowns: torch.Tensor, airspeed, height, p: ModelParams, num_motors: int,
              lateral: str = "wings_level"):
    x = level_state(unknowns, airspeed, height, num_motors, lateral)
    command = normalised_command(unknowns[:, _SURFACES], unknowns[:, _THROTTLE], p)
    xdot = derivative(x, command, p)
    return torch.cat([xdot[:, S.VELOCITY], xdot[:, S.ANGULAR_RATE]], dim=-1)


def trim_level(
    airframe: Airframe,
    airspeed: float | torch.Tensor,
    height: float | torch.Tensor,
    ground_effect: bool | str = True,
    tol: float = 1e-9,
    max_iter: int = 60,
    lateral: str = "wings_level",
) -> TrimResult:
    """Trim straight and level flight. ``airspeed`` and ``height`` are scalars or [K] tensors;
    ``lateral`` one of LATERAL_CONVENTIONS (see the module doc).

    Raises :class:`TrimError` naming the condition when no trim is found within the airframe's
    alpha range, surface limits and throttle range [0, 1].
    """
    if lateral not in LATERAL_CONVENTIONS:
        raise ValueError(f"lateral must be one of {list(LATERAL_CONVENTIONS)}, got {lateral!r}")
    v = torch.as_tensor(airspeed, dtype=torch.float64).reshape(-1)
    h = torch.as_tensor(height, dtype=torch.float64).reshape(-1)
    v, h = torch.broadcast_tensors(v, h)
    v, h = v.contiguous(), h.contiguous()
    k = v.shape[0]
    m = airframe.num_motors
    p = build_params(airframe, k, dtype=torch.float64, ground_effect=ground_effect)
    z = torch.zeros(k, 6, dtype=torch.float64)
    z[:, _ALPHA] = 0.05
    z[:, _THROTTLE] = 0.5
    step_limit = torch.tensor([0.05, 0.05, 0.05, 0.05, 0.05, 0.2], dtype=torch.float64)
    residual = None
    for _ in range(max_iter):
        residual = _residual(z, v, h, p, m, lateral)
        if residual.abs().max() < tol:
            break
        jac = torch.autograd.functional.jacobian(
            lambda zz: _residual(zz, v, h, p, m, lateral).sum(0), z)  # [6, K, 6]
        jac = jac.permute(1, 0, 2)  # [K, 6, 6]
        # Pseudo-inverse: stays finite where the alpha clamp of the aero table flattens a column.
        step = (torch.linalg.pinv(jac) @ -residual.unsqueeze(-1)).squeeze(-1)
        scale = (step.abs() / step_limit).max(dim=-1, keepdim=True).values.clamp_min(1.0)
        z = z + step / scale
    assert residual is not None
    err = residual.abs().max(dim=-1).values
    _check(airframe, z, v, h, err, tol, p)
    return _result(z, v, h, p, m, err, lateral)


def _envelope_hint(airframe: Airframe, airspeed: float) -> str:
    """Why a trim may not exist at ``airspeed``: below the stall speed (naming the stall angle) or above
    the maximum speed of the airframe's envelope; "" inside the envelope."""
    env = airframe.envelope
    if airspeed < env.stall_speed:
        return (f"; {airspeed:.2f} m/s is below the stall speed {env.stall_speed:.2f} m/s (the wing stalls "
                f"at alpha {math.degrees(airframe.aero.alpha_stall):.1f} deg)")
    if airspeed > env.max_speed:
        return f"; {airspeed:.2f} m/s is above the maximum speed {env.max_speed:.2f} m/s"
    return ""


def _check(airframe: Airframe, z, v, h, err, tol, p: ModelParams) -> None:
    lo, hi = airframe.aero.alpha_range
    stall = math.degrees(airframe.aero.alpha_stall)
    for i in range(z.shape[0]):
        where = f"{airframe.name} at {float(v[i]):.2f} m/s, {float(h[i]):.2f} m"
        hint = _envelope_hint(airframe, float(v[i]))
        if not torch.isfinite(z[i]).all():
            raise TrimError(f"trim diverged for {where}{hint}")
        alpha = float(z[i, _ALPHA])
        if not lo <= alpha <= hi:
            raise TrimError(f"no trim for {where}: needs alpha {math.degrees(alpha):.1f} deg, outside the "
                            f"aero table's [{math.degrees(lo):.1f}, {math.degrees(hi):.1f}] deg (stall at "
                            f"{stall:.1f} deg){hint}")
        if not 0.0 <= float(z[i, _THROTTLE]) <= 1.0:
            throttle = float(z[i, _THROTTLE])
            raise TrimError(f"no trim for {where}: needs throttle {throttle:.3f}, outside [0, 1]{hint}")
        for j, surface in enumerate(SURFACES):
            angle, low, high = (math.degrees(float(t)) for t in (z[i, _SURFACES][j], p.surface_min[i, j],
                                                                 p.surface_max[i, j]))
            if not low <= angle <= high:
                raise TrimError(f"no trim for {where}: the {surface} saturates (needs {angle:.1f} deg, its "
                                f"limits are [{low:.1f}, {high:.1f}] deg){hint}")
        if err[i] > max(1e3 * tol, 1e-6):
            raise TrimError(f"trim did not converge for {where} (residual {float(err[i]):.3g}){hint}")


def _result(z, v, h, p: ModelParams, m: int, err, lateral: str) -> TrimResult:
    x = level_state(z, v, h, m, lateral)
    ev = evaluate(x, p)
    qs = 0.5 * ev.density * v**2 * p.wing_area
    banked = lateral == "zero_sideslip"
    return TrimResult(
        airspeed=v, height=h, alpha=z[:, _ALPHA], beta=ev.beta if banked else z[:, _BETA],
        bank=z[:, _BANK] if banked else None, surfaces=z[:, _SURFACES],
        throttle=z[:, _THROTTLE], commands=normalised_command(z[:, _SURFACES], z[:, _THROTTLE], p), state=x,
        thrust=ev.thrust.sum(-1), lift=qs * ev.coefficients[:, _CL], drag=qs * ev.coefficients[:, _CD],
        lift_coefficient=ev.coefficients[:, _CL], drag_coefficient=ev.coefficients[:, _CD],
        induced_drag_coefficient=ev.induced_drag_coefficient, residual=err,
    )
