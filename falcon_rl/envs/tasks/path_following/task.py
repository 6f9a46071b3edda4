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

On the warp backend the env's step runs :meth:`PathFollowingTask.fused_step`: all of the above after
the physics in one Warp kernel (``path_following.kernels``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar

import torch
from tensordict import TensorDictBase

from ....constants import DEG
from ....physics import Simulator
from ....physics import state as S
from ..base import Task, TaskConfig, airspeed_margin_penalty, gaussian, wrap_angle

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
        n, kw = self.num_envs, {"device": self.device, "dtype": self.dtype}
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

    def after_reset(self, state: TensorDictBase, mask: torch.Tensor) -> None:
        super().after_reset(state, mask)
        self.update(state)

    def update(self, state: TensorDictBase) -> None:
        rel = state["position_ned"][:, :2] - self.path_point
        sin_c, cos_c = torch.sin(self.path_course), torch.cos(self.path_course)
        cross_track = -sin_c * rel[:, S.NORTH] + cos_c * rel[:, S.EAST]
        v = state["velocity_ned"]
        course_error = wrap_angle(torch.atan2(v[:, S.EAST], v[:, S.NORTH]) - self.path_course)
        altitude_error = state["height"] - self.config.initial_height
        self.errors.copy_(torch.stack([cross_track, course_error, altitude_error], dim=-1))

    def observe(self, state: TensorDictBase) -> torch.Tensor:
        cfg = self.config
        env = self.airframe.envelope
        e_y, chi, e_h = self.errors.unbind(-1)
        scalars = torch.stack([
            e_y / 50.0, torch.sin(chi), torch.cos(chi), e_h / 25.0,
            state["velocity_ned"][:, S.DOWN] / env.climb_rate_limit,
            (state["airspeed"] - env.cruise_speed) / (cfg.airspeed_scale * env.cruise_speed),
            state["euler"][:, S.ROLL] / (math.pi / 4), state["euler"][:, S.PITCH] / (math.pi / 4),
            state["alpha"] / (20.0 * DEG), state["beta"] / (20.0 * DEG),
        ], dim=-1)
        obs = torch.cat([scalars, state["angular_rate_body"] / 2.0, self.previous_action], dim=-1)
        return obs.clamp(-self.observation_clip, self.observation_clip)

    def reward_terms_of(self, state: TensorDictBase, action: torch.Tensor) -> tuple[torch.Tensor, ...]:
        cfg = self.config
        e_y, chi, e_h = self.errors.unbind(-1)
        action_rate = ((action - self.previous_action) ** 2).sum(-1)
        return (cfg.w_cross_track * gaussian(e_y, cfg.sigma_cross_track),
                cfg.w_course * gaussian(chi, cfg.sigma_course),
                cfg.w_altitude * gaussian(e_h, cfg.sigma_altitude),
                -(cfg.w_energy * airspeed_margin_penalty(state["airspeed"], self.safe_airspeed)),
                -(cfg.w_smooth * action_rate))

    def termination_checks(self, state: TensorDictBase) -> dict[str, torch.Tensor]:
        """The shared checks plus "lost": cross-track error beyond ``lost_distance``."""
        lost = self.errors[:, 0].abs() > self.config.lost_distance
        return {**super().termination_checks(state), "lost": lost}

    def fused_stepper(self) -> FusedStep | None:
        """:meth:`step` as one Warp kernel on the warp backend (``path_following.kernels``; None elsewhere,
        or when a subclass overrides a method of the step): (observation [N, 17], reward [N], reason [N]
        long), buffers overwritten by the next call."""
        if not self.sim.engine.runs_task_kernels:
            return None
        from ..warp_common import fused_stepper
        from .kernels import FusedPathFollowingStep

        return fused_stepper(self, PathFollowingTask, _FUSED_METHODS, FusedPathFollowingStep)

    def info(self) -> dict[str, torch.Tensor]:
        return {"cross_track_error": self.errors[:, 0].clone(), "course_error": self.errors[:, 1].clone(),
                "altitude_error": self.errors[:, 2].clone(), "path_point": self.path_point.clone(),
                "path_course": self.path_course.clone(),
                "path_height": torch.full_like(self.path_course, self.config.initial_height)}


#: The methods :meth:`PathFollowingTask.fused_step` fuses: a subclass that overrides one falls back to
#: ``step``.
_FUSED_METHODS: tuple[str, ...] = ("step", "advance", "update", "reward", "reward_terms_of", "observe",
                                   "termination_checks",
                                   "termination_reason")
