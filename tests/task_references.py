"""Torch references of the built-in tasks, for the tests only: each task's step, start and observation
as the torch expressions of its module docstring (the step the tasks had before their step was written
once, as Warp functions), so that a test can fly a task's Warp step against an independent body.

:func:`torch_reference` replaces an env's task by its reference (a subclass that declares no Warp step:
``fused_stepper = Task.fused_stepper``; built after the env, with the env's generator, so that its
draws are the task's). The references run the base ``Task.torch_step`` (advance, update, reward,
termination, observe) in the simulator's dtype (a float64 env gives a float64 reference).
"""

from __future__ import annotations

import math

import torch
from tensordict import TensorDictBase

from falcon_rl.constants import DEG, G0
from falcon_rl.envs.maneuvers import RandomCommandStream
from falcon_rl.envs.tasks import (
    AltitudeTask,
    AttitudeTask,
    ClimbDescendTask,
    PathFollowingTask,
    TrajectoryTask,
)
from falcon_rl.envs.tasks.base import (
    _WARNED_UNFUSED,
    Task,
    airspeed_margin_penalty,
    gaussian,
    normalised_surfaces,
    taper,
    wrap_angle,
)
from falcon_rl.physics import state as S


def stream_step(stream: RandomCommandStream) -> torch.Tensor:
    """One step of the random command stream: the timer runs down by dt; an expired target is redrawn
    (target and hold from 4 uniforms); the command slews toward the target at ``rate``."""
    stream.timer -= stream.dt
    expired = stream.timer <= 0.0
    n = stream.command.shape[0]
    u = torch.rand(n, 4, generator=stream.generator, device=stream.command.device, dtype=torch.float32)
    u = u.to(stream.command.dtype)
    target = stream.low + (stream.high - stream.low) * u[:, :3]
    lo, hi = stream.hold_seconds
    timer = lo + (hi - lo) * u[:, 3]
    stream.target.copy_(torch.where(expired[:, None], target, stream.target))
    stream.timer.copy_(torch.where(expired, timer, stream.timer))
    step = (stream.target - stream.command).clamp(-stream.rate * stream.dt, stream.rate * stream.dt)
    stream.command += step
    return stream.command


