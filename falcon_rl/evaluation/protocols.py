"""The evaluation protocols, run batched: every episode is one env of one rollout.

Each registered task names its protocol in its ``TaskSpec``; all share one signature,

    protocol(airframe, controller, factory, episodes=..., seed=0, backend=DEFAULT_BACKEND, device="cpu",
             episode_seconds=None, **env_options) -> ProtocolResult

with ``factory(env) -> policy`` and ``episode_seconds`` None for the protocol's own horizon.

- Altitude acquisition and hold (the paper's): commanded altitudes 20..100 m, starts offset by
  +-U(12, 18) m, the ramped sub-target at the climb-rate limit; 30 s episodes; Survival, Acquisition,
  RMSE, settling time and overshoot per controller and airframe.
- Attitude maneuvers: circle, figure-8, helix and s-turn streams from the airframe envelope
  (``episodes`` per maneuver, each as long as its stream unless ``episode_seconds`` cuts it); bank
  RMSE with time-in-band, climb-rate and airspeed errors.
- Climb and descend: the task's episodes (start 30-120 m, change 20-60 m at 0.3-1.0 x the climb-rate
  limit), each long enough for the slowest ramp to end plus ``LEVEL_OFF_SECONDS``; climb-rate tracking
  during the ramp, level-off after it (:func:`~.tracking_metrics.climb_descend_metrics`).
- Path following: the task's 40 s episodes (10-50 m off a line at up to 45 deg); completion, capture
  time and cross-track RMSE after the intercept (:func:`~.tracking_metrics.path_following_metrics`).
- Trajectory: the task's 40 s episodes (a point on a climbing or descending turn, 10-40 m ahead);
  3D position RMSE after the intercept (:func:`~.tracking_metrics.trajectory_metrics`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field, fields

import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModuleBase
from tqdm import tqdm

from ..airframe import load_airframe
from ..defaults import DEFAULT_BACKEND
from ..envs import FixedWingEnv, make_env
from ..envs.layout import flat_scalars
from ..envs.maneuvers import MANEUVERS
from ..envs.tasks import ClimbDescendConfig
from .metrics import altitude_metrics, attitude_metrics, summarize
from .rollout_storage import StepRecord
from .tracking_metrics import climb_descend_metrics, path_following_metrics, trajectory_metrics

ControllerFactory = Callable[[FixedWingEnv], TensorDictModuleBase]
#: rollout [N, T] -> per-episode metrics {name: [N]}.
EpisodeMetrics = Callable[[TensorDictBase], dict[str, torch.Tensor]]

#: Rollout fields kept for figures (batch [N, T]).
ALTITUDE_TRACES = (("next", "state", "height"), ("next", "task", "target_altitude"),
                   ("next", "task", "reference_altitude"), ("next", "state", "surface_position"),
                   ("next", "state", "throttle"), ("next", "state", "time"), ("next", "done"))
ATTITUDE_TRACES = (("next", "state", "euler"), ("next", "task", "bank_command"),
                   ("next", "state", "position_ned"), ("next", "state", "quaternion"),
                   ("next", "state", "time"), ("next", "done"))
CLIMB_DESCEND_TRACES = (("next", "state", "height"), ("next", "state", "velocity_ned"),
                        ("next", "task", "target_altitude"), ("next", "task", "reference_altitude"),
                        ("next", "task", "reference_climb_rate"), ("next", "state", "time"), ("next", "done"))
PATH_FOLLOWING_TRACES = (("next", "state", "position_ned"), ("next", "task", "path_point"),
                         ("next", "task", "path_course"), ("next", "task", "cross_track_error"),
                         ("next", "state", "time"), ("next", "done"))
TRAJECTORY_TRACES = (("next", "state", "position_ned"), ("next", "task", "reference_position"),
                     ("next", "task", "position_error"), ("next", "state", "time"), ("next", "done"))

#: Climb and descend: seconds flown after the slowest ramp of the task's distribution has ended.
LEVEL_OFF_SECONDS = 20.0
#: The protocols control at the paper's 10 ms step: one physics step of 10 ms per env step.
PROTOCOL_DECIMATION = 1
#: Altitude: the paper's episode length, s.
ALTITUDE_SECONDS = 30.0


@dataclass
class ProtocolResult:
    """Summary numbers, per-episode metrics and the traces the figures need."""

    task: str
    airframe: str
    controller: str
    summary: dict[str, float]
    episodes: dict[str, torch.Tensor]
    traces: dict[str, TensorDictBase] = field(default_factory=dict)
    settings: dict[str, object] = field(default_factory=dict)
    seconds_per_control_step: float = math.nan


def _rollout(env: FixedWingEnv, policy: TensorDictModuleBase, steps: int, label: str
             ) -> tuple[TensorDictBase, float]:
    """Roll ``steps`` env steps with a progress bar (on a terminal; none in a log file); returns
    (rollout [N, T] of every step's "action" and "next" entries, what metrics and traces read: the
    observation and state a step starts from are the previous step's "next"; s per policy call)."""
    record = StepRecord(steps)
    td = env.reset()
    policy_seconds = 0.0
    with torch.no_grad():
        for t in tqdm(range(steps), desc=label, unit="step", leave=False, mininterval=1.0, disable=None):
            t0 = time.perf_counter()
            td = policy(td)
            policy_seconds += time.perf_counter() - t0
            td = env.step(td)
            record.record(t, td.select("action", "next"))
            td = env.step_mdp(td)
    rollout = record.rollout()
    rollout.set("next", flat_scalars(rollout["next"]))  # [N, T] series for the metrics and figures
    return rollout, policy_seconds / max(steps, 1)


def _fly(task: str, airframe: str, controller: str, factory: ControllerFactory, episodes: int, seed: int,
         backend: str, device: str, **env_options) -> tuple[FixedWingEnv, TensorDictBase, float]:
    """Roll ``episodes`` envs of ``task`` for one horizon under ``factory(env)``:
    (env, rollout [N, T], s per policy call). The control step is the paper's 10 ms (decimation 1
    of the 10 ms physics step) unless ``env_options`` say otherwise."""
    env_options = {"decimation": PROTOCOL_DECIMATION, **env_options}
    env = make_env(task, airframe, num_envs=episodes, backend=backend, device=device, seed=seed,
                   **env_options)
    rollout, per_step = _rollout(env, factory(env), env.max_episode_steps, f"{controller} {task} {airframe}")
    return env, rollout, per_step


def in_units(summary: dict[str, float]) -> dict[str, float]:
    """Summary with every ``<name>_rad`` entry given as ``<name>_deg``."""
    return {(k[:-4] + "_deg" if k.endswith("_rad") else k): (math.degrees(v) if k.endswith("_rad") else v)
            for k, v in summary.items()}


def tracking_protocol(task: str, metrics: EpisodeMetrics, traces: tuple, airframe: str, controller: str,
                      factory: ControllerFactory, episodes: int = 20, seed: int = 0,
                      backend: str = DEFAULT_BACKEND,
                      device: str = "cpu", episode_seconds: float | None = None,
                      **env_options) -> ProtocolResult:
    """Fly ``episodes`` envs of ``task`` for one horizon (the task's own unless ``episode_seconds``) and
    score them with ``metrics(rollout) -> {name: [N]}`` (``rollout`` [N, T]: each step's "action" and
    "next" entries; a "survival" entry included); the summary is
    :func:`~.metrics.summarize`'s, angles in degrees. ``traces`` are the rollout keys kept for figures.
    The building block of the task protocols below (and of a user's own task)."""
    if episode_seconds is not None:
        env_options = {**env_options, "episode_seconds": episode_seconds}
    env, rollout, per_step = _fly(task, airframe, controller, factory, episodes, seed, backend, device,
                                  **env_options)
    episode_metrics = metrics(rollout)
    summary = in_units(summarize(episode_metrics, episode_metrics["survival"]))
    settings = {"episodes": episodes, "seed": seed, "backend": backend, "device": device, **env_options,
                "episode_seconds": env.max_episode_steps * env.control_dt, "dt": env.control_dt}
    traces_kept = {task: rollout.select(*traces)}
    return ProtocolResult(task, airframe, controller, summary, episode_metrics, traces_kept, settings,
                          per_step)


def altitude_protocol(airframe: str, controller: str, factory: ControllerFactory, episodes: int = 20,
                      seed: int = 0, backend: str = DEFAULT_BACKEND, device: str = "cpu",
                      episode_seconds: float | None = None, **env_options) -> ProtocolResult:
    """Fly ``episodes`` altitude episodes (``ALTITUDE_SECONDS`` unless ``episode_seconds``) in parallel
    and score them (true state)."""
    seconds = ALTITUDE_SECONDS if episode_seconds is None else episode_seconds
    env, rollout, per_step = _fly("altitude", airframe, controller, factory, episodes, seed, backend, device,
                                  episode_seconds=seconds, **env_options)
    episode_metrics = altitude_metrics(rollout)
    survived = episode_metrics["survival"]
    summary = summarize(episode_metrics, survived)
    summary["overshoot_m"] = summary.pop("overshoot")
    summary["rmse_m"] = summary.pop("rmse")
    summary["settling_time_s"] = summary.pop("settling_time")
    settings = {"episodes": episodes, "seed": seed, "backend": backend, "device": device,
                "episode_seconds": seconds, "dt": env.control_dt, **env_options}
    traces = {"altitude": rollout.select(*ALTITUDE_TRACES)}
    return ProtocolResult("altitude", airframe, controller, summary, episode_metrics, traces, settings,
                          per_step)


def attitude_protocol(airframe: str, controller: str, factory: ControllerFactory, episodes: int = 1,
                      seed: int = 0, backend: str = DEFAULT_BACKEND, device: str = "cpu",
                      episode_seconds: float | None = None, maneuvers: tuple[str, ...] = MANEUVERS,
                      **env_options) -> ProtocolResult:
    """Fly each maneuver stream (``episodes`` envs each; its first ``episode_seconds`` when given) and
    score bank, climb-rate, airspeed. Summary keys are "<maneuver>/<metric>"."""
    summary: dict[str, float] = {}
    per_episode: dict[str, torch.Tensor] = {}
    traces, per_step = {}, []
    env_options = {"decimation": PROTOCOL_DECIMATION, **env_options}
    for name in maneuvers:
        env = make_env("attitude", airframe, num_envs=episodes, backend=backend, device=device, seed=seed,
                       maneuver=name, **env_options)
        policy = factory(env)
        steps = env.max_episode_steps
        if episode_seconds is not None:
            steps = max(1, min(steps, round(episode_seconds / env.control_dt)))
        rollout, seconds = _rollout(env, policy, steps, f"{controller} {name} {airframe}")
        per_step.append(seconds)
        metrics = attitude_metrics(rollout)
        row = summarize(metrics, metrics["survival"])
        for key, value in row.items():
            scale = math.degrees(1.0) if key == "bank_rmse" else 1.0
            unit = {"bank_rmse": "_deg", "climb_rate_rmse": "_mps", "airspeed_rmse": "_mps"}.get(key, "")
            summary[f"{name}/{key}{unit}"] = value * scale
        per_episode.update({f"{name}/{k}": v for k, v in metrics.items()})
        traces[name] = rollout.select(*ATTITUDE_TRACES)
    settings = {"episodes": episodes, "seed": seed, "backend": backend, "device": device,
                "maneuvers": list(maneuvers), "episode_seconds": episode_seconds, **env_options}
    return ProtocolResult("attitude", airframe, controller, summary, per_episode, traces, settings,
                          sum(per_step) / len(per_step))


def climb_descend_seconds(airframe: str, **env_options) -> float:
    """Horizon of the climb/descend protocol: the slowest ramp of the task's distribution
    (change_max / (rate_min x climb-rate limit)) plus ``LEVEL_OFF_SECONDS``."""
    names = {f.name for f in fields(ClimbDescendConfig)}
    config = ClimbDescendConfig(**{k: v for k, v in env_options.items() if k in names})
    climb_rate = config.climb_rate or load_airframe(airframe).envelope.climb_rate_limit
    return config.change_max / (config.rate_min * climb_rate) + LEVEL_OFF_SECONDS


def climb_descend_protocol(airframe: str, controller: str, factory: ControllerFactory, episodes: int = 20,
                           seed: int = 0, backend: str = DEFAULT_BACKEND, device: str = "cpu",
                           episode_seconds: float | None = None, **env_options) -> ProtocolResult:
    """Fly ``episodes`` climb/descend episodes (:func:`climb_descend_seconds` unless ``episode_seconds``):
    climb-rate tracking on the ramp, then level-off at the commanded altitude."""
    seconds = climb_descend_seconds(airframe, **env_options) if episode_seconds is None else episode_seconds
    return tracking_protocol("climb_descend", climb_descend_metrics, CLIMB_DESCEND_TRACES, airframe,
                             controller, factory, episodes, seed, backend, device, seconds, **env_options)


def path_following_protocol(airframe: str, controller: str, factory: ControllerFactory, episodes: int = 20,
                            seed: int = 0, backend: str = DEFAULT_BACKEND, device: str = "cpu",
                            episode_seconds: float | None = None, **env_options) -> ProtocolResult:
    """Fly ``episodes`` path-following episodes (the task's horizon unless ``episode_seconds``): survival,
    completion, capture time, cross-track / course / altitude RMSE after the intercept."""
    return tracking_protocol("path_following", path_following_metrics, PATH_FOLLOWING_TRACES, airframe,
                             controller, factory, episodes, seed, backend, device, episode_seconds,
                             **env_options)


def trajectory_protocol(airframe: str, controller: str, factory: ControllerFactory, episodes: int = 20,
                        seed: int = 0, backend: str = DEFAULT_BACKEND, device: str = "cpu",
                        episode_seconds: float | None = None, **env_options) -> ProtocolResult:
    """Fly ``episodes`` trajectory episodes (the task's horizon unless ``episode_seconds``): survival and
    3D / horizontal / vertical position RMSE and time within 10 m after the intercept."""
    return tracking_protocol("trajectory", trajectory_metrics, TRAJECTORY_TRACES, airframe, controller,
                             factory, episodes, seed, backend, device, episode_seconds, **env_options)
