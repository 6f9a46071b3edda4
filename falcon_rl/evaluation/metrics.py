"""The paper's evaluation metrics, batched over episodes and computed from the true state.

Every function takes per-step tensors shaped [N, T] (N episodes, T steps, as TorchRL rollouts
are laid out) and returns one value per episode, [N]. ``valid`` [N, T] marks the steps of the
scored episode (see :func:`first_episode_mask`); e_t is the tracking error and delta the capture band
(1 m on the altitude task).

    Survival       episode reaches the horizon without crash or stall termination
    Acquisition    survival and, additionally, |e_t| <= delta from some step to the end (reach & hold)
    RMSE           sqrt(1/|W| sum_{t in W} e_t^2) over the settled window W
    Time-in-band   fraction of scored steps with |e_t| <= tolerance
    Settling time  min t such that |e_tau| <= delta for all tau >= t (NaN when never settled)
    Overshoot      max_t sgn(h* - h_0) e_t clipped at 0, with e = h - h*: the excursion past the
                   target, not max_t |e_t|

Survival takes precedence: :func:`summarize` averages error metrics over surviving episodes only and
returns NaN for them when none survived.
"""

from __future__ import annotations

import math

import torch
from tensordict import TensorDictBase

from ..envs.layout import flat_scalars


def first_episode_mask(done: torch.Tensor) -> torch.Tensor:
    """[N, T] bool: the steps of each row's first episode, up to and including its first done.
    ``done`` is [N, T] or [N, T, 1] (the "next" done flags of a rollout)."""
    done = done.reshape(done.shape[0], done.shape[1]).bool()
    done_before = torch.cumsum(done.long(), dim=-1) - done.long()
    return done_before == 0


def survival(terminated: torch.Tensor, valid: torch.Tensor | None = None) -> torch.Tensor:
    """[N] bool: no crash/stall termination during the scored steps (truncation is survival)."""
    terminated = terminated.reshape(terminated.shape[0], terminated.shape[1]).bool()
    if valid is not None:
        terminated = terminated & valid
    return ~terminated.any(dim=-1)


def settling_index(error: torch.Tensor, band: float, valid: torch.Tensor | None = None) -> torch.Tensor:
    """[N] long: first step t with |e_tau| <= band for every scored tau >= t; T when the last scored
    step is outside the band (never settled)."""
    inside = error.abs() <= band
    if valid is not None:
        inside = inside | ~valid  # steps after the episode do not count against settling
    holds_to_end = torch.flip(torch.cumprod(torch.flip(inside, [-1]).long(), dim=-1), [-1]).bool()
    if valid is not None:
        last_valid_inside = (inside & valid & holds_to_end).any(dim=-1)
        holds_to_end = holds_to_end & last_valid_inside[:, None]
    t = error.shape[-1]
    steps = torch.arange(t, device=error.device).expand_as(holds_to_end)
    return torch.where(holds_to_end, steps, t).min(dim=-1).values


def settling_time(error: torch.Tensor, band: float, dt: float, valid: torch.Tensor | None = None,
                  start_time: float = 0.0) -> torch.Tensor:
    """[N] s: ``start_time + dt x settling_index``; NaN for episodes that never settle. Use
    ``start_time = dt`` when ``error`` comes from the "next" states of a rollout."""
    index = settling_index(error, band, valid)
    time = start_time + dt * index.to(error.dtype)
    return torch.where(index < error.shape[-1], time, math.nan)


def acquisition(error: torch.Tensor, terminated: torch.Tensor, band: float,
                valid: torch.Tensor | None = None) -> torch.Tensor:
    """[N] bool: survived and reached the target, holding |e| <= band to the end."""
    return survival(terminated, valid) & (settling_index(error, band, valid) < error.shape[-1])


def rmse(error: torch.Tensor, window: torch.Tensor | None = None) -> torch.Tensor:
    """[N] sqrt(mean_{t in W} e_t^2) over the window W [N, T] bool (all steps when None); NaN where
    W is empty."""
    if window is None:
        window = torch.ones_like(error, dtype=torch.bool)
    count = window.sum(dim=-1)
    total = torch.where(window, error * error, 0.0).sum(dim=-1)
    return torch.where(count > 0, torch.sqrt(total / count.clamp_min(1)), math.nan)


def time_in_band(error: torch.Tensor, tolerance: float, window: torch.Tensor | None = None) -> torch.Tensor:
    """[N] fraction of the scored steps W [N, T] with |e_t| <= tolerance; NaN where W is empty."""
    if window is None:
        window = torch.ones_like(error, dtype=torch.bool)
    count = window.sum(dim=-1)
    inside = ((error.abs() <= tolerance) & window).sum(dim=-1)
    return torch.where(count > 0, inside.to(error.dtype) / count.clamp_min(1), math.nan)


