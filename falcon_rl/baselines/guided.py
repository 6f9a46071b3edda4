"""Guided controllers: lateral guidance (NPFG or L1) and TECS's altitude loop above an attitude executor.

A path (from the task's published ("task", ...) entries) becomes the attitude executor's commands:

    bank*  = atan(a / (g cos theta))    a the lateral acceleration of NPFG (PX4) or L1 (ArduPilot)
    hdot*  = TECS's altitude loop: clamp((h_ref - h) / FW_T_ALT_TC + FW_T_HRATE_FF hdot_ref, -sink, climb)
    V_a*   = the guidance's airspeed reference (NPFG: the nominal airspeed, raised in excess wind; L1: the
             nominal airspeed)

and an executor turns them into surface and throttle commands: :class:`LQRExecutor` (the gain-scheduled
attitude LQRI, ``AttitudeLQR.control``) or :class:`PolicyExecutor` (a trained attitude-task policy, e.g.
the shipped PPO one, fed the attitude task's own observation of the state and the commands). The guidance
reads the true state: position, ground velocity, attitude, and the wind as an autopilot's estimator gives it
(ground velocity minus the air velocity, gusts included). The climb and sink limits are the airframe's
climb-rate limit (TECS's FW_T_CLMB_MAX / FW_T_SINK_MAX when smaller); the roll limit the airframe's
``max_bank`` (FW_R_LIM / ROLL_LIMIT when smaller).

Paths: :class:`PathGuidance` flies the ``path_following`` task's line (("task", "path_point"),
("task", "path_course") at ("task", "path_height")); :class:`TrajectoryGuidance` the ``trajectory``
task's moving reference (its arc, its height, and the along-track gap closed by the airspeed).
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING, Literal, Protocol

import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModuleBase

from ..envs.layout import flat_scalars
from ..physics.rotations import body_to_ned
from .guidance.l1 import L1Params, l1_loiter, l1_waypoints
from .guidance.npfg import NPFGParams, npfg
from .guidance.paths import PathFrame, circle_frame, line_frame, unit
from .guidance.tecs import TECSParams, climb_rate_setpoint
from .lqr import AttitudeLQR, GainSchedule

if TYPE_CHECKING:
    from pathlib import Path

    from ..airframe import Airframe
    from ..envs import FixedWingEnv

Lateral = Literal["npfg", "l1"]
#: How far ahead of the closest point the L1 line's second waypoint lies (m; ArduPilot's update_path).
L1_LINE_AHEAD = 100.0
#: The state entries guidance and executors read.
STATE_KEYS: tuple[str, ...] = ("position_ned", "quaternion", "velocity_body", "velocity_ned",
                               "angular_rate_body", "euler", "height", "airspeed", "alpha", "beta",
                               "surface_position", "throttle", "time")


def air_velocity_ned(v: TensorDictBase) -> torch.Tensor:
    """[N, 3] the air-relative velocity in NED from airspeed, alpha, beta and the attitude of the [N]
    scalars ``v`` (body air velocity V (cos a cos b, sin b, sin a cos b), rotated)."""
    speed, alpha, beta = v["state", "airspeed"], v["state", "alpha"], v["state", "beta"]
    body = speed.unsqueeze(-1) * torch.stack([torch.cos(alpha) * torch.cos(beta), torch.sin(beta),
                                              torch.sin(alpha) * torch.cos(beta)], dim=-1)
    return body_to_ned(v["state", "quaternion"], body)


class PathGuidance:
    """Lateral guidance (``lateral``: NPFG or L1) and TECS's altitude loop for the path-following task's
    line: :meth:`commands` gives (bank, climb rate, airspeed) [N] from the env's [N] scalars."""

    #: The ("task", ...) entries the path is read from.
    path_keys: tuple[str, ...] = ("path_point", "path_course", "path_height")

    def __init__(self, airframe: Airframe, dt: float, lateral: Lateral = "npfg",
                 airspeed: float | None = None, npfg_params: NPFGParams | None = None,
                 l1_params: L1Params | None = None, tecs_params: TECSParams | None = None):
        if lateral not in ("npfg", "l1"):
            raise ValueError(f"lateral guidance must be 'npfg' or 'l1', got {lateral!r}")
        envelope = airframe.envelope
        self.dt = float(dt)
        self.lateral = lateral
        self.airspeed = float(airspeed or envelope.cruise_speed)
        self.airspeed_max = float(envelope.max_speed)
        climb = float(envelope.climb_rate_limit)
        npfg_params, l1_params = npfg_params or NPFGParams(), l1_params or L1Params()
        tecs_params = tecs_params or TECSParams()
        self.npfg_params = replace(npfg_params, FW_R_LIM=min(npfg_params.FW_R_LIM, envelope.max_bank))
        self.l1_params = replace(l1_params, ROLL_LIMIT=min(l1_params.ROLL_LIMIT, envelope.max_bank))
        self.tecs_params = replace(tecs_params, FW_T_CLMB_MAX=min(tecs_params.FW_T_CLMB_MAX, climb),
                                   FW_T_SINK_MAX=min(tecs_params.FW_T_SINK_MAX, climb))
        self.l1_integrator: torch.Tensor | None = None

    def path(self, v: TensorDictBase) -> tuple[PathFrame, torch.Tensor, torch.Tensor]:
        """(the path frame at the aircraft, the reference height [N] m, its rate [N] m/s)."""
        position = v["state", "position_ned"][:, :2]
        frame = line_frame(position, v["task", "path_point"], v["task", "path_course"])
        height_ref = v["task", "path_height"]
        return frame, height_ref, torch.zeros_like(height_ref)

    def commands(self, v: TensorDictBase) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(bank [N] rad, climb rate [N] m/s, airspeed [N] m/s) the guidance commands."""
        frame, height_ref, height_rate_ref = self.path(v)
        ground_velocity = v["state", "velocity_ned"][:, :2]
        pitch, yaw = v["state", "euler"][:, 1], v["state", "euler"][:, 2]
        if self.lateral == "npfg":
            wind = ground_velocity - air_velocity_ned(v)[:, :2]
            out = npfg(frame, ground_velocity, wind, self.airspeed, self.airspeed_max, pitch,
                       self.npfg_params)
            bank, speed = out.bank, out.airspeed_ref.clamp(max=self.airspeed_max)
        else:
            bank = self._l1_bank(v, frame, ground_velocity, pitch, yaw)
            speed = torch.full_like(bank, self.airspeed)
        climb = climb_rate_setpoint(v["state", "height"], height_ref, height_rate_ref, self.tecs_params)
        return bank, climb, speed

    def _l1_bank(self, v: TensorDictBase, frame: PathFrame, ground_velocity: torch.Tensor,
                 pitch: torch.Tensor, yaw: torch.Tensor) -> torch.Tensor:
        """L1's bank [N]: along the line through the closest point (ArduPilot's update_path), or loitering
        about the centre of curvature of an arc; the cross-track integrator restarts with each episode."""
        position = v["state", "position_ned"][:, :2]
        normal = torch.stack([-frame.tangent[:, 1], frame.tangent[:, 0]], dim=-1)
        closest = position - frame.track_error.unsqueeze(-1) * normal
        fresh = v["state", "time"] <= 0.5 * self.dt
        integrator = self.l1_integrator
        if integrator is None or integrator.shape != fresh.shape:
            integrator = torch.zeros_like(frame.track_error)
        integrator = torch.where(fresh, torch.zeros_like(integrator), integrator)
        ahead = closest + L1_LINE_AHEAD * frame.tangent
        line = l1_waypoints(position, closest, ahead, ground_velocity, yaw, self.dt, integrator, pitch,
                            self.l1_params)
        self.l1_integrator = line.integrator
        curved = frame.curvature != 0.0  # both laws every step: no host sync to ask which rows curve
        radius = 1.0 / frame.curvature.abs().clamp_min(1e-6)
        direction = torch.sign(frame.curvature)
        center = closest + (direction * radius).unsqueeze(-1) * normal
        arc = l1_loiter(position, center, radius, direction, ground_velocity, yaw, pitch, self.l1_params)
        return torch.where(curved, arc.bank, line.bank)


class TrajectoryGuidance(PathGuidance):
    """The guidance on the trajectory task's moving reference: the lateral law flies the reference's
    horizontal arc (centre p_ref + n / kappa, n the unit normal right of v_ref, kappa the published
    ``reference_curvature``), TECS's altitude loop the reference height with its rate fed forward in full
    (FW_T_HRATE_FF 1: a ramp is then held without a lag), and the airspeed closes the along-track gap:

        V_a* = clamp(|v_ref,h| + e_along / ``along_track_time``, 0.85 V_nominal, V_max),
        e_along = (p_ref - p) . v_ref,h / |v_ref,h|
    """

    path_keys = ("reference_position", "reference_velocity", "reference_curvature")

    def __init__(self, *args, along_track_time: float = 4.0, **kwargs):
        kwargs["tecs_params"] = kwargs.get("tecs_params") or TECSParams(FW_T_HRATE_FF=1.0)
        super().__init__(*args, **kwargs)
        self.along_track_time = float(along_track_time)
        self.airspeed_min = 0.85 * self.airspeed

    def path(self, v: TensorDictBase) -> tuple[PathFrame, torch.Tensor, torch.Tensor]:
        position = v["state", "position_ned"][:, :2]
        reference, velocity = v["task", "reference_position"], v["task", "reference_velocity"]
        curvature = v["task", "reference_curvature"]
        tangent = unit(velocity[:, :2])
        right = torch.stack([-tangent[:, 1], tangent[:, 0]], dim=-1)
        radius = 1.0 / curvature.abs().clamp_min(1e-6)
        center = reference[:, :2] + (torch.sign(curvature) * radius).unsqueeze(-1) * right
        ground_velocity = v["state", "velocity_ned"][:, :2]
        frame = circle_frame(position, center, radius, torch.sign(curvature), ground_velocity)
        return frame, -reference[:, 2], -velocity[:, 2]

    def commands(self, v: TensorDictBase) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        bank, climb, _ = super().commands(v)
        velocity = v["task", "reference_velocity"][:, :2]
        along = ((v["task", "reference_position"][:, :2] - v["state", "position_ned"][:, :2])
                 * unit(velocity)).sum(-1)
        speed = (velocity.norm(dim=-1) + along / self.along_track_time).clamp(self.airspeed_min,
                                                                              self.airspeed_max)
        return bank, climb, speed


class Executor(Protocol):
    """An attitude executor: the action [N, A] that holds (bank, climb rate, airspeed) [N] from the env's
    TensorDict ``td`` and its [N] scalars ``v``."""

    in_keys: list

    def act(self, td: TensorDictBase, v: TensorDictBase, bank: torch.Tensor, climb: torch.Tensor,
            speed: torch.Tensor) -> torch.Tensor: ...


class LQRExecutor:
    """The attitude LQRI (:class:`~falcon_rl.baselines.lqr.AttitudeLQR`; its gain ``schedule``, by default
    out of ground effect at 100 m) as an executor."""

    def __init__(self, airframe: Airframe, dt: float, device: str | torch.device = "cpu",
                 dtype: torch.dtype = torch.float32, schedule: GainSchedule | None = None):
        self.lqr = AttitudeLQR(airframe, dt, device, dtype, schedule=schedule)
        self.in_keys = [("state", k) for k in STATE_KEYS]

    def act(self, td: TensorDictBase, v: TensorDictBase, bank: torch.Tensor, climb: torch.Tensor,
            speed: torch.Tensor) -> torch.Tensor:
        return self.lqr.control(v, bank, climb, speed, v["state", "height"])


class PolicyExecutor:
    """A trained attitude-task policy (a policy file, e.g. the shipped PPO one) as an executor: the
    attitude task's own observation (its Warp observe kernel, on an attitude task built over the env's
    simulator) of the state, the commands and the executor's previous action (zero at each episode's
    start), then the policy."""

    def __init__(self, env: FixedWingEnv, path: str | Path):
        from ..envs.tasks.attitude.task import AttitudeConfig, AttitudeTask
        from ..policies.format import FileFormatError, read_policy

        policy, meta = read_policy(path)
        if meta.get("task") != "attitude" or policy.obs_dim != AttitudeTask.observation_dim:
            raise FileFormatError(path, f"an executor needs an attitude-task policy, this one is for task "
                                        f"{meta.get('task')!r} with {policy.obs_dim} observations")
        self.policy = policy.to(device=env.device, dtype=torch.float32)
        generator = torch.Generator(device=env.device)
        self.task = AttitudeTask(AttitudeConfig(maneuver="circle"), env.sim, generator, env.control_dt,
                                 env.config.ground_effect)
        self.dt = float(env.control_dt)
        self.in_keys = [("state", k) for k in STATE_KEYS]

    def act(self, td: TensorDictBase, v: TensorDictBase, bank: torch.Tensor, climb: torch.Tensor,
            speed: torch.Tensor) -> torch.Tensor:
        task = self.task
        fresh = (v["state", "time"] <= 0.5 * self.dt).unsqueeze(-1)
        task.previous_action.masked_fill_(fresh, 0.0)
        task.commanded.copy_(torch.stack([bank, climb, speed], dim=-1))
        with torch.no_grad():
            action = self.policy(task.observe(td["state"]).float())
        task.previous_action.copy_(action)
        return action.to(v["state", "airspeed"].dtype)


class GuidedController(TensorDictModuleBase):
    """Guidance (:class:`PathGuidance` or :class:`TrajectoryGuidance`) over an executor; action [elevator,
    aileron, rudder, throttle]."""

    def __init__(self, guidance: PathGuidance, executor: Executor):
        super().__init__()
        self.guidance = guidance
        self.executor = executor
        self.in_keys = [*executor.in_keys, *(("task", k) for k in guidance.path_keys)]
        self.out_keys = ["action"]

    def forward(self, td: TensorDictBase) -> TensorDictBase:
        v = flat_scalars(td)  # [N] scalars
        bank, climb, speed = self.guidance.commands(v)
        td.set(self.out_keys[0], self.executor.act(td, v, bank, climb, speed))
        return td


def guidance_for(env: FixedWingEnv, lateral: Lateral) -> PathGuidance:
    """The guidance of ``env``'s task (path following or trajectory) at its trim airspeed."""
    kind = TrajectoryGuidance if env.task.name == "trajectory" else PathGuidance
    return kind(env.sim.airframe, env.control_dt, lateral, airspeed=getattr(env.task, "trim_airspeed", None))