class AltitudeTorchStep:
    """The altitude task's step in torch (also the climb/descend task's)."""

    fused_stepper = Task.fused_stepper

    def after_reset(self, state: TensorDictBase, mask: torch.Tensor) -> None:
        super().after_reset(state, mask)
        for buffer in (self.segment_time, self.time_in_band, self.error_integral):
            buffer.masked_fill_(mask, 0.0)
        elevator = state["surface_position"][:, S.ELEVATOR]
        self.previous_elevator.copy_(torch.where(mask, elevator, self.previous_elevator))
        self.elevator_rate.masked_fill_(mask, 0.0)
        self.previous_airspeed.copy_(torch.where(mask, state["airspeed"], self.previous_airspeed))
        self.airspeed_rate.masked_fill_(mask, 0.0)
        self._update_reference()
        self.altitude_error.copy_(state["height"] - self.target)
        self.reference_error.copy_(state["height"] - self.reference)

    # ------------------------------------------------------------------ reference
    def _update_reference(self) -> None:
        """h_ref and hdot_ref from the ramp's start, target and elapsed time (closed form)."""
        gap = self.target - self.segment_start
        direction = torch.sign(gap)
        remaining = (gap.abs() - self.climb_rate * self.segment_time).clamp_min(0.0)
        self.reference.copy_(self.target - direction * remaining)
        self.reference_rate.copy_(torch.where(remaining > 0, direction * self.climb_rate, 0.0))

    def advance(self) -> None:
        super().advance()
        self.segment_time += self.control_dt
        self._update_reference()

    def _release_next_targets(self, height: torch.Tensor) -> None:
        """Target sequence: envs that held h* for hold_seconds get a new, different target."""
        cfg = self.config
        inside = (height - self.target).abs() <= cfg.capture_band
        self.time_in_band.copy_(torch.where(inside, self.time_in_band + self.control_dt, 0.0))
        held = self.time_in_band >= cfg.hold_seconds
        table = self.target_table
        shift = torch.randint(1, max(len(table), 2), (self.num_envs,), generator=self.generator,
                              device=self.device)
        current = (self.target[:, None] - table).abs().argmin(-1)
        new_target = table[(current + shift) % len(table)]
        self.segment_start.copy_(torch.where(held, self.target, self.segment_start))
        self.initial_altitude.copy_(torch.where(held, self.target, self.initial_altitude))
        self.target.copy_(torch.where(held, new_target, self.target))
        self.segment_time.masked_fill_(held, 0.0)
        self.time_in_band.masked_fill_(held, 0.0)
        self._update_reference()

    # ------------------------------------------------------------------ MDP
    def update(self, state: TensorDictBase) -> None:
        cfg = self.config
        height = state["height"]
        if cfg.target_sequence:
            self._release_next_targets(height)
        self.altitude_error.copy_(height - self.target)
        self.reference_error.copy_(height - self.reference)
        elevator = state["surface_position"][:, S.ELEVATOR]
        torch.div(elevator - self.previous_elevator, self.control_dt, out=self.elevator_rate)
        self.previous_elevator.copy_(elevator)
        torch.div(state["airspeed"] - self.previous_airspeed, self.control_dt, out=self.airspeed_rate)
        self.previous_airspeed.copy_(state["airspeed"])
        self.error_integral.copy_((self.error_integral + (height - self.reference) * self.control_dt)
                                  .clamp(-cfg.integral_limit, cfg.integral_limit))

    def observe(self, state: TensorDictBase) -> torch.Tensor:
        cfg = self.config
        e_h = state["height"] - self.reference
        surfaces = normalised_surfaces(state, self.sim)
        throttle = 2.0 * state["throttle"].mean(-1) - 1.0
        obs = torch.stack([
            e_h / 25.0,
            state["angular_rate_body"][:, S.PITCH] / 2.0,
            (state["airspeed"] - self.trim_airspeed) / (cfg.airspeed_scale * self.trim_airspeed),
            state["euler"][:, S.PITCH] / (math.pi / 4),
            state["velocity_ned"][:, S.DOWN] / self.airframe.envelope.climb_rate_limit,
            state["alpha"] / (20.0 * DEG),
            surfaces[:, S.ELEVATOR],
            self.elevator_rate / (100.0 * DEG),
            throttle,
            self.error_integral / 10.0,
            self.reference_rate / 5.0,
        ], dim=-1)
        return obs.clamp(-self.observation_clip, self.observation_clip)

    def reward_terms_of(self, state: TensorDictBase, action: torch.Tensor) -> tuple[torch.Tensor, ...]:
        cfg = self.config
        e_h = state["height"] - self.reference
        e_v = state["airspeed"] - self.trim_airspeed
        q = state["angular_rate_body"][:, S.PITCH]
        action_rate = torch.linalg.vector_norm(action - self.previous_action, dim=-1)
        direction = torch.sign(self.target - self.initial_altitude)
        past_target = (direction * (state["height"] - self.target)).clamp_min(0.0)
        return (cfg.w_altitude * gaussian(e_h, cfg.sigma_altitude),
                -(cfg.w_airspeed * e_v.abs() / self.trim_airspeed),
                -(cfg.w_pitch_rate * torch.clamp(q * q, max=cfg.pitch_rate_cap)),
                -(cfg.w_smooth * action_rate * taper(e_h, cfg.gate_band)),
                cfg.w_altitude * taper(e_h, cfg.capture_band)
                * taper(e_v, cfg.airspeed_band_fraction * self.trim_airspeed),
                torch.full_like(e_h, cfg.survival_bonus),
                -(cfg.w_overshoot * past_target),
                -(cfg.w_energy_rate * self.energy_rate_error(state).abs().clamp(max=self.energy_rate_cap)))

    def energy_rate_error(self, state: TensorDictBase) -> torch.Tensor:
        """e_E [N]: (hdot + V_a dV_a/dt / g - hdot_ref) / r, r the reference climb rate limit."""
        climb = -state["velocity_ned"][:, S.DOWN]
        energy_rate = climb + state["airspeed"] * self.airspeed_rate / G0
        return (energy_rate - self.reference_rate) / self.airframe.envelope.climb_rate_limit


