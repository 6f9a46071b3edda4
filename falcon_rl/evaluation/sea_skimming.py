"""The sea-skimming protocol: water contacts, clearance error and the power ground effect saves.

``sea_skimming_protocol`` flies ``episodes`` envs of the task over one sea state (``sea_state``, WMO code),
every episode at the commanded clearance ``clearance`` b, its heading to the waves drawn from the task's
(following, beam and head seas), at the paper's 10 ms control step, and scores the first episode of each:

    water_contact          the episode ended on the water (a CG or wing-tip contact)
    survival               it flew its horizon (no termination)
    clearance_rmse_span    sqrt(mean e_c^2) / b over the steps after ``grace_seconds`` (the start's offset)
    clearance_rmse_m       the same in metres
    min_tip_clearance_m    the lower wing tip's closest approach to the water
    power_saved            1 - mean(T V_a) / (T_free V_a*): the propulsive power against straight and level
                           flight at the trim airspeed out of ground effect (trim at 100 m)

``water_contact_rate`` is the fraction of episodes with a contact; the other numbers are means over the
surviving episodes (``metrics.summarize``).
"""

from __future__ import annotations

import math

import torch
from tensordict import TensorDictBase

from ..airframe import load_airframe
from ..defaults import DEFAULT_BACKEND
from ..envs.layout import flat_scalars
from ..envs.tasks import TERMINATION_CODE
from ..physics.trim import trim_level
from .metrics import first_episode_mask, rmse, summarize, survival
from .protocols import ControllerFactory, ProtocolResult, _fly

#: The rollout entries the figure reads.
SEA_SKIMMING_TRACES = (("next", "task", "clearance"), ("next", "task", "commanded_clearance"),
                       ("next", "task", "lowest_tip_clearance"), ("next", "task", "surface_elevation"),
                       ("next", "state", "height"), ("next", "state", "thrust"), ("next", "state", "time"),
                       ("next", "done"))
#: The protocol's horizon (s) and the start transient it leaves out of the RMSE (s).
SEA_SKIMMING_SECONDS = 30.0
GRACE_SECONDS = 5.0


def free_flight_power(airframe: str, airspeed: float) -> float:
    """T V (W) of straight and level trim at ``airspeed`` and 100 m out of ground effect."""
    trim = trim_level(load_airframe(airframe), airspeed, 100.0, ground_effect=False)
    return float(trim.thrust.reshape(-1)[0]) * airspeed


def sea_skimming_metrics(rollout: TensorDictBase, span: float, dt: float, free_power: float,
                         grace_seconds: float = GRACE_SECONDS) -> dict[str, torch.Tensor]:
    """Per-episode metrics [N] of a sea-skimming rollout (batch [N, T]) on each row's first episode (see
    the module docstring); ``free_power`` W, ``span`` m, ``dt`` the control step (s)."""
    nxt = flat_scalars(rollout["next"])
    valid = first_episode_mask(nxt["done"])
    reason = nxt["termination_reason"].reshape(valid.shape)
    ended = torch.where(valid, reason, 0).max(dim=-1).values
    contact = (ended == TERMINATION_CODE["water_contact"]) | (ended == TERMINATION_CODE["ground_contact"])
    error = nxt["task", "clearance"] - nxt["task", "commanded_clearance"]
    steps = torch.arange(error.shape[-1], device=error.device).expand_as(error)
    window = valid & (steps >= round(grace_seconds / dt))
    clearance_rmse = rmse(error, window)
    tip = torch.where(valid, nxt["task", "lowest_tip_clearance"], math.inf).min(dim=-1).values
    thrust = nxt["state", "thrust"].reshape(valid.shape)
    power = torch.where(window, thrust * nxt["state", "airspeed"], 0.0).sum(-1) / window.sum(-1).clamp_min(1)
    return {"survival": survival(nxt["terminated"], valid), "water_contact": contact,
            "clearance_rmse_span": clearance_rmse / span, "clearance_rmse_m": clearance_rmse,
            "min_tip_clearance_m": tip, "power_saved": 1.0 - power / free_power}


def sea_skimming_protocol(airframe: str, controller: str, factory: ControllerFactory, episodes: int = 20,
                          seed: int = 0, backend: str = DEFAULT_BACKEND, device: str = "cpu",
                          episode_seconds: float | None = None, sea_state: int = 3, clearance: float = 0.25,
                          **env_options) -> ProtocolResult:
    """Fly ``episodes`` sea-skimming episodes over sea state ``sea_state`` at ``clearance`` b (the module
    docstring) for ``SEA_SKIMMING_SECONDS`` unless ``episode_seconds``, and score them (true state)."""
    seconds = SEA_SKIMMING_SECONDS if episode_seconds is None else episode_seconds
    options = {"sea_states": (float(sea_state),), "clearance_min": clearance, "clearance_max": clearance,
               **env_options}
    env, rollout, per_step = _fly("sea_skimming", airframe, controller, factory, episodes, seed, backend,
                                  device, episode_seconds=seconds, **options)
    task = env.task
    metrics = sea_skimming_metrics(rollout, task.span, env.control_dt,
                                   free_flight_power(airframe, task.trim_airspeed),
                                   min(GRACE_SECONDS, 0.5 * seconds))
    summary = summarize(metrics, metrics["survival"])
    summary["water_contact_rate"] = summary.pop("water_contact")
    settings = {"episodes": episodes, "seed": seed, "backend": backend, "device": device,
                "episode_seconds": seconds, "dt": env.control_dt, "sea_state": sea_state,
                "clearance": clearance, **env_options}
    traces = {"sea_skimming": rollout.select(*SEA_SKIMMING_TRACES, strict=False)}
    return ProtocolResult("sea_skimming", airframe, controller, summary, metrics, traces, settings, per_step)


__all__ = ["SEA_SKIMMING_TRACES", "free_flight_power", "sea_skimming_metrics", "sea_skimming_protocol"]
