"""The landing protocol, scored as certification would: the touchdown's sink rate, attitude and position.

``landing_protocol`` flies ``episodes`` landing episodes (each from its own start on the glide path) at the
paper's 10 ms control step and scores the first episode of each at its touchdown:

    touchdown             the episode ended with the wheels on the surface (not a wing-tip strike, a stall,
                          off the centreline or long, nor the horizon)
    sink_rate_mps         the touchdown's sink rate (down positive)
    pitch_deg, bank_deg   the touchdown's pitch and bank
    lateral_m             |the touchdown's offset from the centreline|
    longitudinal_m        the touchdown's distance past the aim point (negative: short)
    float_m               the distance flown from the wheels' first coming below one span (ground effect's
                          band) to the touchdown
    landed_within_limits  a touchdown with sink <= ``SINK_LIMIT`` (0.6 m/s; CS/FAR 25.473's limit is
                          3.05 m/s), pitch within the task's [pitch_min, pitch_max], |bank| <= bank_max,
                          |lateral| <= ``LATERAL_LIMIT`` (3 m) and |longitudinal| <= ``LONGITUDINAL_LIMIT``
                          (30 m)

``touchdown`` and ``landed_within_limits`` are fractions of the episodes; the other numbers means over the
episodes that touched down. ``ground_effect`` (an env option) False flies the same starts without ground
effect (the float it makes is the difference).
"""

from __future__ import annotations

import math

import torch
from tensordict import TensorDictBase

from ..defaults import DEFAULT_BACKEND
from ..envs.layout import flat_scalars
from ..envs.tasks import TERMINATION_CODE
from .metrics import first_episode_mask, summarize
from .protocols import ControllerFactory, ProtocolResult, _fly

#: Certification-style touchdown limits: sink rate (m/s), lateral offset (m), longitudinal dispersion (m).
SINK_LIMIT = 0.6
LATERAL_LIMIT = 3.0
LONGITUDINAL_LIMIT = 30.0
#: The rollout entries the figure reads.
LANDING_TRACES = (("next", "state", "position_ned"), ("next", "state", "height"),
                  ("next", "task", "glide_path_height"), ("next", "task", "wheel_height"),
                  ("next", "state", "velocity_ned"), ("next", "state", "time"), ("next", "done"),
                  ("next", "termination_reason"))


def landing_metrics(rollout: TensorDictBase, pitch_min: float, pitch_max: float, bank_max: float
                    ) -> dict[str, torch.Tensor]:
    """Per-episode metrics [N] of a landing rollout (batch [N, T]) at each row's first touchdown (see the
    module docstring); the pitch and bank limits in rad."""
    nxt = flat_scalars(rollout["next"])
    valid = first_episode_mask(nxt["done"])
    reason = nxt["termination_reason"].reshape(valid.shape)
    at = valid & (reason == TERMINATION_CODE["touchdown"])
    touchdown = at.any(-1)
    step = at.float().argmax(-1, keepdim=True)

    def at_touchdown(value: torch.Tensor) -> torch.Tensor:
        picked = value.gather(-1, step).squeeze(-1)
        return torch.where(touchdown, picked, torch.full_like(picked, math.nan))

    task = nxt["task"]
    sink = at_touchdown(task["touchdown_sink_rate"])
    pitch, bank = at_touchdown(task["touchdown_pitch"]), at_touchdown(task["touchdown_bank"])
    along, lateral = at_touchdown(task["touchdown_along"]), at_touchdown(task["touchdown_lateral"]).abs()
    entry = at_touchdown(task["ground_effect_north"])
    within = (touchdown & (sink <= SINK_LIMIT) & (pitch >= pitch_min) & (pitch <= pitch_max)
              & (bank.abs() <= bank_max) & (lateral <= LATERAL_LIMIT) & (along.abs() <= LONGITUDINAL_LIMIT))
    return {"touchdown": touchdown, "landed_within_limits": within, "sink_rate_mps": sink,
            "pitch_deg": torch.rad2deg(pitch), "bank_deg": torch.rad2deg(bank), "lateral_m": lateral,
            "longitudinal_m": along, "float_m": along - entry}


def landing_protocol(airframe: str, controller: str, factory: ControllerFactory, episodes: int = 20,
                     seed: int = 0, backend: str = DEFAULT_BACKEND, device: str = "cpu",
                     episode_seconds: float | None = None, **env_options) -> ProtocolResult:
    """Fly ``episodes`` landings (the task's horizon unless ``episode_seconds``) and score their touchdowns
    (the module docstring; true state)."""
    if episode_seconds is not None:
        env_options = {**env_options, "episode_seconds": episode_seconds}
    env, rollout, per_step = _fly("landing", airframe, controller, factory, episodes, seed, backend, device,
                                  **env_options)
    cfg = env.task.config
    metrics = landing_metrics(rollout, cfg.pitch_min, cfg.pitch_max, cfg.bank_max)
    summary = summarize(metrics, metrics["touchdown"])
    summary.pop("survival")
    settings = {"episodes": episodes, "seed": seed, "backend": backend, "device": device, **env_options,
                "episode_seconds": env.max_episode_steps * env.control_dt, "dt": env.control_dt,
                "glide_slope_deg": math.degrees(cfg.glide_slope), "approach_speed": env.task.trim_airspeed}
    traces = {"landing": rollout.select(*LANDING_TRACES, strict=False)}
    return ProtocolResult("landing", airframe, controller, summary, metrics, traces, settings, per_step)


__all__ = ["LANDING_TRACES", "LATERAL_LIMIT", "LONGITUDINAL_LIMIT", "SINK_LIMIT", "landing_metrics",
           "landing_protocol"]