class AltitudeReference(AltitudeTorchStep, AltitudeTask):
    """The altitude task with its torch step."""


class ClimbDescendReference(AltitudeTorchStep, ClimbDescendTask):
    """The climb/descend task with its torch step."""


class AttitudeReference(AttitudeTask):
    """The attitude task with its torch step."""

    fused_stepper = Task.fused_stepper

    def after_reset(self, state: TensorDictBase, mask: torch.Tensor) -> None:
        super().after_reset(state, mask)
        self.commanded.copy_(torch.where(mask[:, None], self._current_command(), self.commanded))
        self._update_errors(state)

    # ------------------------------------------------------------------ command stream
    def _current_command(self) -> torch.Tensor:
        if self.random_stream is not None:
            return self.random_stream.command
        assert self.table is not None
        return self.table[self.step_index.clamp(max=self.table.shape[0] - 1)]

    def advance(self) -> None:
        super().advance()
        self.step_index += 1
        if self.random_stream is not None:
            stream_step(self.random_stream)
        self.commanded.copy_(self._current_command())

    def _update_errors(self, state: TensorDictBase) -> None:
        climb_rate = -state["velocity_ned"][:, S.DOWN]
        actual = torch.stack([state["euler"][:, S.ROLL], climb_rate, state["airspeed"]], dim=-1)
        self.errors.copy_(actual - self.commanded)

    # ------------------------------------------------------------------ MDP
    def update(self, state: TensorDictBase) -> None:
        self._update_errors(state)

    def observe(self, state: TensorDictBase) -> torch.Tensor:
        # Errors from the state being observed (measured when a sensor chain is on), not the
        # true-state errors that the reward and metrics use.
        climb_rate = -state["velocity_ned"][:, S.DOWN]
        actual = torch.stack([state["euler"][:, S.ROLL], climb_rate, state["airspeed"]], dim=-1)
        errors = actual - self.commanded
        rates = state["angular_rate_body"] / 2.0
        euler = state["euler"][:, :2] / (math.pi / 4)
        air = torch.stack([state["alpha"], state["beta"]], dim=-1) / (20.0 * DEG)
        v_z = state["velocity_ned"][:, S.DOWN, None] / self.climb_scale
        obs = torch.cat([errors / self.error_scale, euler, rates, air, v_z, self.previous_action],
                        dim=-1)
        return obs.clamp(-self.observation_clip, self.observation_clip)

    def reward_terms_of(self, state: TensorDictBase, action: torch.Tensor) -> tuple[torch.Tensor, ...]:
        cfg = self.config
        env = self.airframe.envelope
        e_phi, e_hdot, e_v = self.errors.unbind(-1)
        action_rate = ((action - self.previous_action) ** 2).sum(-1)
        return (cfg.w_bank * gaussian(e_phi, cfg.sigma_bank),
                cfg.w_climb * gaussian(e_hdot, cfg.sigma_climb_fraction * env.climb_rate_limit),
                cfg.w_airspeed * gaussian(e_v, cfg.sigma_airspeed_fraction * env.cruise_speed),
                -(cfg.w_energy * airspeed_margin_penalty(state["airspeed"], self.safe_airspeed)),
                -(cfg.w_smooth * action_rate))


class PathFollowingReference(PathFollowingTask):
    """The path-following task with its torch step."""

    fused_stepper = Task.fused_stepper

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


