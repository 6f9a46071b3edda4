"""3D trajectory tracking: follow a point moving along a climbing or descending turn.

Episode: trimmed level flight at cruise and ``initial_height``, heading north, at the origin. The
reference point starts ``U(lead_min, lead_max)`` m ahead, +-U(0, ``lateral_max``) m to the side and
+-U(0, ``vertical_max``) m off in height, and moves at cruise speed V along a helix arc of turn
direction s = +-1, radius R = V^2 / (g tan phi_ref) with phi_ref ~ U(``bank_min``, ``bank_max``)
x max_bank, and climb rate hdot_ref ~ U(-1, 1) ``climb_fraction`` x climb_rate_limit:

    omega = V / R,  p_ref(t) = p_0 + (R sin(omega t), s R (1 - cos(omega t)), -hdot_ref t)   (NED)
    v_ref(t) = (V cos(omega t), s V sin(omega t), -hdot_ref)

Errors e_p = p - p_ref and e_v = v - v_ref rotated into the heading frame (yaw psi only:
forward, right, down). Observation (17, clipped to [-5, 5]):

    o = [e_p/25, e_v/sigma_V, phi/(pi/4), theta/(pi/4), p/2, q/2, r/2, alpha/20deg, beta/20deg,
         a_{t-1}]

sigma_V = ``airspeed_scale`` x cruise. Action [delta_e, delta_a, delta_r, delta_t]. Reward:

    r = w_p exp(-|e_p|^2 / 2 sigma_p^2) + w_v exp(-|e_v|^2 / 2 sigma_v^2)
        - w_E ((V_safe - V_a)/V_safe)^2 [V_a < V_safe] - w_s ||a_t - a_{t-1}||^2

Termination: ground contact, stall, or |e_p| > ``lost_distance``. Published: position_error
(|e_p|), position_error_ned [3], reference_position [3], reference_velocity [3] and reference_curvature
s / R (1/m, the horizontal path's; positive turning right), what a path-following guidance reads.

The step, the start of episodes and the observation are written once, as Warp functions
(``trajectory.kernels``); every engine runs them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar

import torch

from ....constants import G0
from ....physics import Simulator
from ..base import Task, TaskConfig

if TYPE_CHECKING:
    from ..warp_common import FusedStep


@dataclass
class TrajectoryConfig(TaskConfig):
    """3D trajectory tracking parameters (SI units)."""

    episode_seconds: float = 40.0
    initial_height: float = 80.0
    lead_min: float = 10.0
    lead_max: float = 40.0
    lateral_max: float = 20.0
    vertical_max: float = 10.0
    bank_min: float = 0.1
    bank_max: float = 0.5
    climb_fraction: float = 0.5
    lost_distance: float = 250.0
    airspeed_scale: float = 0.1
    w_position: float = 1.0
    sigma_position: float = 10.0
    w_velocity: float = 0.5
    sigma_velocity_fraction: float = 0.1
    w_energy: float = 2.0
    safe_airspeed_factor: float = 1.3
    w_smooth: float = 0.05

    positive: ClassVar[tuple[str, ...]] = (
        *TaskConfig.positive, "initial_height", "lead_min", "lost_distance", "airspeed_scale",
        "sigma_position", "sigma_velocity_fraction", "safe_airspeed_factor")
    non_negative: ClassVar[tuple[str, ...]] = ("lateral_max", "vertical_max", "bank_min", "climb_fraction")
    ordered: ClassVar[tuple[tuple[str, str], ...]] = (("lead_min", "lead_max"), ("bank_min", "bank_max"))


class TrajectoryTask(Task):
    """Tracking of a moving 3D reference point; see the module docstring."""

    name = "trajectory"
    observation_dim = 17
    action_dim = 4
    observation_clip = 5.0
    reward_terms = ("position", "velocity", "energy", "smoothness")
    config: TrajectoryConfig

    def __init__(self, config: TrajectoryConfig, sim: Simulator, generator: torch.Generator,
                 control_dt: float, ground_effect: bool | str = True):
        super().__init__(config, sim, generator, control_dt, ground_effect)
        n, kw = self.num_envs, {"device": self.device, "dtype": self.buffer_dtype}
        self.speed = float(self.airframe.envelope.cruise_speed)
        self.start = torch.zeros(n, 3, **kw)  # p_0, NED
        self.radius = torch.ones(n, **kw)
        self.turn = torch.ones(n, **kw)  # s = +-1
        self.climb = torch.zeros(n, **kw)
        self.reference_position = torch.zeros(n, 3, **kw)
        self.reference_velocity = torch.zeros(n, 3, **kw)
        self.position_error = torch.zeros(n, 3, **kw)  # heading frame
        self.velocity_error = torch.zeros(n, 3, **kw)  # heading frame
        self.position_error_ned = torch.zeros(n, 3, **kw)
        self.safe_airspeed = config.safe_airspeed_factor * self.airframe.envelope.stall_speed
        self._fused: FusedStep | None = None  # bound on the first fused step

    def sample_initial(self, mask: torch.Tensor) -> dict[str, torch.Tensor]:
        cfg = self.config
        env = self.airframe.envelope
        start = torch.stack([
            self.uniform(cfg.lead_min, cfg.lead_max),
            self.uniform(-cfg.lateral_max, cfg.lateral_max),
            -cfg.initial_height + self.uniform(-cfg.vertical_max, cfg.vertical_max)], dim=-1)
        bank = self.uniform(cfg.bank_min, cfg.bank_max) * env.max_bank
        radius = self.speed**2 / (G0 * torch.tan(bank))
        climb = self.uniform(-cfg.climb_fraction, cfg.climb_fraction) * env.climb_rate_limit
        self.start.copy_(torch.where(mask[:, None], start, self.start))
        for buffer, value in ((self.radius, radius), (self.turn, self.random_sign()), (self.climb, climb)):
            buffer.copy_(torch.where(mask, value, buffer))
        height = torch.full((self.num_envs,), cfg.initial_height, device=self.device, dtype=self.dtype)
        return {**self.trim_initial(), "position_ned": torch.zeros(3, device=self.device, dtype=self.dtype),
                "height": height}

    def fused_stepper(self) -> FusedStep:
        """The task's step, its start and its observation (``trajectory.kernels``,
        :class:`FusedTrajectoryStep`): (observation [N, 17], reward [N], reason [N] long), buffers
        overwritten by the next call."""
        from ..warp_common import fused_stepper
        from .kernels import FusedTrajectoryStep

        return fused_stepper(self, FusedTrajectoryStep)

    def info(self) -> dict[str, torch.Tensor]:
        info = {"position_error": torch.linalg.vector_norm(self.position_error, dim=-1),
                "position_error_ned": self.position_error_ned, "reference_position": self.reference_position,
                "reference_velocity": self.reference_velocity, "reference_curvature": self.turn / self.radius}
        return {key: value.to(self.dtype, copy=True) for key, value in info.items()}
