"""Attitude-command tracking: a low-level executor of (phi*, hdot*, V_a*)(t) owning all actuators.

Episode: trimmed level flight at cruise and ``initial_height``; the command stream is one of the
maneuvers of :mod:`falcon_rl.envs.maneuvers` (circle, figure8, helix, s_turn; the episode lasts the
stream) or ``"random"`` (training streams, random initial heading).

Errors e_phi = phi - phi*, e_hdot = hdot - hdot*, e_Va = V_a - V_a*, with hdot = -v_z (v_z the NED
down velocity). Observation (15, clipped to [-5, 5]):

    o = [e_phi/30deg, e_hdot/sigma_v, e_Va/sigma_V, phi/(pi/4), theta/(pi/4), p/2, q/2, r/2,
         alpha/20deg, beta/20deg, v_z/sigma_v, a_{t-1}]

sigma_v = the airframe's climb-rate limit, sigma_V = ``airspeed_scale`` x cruise speed, a_{t-1} the
previous action (4).

Action [delta_e, delta_a, delta_r, delta_t] in [-1, 1]^4.

Reward:

    r = sum_{i in phi, hdot, Va} w_i exp(-e_i^2 / 2 sigma_i^2)
        - w_E ((V_safe - V_a) / V_safe)^2 [V_a < V_safe] - w_s ||a_t - a_{t-1}||^2

sigma_phi = 8.6 deg (the paper's bank tolerance band), sigma_hdot = 0.25 climb-rate limit,
sigma_Va = 0.05 cruise, V_safe = 1.3 V_stall.
Termination: ground contact, |alpha| > 1.5 alpha_stall or V_a < V_stall; truncation at the horizon.
Published under ("task", ...): bank/climb_rate/airspeed commands and their errors.

The step, the start of episodes and the observation are written once, as Warp functions
(``attitude.kernels``), the random stream's process included (its uniforms drawn from the stream's
generator before each launch); every engine runs them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar

import torch

from ....constants import DEG
from ....physics import Simulator
from ...maneuvers import RandomCommandStream, maneuver_stream
from ..base import Task, TaskConfig

if TYPE_CHECKING:
    from ..warp_common import FusedStep


@dataclass
class AttitudeConfig(TaskConfig):
    """Attitude-command tracking parameters (SI units, angles in rad)."""

    #: "random" (training) or one of falcon_rl.envs.maneuvers.MANEUVERS (episode = the stream).
    maneuver: str = "random"
    episode_seconds: float = 30.0
    initial_height: float = 100.0
    airspeed_scale: float = 0.1
    w_bank: float = 1.0
    sigma_bank: float = 8.6 * DEG
    w_climb: float = 0.5
    sigma_climb_fraction: float = 0.25
    w_airspeed: float = 0.5
    sigma_airspeed_fraction: float = 0.05
    w_energy: float = 2.0
    safe_airspeed_factor: float = 1.3
    w_smooth: float = 0.05

    positive: ClassVar[tuple[str, ...]] = (
        *TaskConfig.positive, "initial_height", "airspeed_scale", "sigma_bank", "sigma_climb_fraction",
        "sigma_airspeed_fraction", "safe_airspeed_factor")


class AttitudeTask(Task):
    """Bank, climb-rate and airspeed command tracking; see the module docstring."""

    name = "attitude"
    observation_dim = 15
    action_dim = 4
    observation_clip = 5.0
    reward_terms = ("bank", "climb", "airspeed", "energy", "smoothness")
    config: AttitudeConfig

    def __init__(self, config: AttitudeConfig, sim: Simulator, generator: torch.Generator,
                 control_dt: float, ground_effect: bool | str = True):
        super().__init__(config, sim, generator, control_dt, ground_effect)
        env = self.airframe.envelope
        n, kw = self.num_envs, {"device": self.device, "dtype": self.buffer_dtype}
        self.climb_scale = float(env.climb_rate_limit)
        self.safe_airspeed = config.safe_airspeed_factor * env.stall_speed
        self.step_index = torch.zeros(n, dtype=torch.long, device=self.device)
        self.random_stream: RandomCommandStream | None = None
        self.table: torch.Tensor | None = None
        if config.maneuver == "random":
            self.random_stream = RandomCommandStream(self.airframe, n, generator, self.control_dt, **kw)
        else:
            self.table = maneuver_stream(config.maneuver, self.airframe, self.control_dt).to(**kw)
        self.commanded = torch.zeros(n, 3, **kw)
        self.errors = torch.zeros(n, 3, **kw)  # (e_phi, e_hdot, e_Va)
        self.error_scale = torch.tensor(
            [30.0 * DEG, self.climb_scale, config.airspeed_scale * env.cruise_speed], **kw)
        self._fused: FusedStep | None = None  # bound on the first fused step

    @property
    def episode_seconds(self) -> float:
        if self.table is not None:
            return self.table.shape[0] * self.control_dt
        return self.config.episode_seconds

    # ------------------------------------------------------------------ episode start
    def sample_initial(self, mask: torch.Tensor) -> dict[str, torch.Tensor]:
        yaw = self.uniform(-math.pi, math.pi) if self.random_stream is not None else None
        if self.random_stream is not None:
            self.random_stream.reset(mask)
        self.step_index.masked_fill_(mask, 0)
        height = torch.full((self.num_envs,), self.config.initial_height, device=self.device,
                            dtype=self.dtype)
        return {**self.trim_initial(yaw), "position_ned": torch.zeros(3, device=self.device,
                                                                      dtype=self.dtype),
                "height": height}

    # ------------------------------------------------------------------ step
    def fused_stepper(self) -> FusedStep:
        """The task's step, its start and its observation (``attitude.kernels``, :class:`FusedAttitudeStep`):
        (observation [N, 15], reward [N], reason [N] long), buffers overwritten by the next call. The
        random stream's process is the kernel's: a stream of another class than ``RandomCommandStream``
        is refused (TypeError)."""
        stream = self.random_stream
        if stream is not None and type(stream) is not RandomCommandStream:
            raise TypeError(f"the attitude task's Warp step runs the RandomCommandStream process; a "
                            f"{type(stream).__name__} cannot be stepped (change the kernel's stream_step)")
        from ..warp_common import fused_stepper
        from .kernels import FusedAttitudeStep

        return fused_stepper(self, FusedAttitudeStep)

    def info_views(self) -> dict[str, torch.Tensor]:
        return {
            "bank_command": self.commanded[:, 0],
            "climb_rate_command": self.commanded[:, 1],
            "airspeed_command": self.commanded[:, 2],
            "bank_error": self.errors[:, 0],
            "climb_rate_error": self.errors[:, 1],
            "airspeed_error": self.errors[:, 2],
        }