def overshoot(error: torch.Tensor, direction: torch.Tensor,
              valid: torch.Tensor | None = None) -> torch.Tensor:
    """[N] max_t direction e_t clipped at 0, with e = h - h* and direction = sgn(h* - h_0) [N]."""
    signed = direction[:, None] * error
    if valid is not None:
        signed = torch.where(valid, signed, -math.inf)
    return signed.max(dim=-1).values.clamp_min(0.0)


def ramp_end_index(reference_rate: torch.Tensor, valid: torch.Tensor | None = None) -> torch.Tensor:
    """[N] long: first step from which the reference rate [N, T] is zero to the end of the scored
    steps (the reference stopped moving for good); T when it still moves at the last step."""
    still = reference_rate == 0
    if valid is not None:
        still = still | ~valid
    holds = torch.flip(torch.cumprod(torch.flip(still, [-1]).long(), dim=-1), [-1]).bool()
    t = reference_rate.shape[-1]
    steps = torch.arange(t, device=reference_rate.device).expand_as(holds)
    return torch.where(holds, steps, t).min(dim=-1).values


def settled_window(reference_rate: torch.Tensor, dt: float, grace_seconds: float,
                   valid: torch.Tensor | None = None) -> torch.Tensor:
    """[N, T] bool: the steps ``grace_seconds`` or more after the reference stopped moving for good
    (its rate [N, T] is zero from there to the end)."""
    ramp_end = ramp_end_index(reference_rate, valid)
    steps = torch.arange(reference_rate.shape[-1], device=reference_rate.device).expand_as(reference_rate)
    window = steps >= (ramp_end + round(grace_seconds / dt))[:, None]
    return window if valid is None else window & valid


def summarize(metrics: dict[str, torch.Tensor], survived: torch.Tensor) -> dict[str, float]:
    """Episode metrics [N] -> one number each. ``survival`` and ``acquisition`` are fractions of
    all episodes; every other metric is the mean over surviving episodes with a finite value (NaN
    when there is none)."""
    out: dict[str, float] = {"survival": float(survived.float().mean())}
    for name, values in metrics.items():
        if name == "survival":
            continue
        if values.dtype == torch.bool:
            out[name] = float(values.float().mean())
            continue
        keep = survived & torch.isfinite(values)
        out[name] = float(values[keep].mean()) if keep.any() else math.nan
    return out


def altitude_metrics(rollout: TensorDictBase, band: float = 1.0, grace_seconds: float = 5.0
                     ) -> dict[str, torch.Tensor]:
    """Per-episode metrics [N] of an altitude rollout (batch [N, T], from ``env.rollout`` of the
    altitude or climb_descend task), scored on the first episode of each row with e = h - h*:
    the true height from ("next", "state", "height") and h* from ("next", "task", "target_altitude").
    W starts ``grace_seconds`` after the reference ramp ends; time-in-band uses the band delta."""
    nxt = flat_scalars(rollout["next"])
    valid = first_episode_mask(nxt["done"])
    error = nxt["state", "height"] - nxt["task", "target_altitude"]
    dt = float(nxt["state", "time"][0, 0])
    window = settled_window(nxt["task", "reference_climb_rate"], dt, grace_seconds, valid)
    direction = torch.sign(nxt["task", "target_altitude"][:, 0] - nxt["task", "initial_altitude"][:, 0])
    terminated = nxt["terminated"]
    return {
        "survival": survival(terminated, valid),
        "acquisition": acquisition(error, terminated, band, valid),
        "rmse": rmse(error, window),
        "time_in_band": time_in_band(error, band, window),
        "settling_time": settling_time(error, band, dt, valid, start_time=dt),
        "overshoot": overshoot(error, direction, valid),
    }


def attitude_metrics(rollout: TensorDictBase, bank_tolerance: float = math.radians(8.6)
                     ) -> dict[str, torch.Tensor]:
    """Per-episode metrics [N] of an attitude-task rollout: survival, bank RMSE (rad) and
    time-in-band over the whole scored episode, and climb-rate / airspeed RMSE, all recomputed from
    the true state against the commanded stream."""
    nxt = flat_scalars(rollout["next"])
    valid = first_episode_mask(nxt["done"])
    bank_error = nxt["state", "euler"][..., 0] - nxt["task", "bank_command"]
    climb_error = -nxt["state", "velocity_ned"][..., 2] - nxt["task", "climb_rate_command"]
    airspeed_error = nxt["state", "airspeed"] - nxt["task", "airspeed_command"]
    return {
        "survival": survival(nxt["terminated"], valid),
        "bank_rmse": rmse(bank_error, valid),
        "bank_time_in_band": time_in_band(bank_error, bank_tolerance, valid),
        "climb_rate_rmse": rmse(climb_error, valid),
        "airspeed_rmse": rmse(airspeed_error, valid),
    }
