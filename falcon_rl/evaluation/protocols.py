"""The paper's evaluation protocols, run batched: every episode is one env of one rollout.

- Altitude acquisition and hold: commanded altitudes 20..100 m, starts offset by +-U(12, 18) m,
  the ramped sub-target at the climb-rate limit; Survival, Acquisition, RMSE, settling time and
  overshoot per controller and airframe.
- Attitude maneuvers: circle, figure-8, helix and s-turn streams from the airframe envelope; bank
  RMSE with time-in-band, climb-rate and airspeed errors.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModuleBase
from tqdm import tqdm

from ..envs import FixedWingEnv, make_env
from ..envs.maneuvers import MANEUVERS
from .metrics import altitude_metrics, attitude_metrics, summarize

ControllerFactory = Callable[[FixedWingEnv], TensorDictModuleBase]

#: Rollout fields kept for figures (batch [N, T]).
ALTITUDE_TRACES = (("next", "state", "height"), ("next", "task", "target_altitude"),
                   ("next", "task", "reference_altitude"), ("next", "state", "surface_position"),
                   ("next", "state", "throttle"), ("next", "state", "time"), ("next", "done"))
ATTITUDE_TRACES = (("next", "state", "euler"), ("next", "task", "bank_command"),
                   ("next", "state", "time"), ("next", "done"))


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
    """Roll ``steps`` env steps with a progress bar; returns (rollout [N, T], s per policy call)."""
    td = env.reset()
    frames, policy_seconds = [], 0.0
    with torch.no_grad():
        for _ in tqdm(range(steps), desc=label, unit="step", leave=False, mininterval=1.0):
            t0 = time.perf_counter()
            td = policy(td)
            policy_seconds += time.perf_counter() - t0
            td = env.step(td)
            frames.append(td.clone())
            td = env.step_mdp(td)
    return torch.stack(frames, dim=1), policy_seconds / max(steps, 1)


def altitude_protocol(airframe: str, controller: str, factory: ControllerFactory, episodes: int = 20,
                      seed: int = 0, backend: str = "torch", device: str = "cpu",
                      episode_seconds: float = 30.0, **env_options) -> ProtocolResult:
    """Fly ``episodes`` altitude episodes in parallel and score them (true state)."""
    env = make_env("altitude", airframe, num_envs=episodes, backend=backend, device=device, seed=seed,
                   episode_seconds=episode_seconds, **env_options)
    policy = factory(env)
    steps = round(episode_seconds / env.env_dt)
    rollout, per_step = _rollout(env, policy, steps, f"{controller} altitude {airframe}")
    episode_metrics = altitude_metrics(rollout)
    survived = episode_metrics["survival"]
    summary = summarize(episode_metrics, survived)
    summary["overshoot_m"] = summary.pop("overshoot")
    summary["rmse_m"] = summary.pop("rmse")
    summary["settling_time_s"] = summary.pop("settling_time")
    settings = {"episodes": episodes, "seed": seed, "backend": backend, "device": device,
                "episode_seconds": episode_seconds, "dt": env.env_dt, **env_options}
    traces = {"altitude": rollout.select(*ALTITUDE_TRACES)}
    return ProtocolResult("altitude", airframe, controller, summary, episode_metrics, traces, settings,
                          per_step)


def attitude_protocol(airframe: str, controller: str, factory: ControllerFactory,
                      maneuvers: tuple[str, ...] = MANEUVERS, episodes: int = 1, seed: int = 0,
                      backend: str = "torch", device: str = "cpu", **env_options) -> ProtocolResult:
    """Fly each maneuver stream (``episodes`` envs each) and score bank, climb-rate, airspeed."""
    summary: dict[str, float] = {}
    per_episode: dict[str, torch.Tensor] = {}
    traces, per_step = {}, []
    for name in maneuvers:
        env = make_env("attitude", airframe, num_envs=episodes, backend=backend, device=device, seed=seed,
                       maneuver=name, **env_options)
        policy = factory(env)
        steps = round(env.task.episode_seconds / env.env_dt)
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
                "maneuvers": list(maneuvers), **env_options}
    return ProtocolResult("attitude", airframe, controller, summary, per_episode, traces, settings,
                          sum(per_step) / len(per_step))