class TrajectoryReference(TrajectoryTask):
    """The trajectory task with its torch step."""

    fused_stepper = Task.fused_stepper

    def after_reset(self, state: TensorDictBase, mask: torch.Tensor) -> None:
        super().after_reset(state, mask)
        self.advance_reference()
        self.update(state)

    def advance_reference(self) -> None:
        """p_ref and v_ref at the task time (closed form)."""
        angle = self.speed / self.radius * self.time
        s, c = torch.sin(angle), torch.cos(angle)
        offset = torch.stack([self.radius * s, self.turn * self.radius * (1.0 - c), -self.climb * self.time],
                             dim=-1)
        self.reference_position.copy_(self.start + offset)
        self.reference_velocity.copy_(torch.stack([self.speed * c, self.turn * self.speed * s, -self.climb],
                                                  dim=-1))

    def advance(self) -> None:
        super().advance()
        self.advance_reference()

    def update(self, state: TensorDictBase) -> None:
        yaw = state["euler"][:, S.YAW]
        sin_y, cos_y = torch.sin(yaw), torch.cos(yaw)
        e_p = state["position_ned"] - self.reference_position
        e_v = state["velocity_ned"] - self.reference_velocity
        self.position_error_ned.copy_(e_p)
        for out, e in ((self.position_error, e_p), (self.velocity_error, e_v)):
            north, east, down = e[:, S.NORTH], e[:, S.EAST], e[:, S.DOWN]
            out.copy_(torch.stack([cos_y * north + sin_y * east, -sin_y * north + cos_y * east, down],
                                  dim=-1))

    def observe(self, state: TensorDictBase) -> torch.Tensor:
        sigma_v = self.config.airspeed_scale * self.speed
        air = torch.stack([state["alpha"], state["beta"]], dim=-1) / (20.0 * DEG)
        obs = torch.cat([self.position_error / 25.0, self.velocity_error / sigma_v,
                         state["euler"][:, :2] / (math.pi / 4), state["angular_rate_body"] / 2.0, air,
                         self.previous_action], dim=-1)
        return obs.clamp(-self.observation_clip, self.observation_clip)

    def reward_terms_of(self, state: TensorDictBase, action: torch.Tensor) -> tuple[torch.Tensor, ...]:
        cfg = self.config
        distance = torch.linalg.vector_norm(self.position_error, dim=-1)
        speed_error = torch.linalg.vector_norm(self.velocity_error, dim=-1)
        action_rate = ((action - self.previous_action) ** 2).sum(-1)
        return (cfg.w_position * gaussian(distance, cfg.sigma_position),
                cfg.w_velocity * gaussian(speed_error, cfg.sigma_velocity_fraction * self.speed),
                -(cfg.w_energy * airspeed_margin_penalty(state["airspeed"], self.safe_airspeed)),
                -(cfg.w_smooth * action_rate))

    def termination_checks(self, state: TensorDictBase) -> dict[str, torch.Tensor]:
        """The shared checks plus "lost": 3D distance to the reference beyond ``lost_distance``."""
        distance = torch.linalg.vector_norm(self.position_error, dim=-1)
        return {**super().termination_checks(state), "lost": distance > self.config.lost_distance}


#: The reference of each built-in task class.
REFERENCES: dict[type, type] = {AltitudeTask: AltitudeReference, ClimbDescendTask: ClimbDescendReference,
                                AttitudeTask: AttitudeReference, PathFollowingTask: PathFollowingReference,
                                TrajectoryTask: TrajectoryReference}


def torch_reference(env):
    """``env`` (a FixedWingEnv, never stepped) with its task replaced by the task's torch reference, built
    with the env's config, simulator and generator; returns it. A reference does not warn that it steps
    unfused."""
    task = env.task
    _WARNED_UNFUSED.update(REFERENCES.values())
    env.task = REFERENCES[type(task)](task.config, env.sim, env.generator, env.control_dt,
                                      env.config.ground_effect)
    return env
