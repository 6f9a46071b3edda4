"""2D path following: fly along a straight line in the horizontal plane at constant altitude.

Episode: trimmed level flight at cruise and ``initial_height``, heading north. The path passes
through a point ``+-U(offset_min, offset_max)`` m to the side of the aircraft with course
chi_p = U(-max_course_error, max_course_error) (so the aircraft starts off the line and misaligned).

Cross-track error e_y = -sin(chi_p) (n - n_p) + cos(chi_p) (e - e_p) (m, positive right of the path),
course error chi_err = wrap(chi - chi_p) with chi = atan2(v_e, v_n), e_h = h - h_path,
e_Va = V_a - cruise. Observation (17, clipped to [-5, 5]):

    o = [e_y/50, sin chi_err, cos chi_err, e_h/25, v_z/sigma_v, e_Va/sigma_V, phi/(pi/4),
         theta/(pi/4), p/2, q/2, r/2, alpha/20deg, beta/20deg, a_{t-1}]

Action [delta_e, delta_a, delta_r, delta_t]. Reward:

    r = w_y exp(-e_y^2 / 2 sigma_y^2) + w_chi exp(-chi_err^2 / 2 sigma_chi^2)
        + w_h exp(-e_h^2 / 2 sigma_h^2) - w_E ((V_safe - V_a)/V_safe)^2 [V_a < V_safe]
        - w_s ||a_t - a_{t-1}||^2

Termination: ground contact, stall, or |e_y| > ``lost_distance``. Published: cross_track_error,
course_error, altitude_error and the path: path_point [2] (north, east, m), path_course (rad),
path_height (m).

The step, the start of episodes and the observation are written once, as Warp functions
(``path_following.kernels``); every engine runs them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar

import torch

from ....constants import DEG
from ....physics import Simulator
from ..base import Task, TaskConfig

if TYPE_CHECKING:
    from ..warp_common import FusedStep


@dataclass
class PathFollowingConfig(TaskConfig):
    """Straight-line path following parameters (SI units, angles in rad)."""

    episode_seconds: float = 40.0
    initial_height: float = 60.0
    offset_min: float = 10.0
    offset_max: float = 50.0
    max_course_error: float = 45.0 * DEG
    lost_distance: float = 300.0
    airspeed_scale: float = 0.1
    w_cross_track: float = 1.0
    sigma_cross_track: float = 5.0
    w_course: float = 0.3
    sigma_course: float = 15.0 * DEG
    w_altitude: float = 0.5
    sigma_altitude: float = 3.0
    w_energy: float = 2.0
    safe_airspeed_factor: float = 1.3
    w_smooth: float = 0.05

    positive: ClassVar[tuple[str, ...]] = (
        *TaskConfig.positive, "initial_height", "max_course_error", "lost_distance", "airspeed_scale",
        "sigma_cross_track", "sigma_course", "sigma_altitude", "safe_airspeed_factor")
    non_negative: ClassVar[tuple[str, ...]] = ("offset_min",)
    ordered: ClassVar[tuple[tuple[str, str], ...]] = (("offset_min", "offset_max"),)


class PathFollowingTask(Task):
    """Straight-line following in the horizontal plane; see the module docstring."""

    name = "path_following"
    observation_dim = 17
    action_dim = 4
    observation_clip = 5.0
    reward_terms = ("cross_track", "course", "altitude", "energy", "smoothness")
    config: PathFollowingConfig

    def __init__(self, config: PathFollowingConfig, sim: Simulator, generator: torch.Generator,
                 control_dt: float, ground_effect: bool | str = True):
        super().__init__(config, sim, generator, control_dt, ground_effect)
        n, kw = self.num_envs, {"device": self.device, "dtype": self.buffer_dtype}
        self.path_point = torch.zeros(n, 2, **kw)  # (north, east) m
        self.path_course = torch.zeros(n, **kw)
        self.errors = torch.zeros(n, 3, **kw)  # (e_y, chi_err, e_h)
        self.safe_airspeed = config.safe_airspeed_factor * self.airframe.envelope.stall_speed
        self._fused: FusedStep | None = None  # bound on the first fused step

    def sample_initial(self, mask: torch.Tensor) -> dict[str, torch.Tensor]:
        cfg = self.config
        course = self.uniform(-cfg.max_course_error, cfg.max_course_error)
        lateral = self.random_sign() * self.uniform(cfg.offset_min, cfg.offset_max)
        # the path point sits `lateral` m across the path from the aircraft (at the origin)
        point = torch.stack([lateral * torch.sin(course), -lateral * torch.cos(course)], dim=-1)
        self.path_course.copy_(torch.where(mask, course, self.path_course))
        self.path_point.copy_(torch.where(mask[:, None], point, self.path_point))
        height = torch.full((self.num_envs,), cfg.initial_height, device=self.device, dtype=self.dtype)
        return {**self.trim_initial(), "position_ned": torch.zeros(3, device=self.device, dtype=self.dtype),
                "height": height}

    def fused_stepper(self) -> FusedStep:
        """The task's step, its start and its observation (``path_following.kernels``,
        :class:`FusedPathFollowingStep`): (observation [N, 17], reward [N], reason [N] long), buffers
        overwritten by the next call."""
        from ..warp_common import fused_stepper
        from .kernels import FusedPathFollowingStep

        return fused_stepper(self, FusedPathFollowingStep)

    def info(self) -> dict[str, torch.Tensor]:
        info = {"cross_track_error": self.errors[:, 0], "course_error": self.errors[:, 1],
                "altitude_error": self.errors[:, 2], "path_point": self.path_point,
                "path_course": self.path_course,
                "path_height": torch.full_like(self.path_course, self.config.initial_height)}
        return {key: value.to(self.dtype, copy=True) for key, value in info.items()}