def guided_lqr(env: FixedWingEnv, lateral: Lateral = "npfg") -> GuidedController:
    """NPFG (or L1) + TECS over the attitude LQRI for ``env`` (controllers ``guided-lqr``,
    ``guided-l1-lqr``)."""
    executor = LQRExecutor(env.sim.airframe, env.control_dt, env.device, env.sim.dtype)
    return GuidedController(guidance_for(env, lateral), executor)


def guided_l1_lqr(env: FixedWingEnv) -> GuidedController:
    """L1 + TECS over the attitude LQRI for ``env`` (controller ``guided-l1-lqr``)."""
    return guided_lqr(env, "l1")


def guided_ppo(env: FixedWingEnv, lateral: Lateral = "npfg", policy_seed: int = 0) -> GuidedController:
    """NPFG (or L1) + TECS over the shipped PPO attitude policy of ``env``'s airframe (controller
    ``guided-ppo``)."""
    from ..policies import shipped_policy

    executor = PolicyExecutor(env, shipped_policy("attitude", env.config.airframe, "ppo", policy_seed))
    return GuidedController(guidance_for(env, lateral), executor)


def guided_l1_ppo(env: FixedWingEnv) -> GuidedController:
    """L1 + TECS over the shipped PPO attitude policy (controller ``guided-l1-ppo``)."""
    return guided_ppo(env, "l1")


__all__ = ["L1_LINE_AHEAD", "STATE_KEYS", "Executor", "GuidedController", "LQRExecutor", "PathGuidance",
           "PolicyExecutor", "TrajectoryGuidance", "air_velocity_ned", "guidance_for", "guided_l1_lqr",
           "guided_l1_ppo", "guided_lqr", "guided_ppo"]
