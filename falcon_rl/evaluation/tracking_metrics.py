"""Metrics of the climb/descend, path-following and trajectory protocols.

Conventions of :mod:`.metrics`: a rollout of batch [N, T] (N episodes, T steps), the first episode of
each row scored (``valid`` [N, T]), errors recomputed from the true state (("next", "state", ...))
against the references the task publishes (("next", "task", ...)), one value per episode [N].
:func:`~.metrics.summarize` then averages the error metrics over the surviving episodes. Keys carry
their unit (angles in rad, ``_rad``); delta is the capture band.

Climb/descend: e_h = h - h*, hdot = -v_z, R = the steps while the reference ramps (hdot_ref != 0).

    climb_rate_rmse_mps  RMSE of hdot - hdot_ref over R (climb-rate tracking)
    ramp_rmse_m          RMSE of h - h_ref over R
    level_off            survived, the ramp ended and |e_h| <= delta held from some step to the end
    level_off_time_s     time from the end of the ramp until |e_h| <= delta for good (0 if already)
    level_off_rmse_m     RMSE of e_h over the steps ``grace_seconds`` or more after the ramp ended
    overshoot_m          max_t sgn(h* - h_0) e_h clipped at 0

Path following: path point (n_p, e_p), course chi_p, height h_p; e_y = -sin chi_p (n - n_p)
+ cos chi_p (e - e_p); W = the scored steps from ``intercept_seconds`` on.

    completion           survived and reached the path: |e_y| <= delta held from some step to the end
    capture_time_s       first time from which |e_y| <= delta holds to the end (NaN when never)
    cross_track_rmse_m   RMSE of e_y over W
    course_rmse_rad      RMSE of wrap(chi - chi_p) over W, chi = atan2(v_e, v_n)
    altitude_rmse_m      RMSE of h - h_p over W

Trajectory: e_p = p - p_ref (NED); W as above.

    position_rmse_m      RMSE of |e_p| over W
    horizontal_rmse_m    RMSE of |(e_n, e_e)| over W;   vertical_rmse_m   RMSE of e_d over W
    cross_track_rmse_m   RMSE over W of the horizontal distance to the reference's arc, | |p - c| - R |
                         (c = p_ref + n / kappa, n the unit normal right of v_ref, kappa the published
                         reference_curvature, R = 1 / |kappa|): the path error, along-track lag aside
    time_in_band         fraction of W with |e_p| <= ``tolerance``
"""

from __future__ import annotations

import math

import torch
from tensordict import TensorDictBase

from ..envs.layout import flat_scalars
from .metrics import (
    acquisition,
    first_episode_mask,
    overshoot,
    ramp_end_index,
    rmse,
    settled_window,
    settling_index,
    settling_time,
    survival,
    time_in_band,
)


def _step_dt(nxt: TensorDictBase) -> float:
    """Env step, s: the time of the first "next" state."""
    return float(nxt["state", "time"][0, 0])


def climb_descend_metrics(rollout: TensorDictBase, band: float = 1.0, grace_seconds: float = 5.0
                          ) -> dict[str, torch.Tensor]:
    """Per-episode metrics [N] of a climb/descend rollout (see the module docstring)."""
    nxt = flat_scalars(rollout["next"])
    valid = first_episode_mask(nxt["done"])
    dt = _step_dt(nxt)
    height, rate = nxt["state", "height"], nxt["task", "reference_climb_rate"]
    error = height - nxt["task", "target_altitude"]
    ramp = (rate != 0) & valid
    climb_error = -nxt["state", "velocity_ned"][..., 2] - rate
    ramp_end = ramp_end_index(rate, valid)
    settle = settling_index(error, band, valid)
    steps = error.shape[-1]
    ended = ramp_end < steps
    level_time = torch.where(ended & (settle < steps), dt * (settle - ramp_end).clamp_min(0).to(error.dtype),
                             math.nan)
    direction = torch.sign(nxt["task", "target_altitude"][:, 0] - nxt["task", "initial_altitude"][:, 0])
    terminated = nxt["terminated"]
    return {
        "survival": survival(terminated, valid),
        "climb_rate_rmse_mps": rmse(climb_error, ramp),
        "ramp_rmse_m": rmse(height - nxt["task", "reference_altitude"], ramp),
        "level_off": acquisition(error, terminated, band, valid) & ended,
        "level_off_time_s": level_time,
        "level_off_rmse_m": rmse(error, settled_window(rate, dt, grace_seconds, valid)),
        "overshoot_m": overshoot(error, direction, valid),
    }


def path_following_metrics(rollout: TensorDictBase, band: float = 5.0, intercept_seconds: float = 15.0
                           ) -> dict[str, torch.Tensor]:
    """Per-episode metrics [N] of a path-following rollout (see the module docstring)."""
    nxt = flat_scalars(rollout["next"])
    valid = first_episode_mask(nxt["done"])
    dt = _step_dt(nxt)
    course = nxt["task", "path_course"]
    relative = nxt["state", "position_ned"][..., :2] - nxt["task", "path_point"]
    cross_track = -torch.sin(course) * relative[..., 0] + torch.cos(course) * relative[..., 1]
    velocity = nxt["state", "velocity_ned"]
    course_error = torch.remainder(torch.atan2(velocity[..., 1], velocity[..., 0]) - course + math.pi,
                                   2.0 * math.pi) - math.pi
    altitude_error = nxt["state", "height"] - nxt["task", "path_height"]
    window = valid & (nxt["state", "time"] >= intercept_seconds - 0.5 * dt)
    terminated = nxt["terminated"]
    return {
        "survival": survival(terminated, valid),
        "completion": acquisition(cross_track, terminated, band, valid),
        "capture_time_s": settling_time(cross_track, band, dt, valid, start_time=dt),
        "cross_track_rmse_m": rmse(cross_track, window),
        "course_rmse_rad": rmse(course_error, window),
        "altitude_rmse_m": rmse(altitude_error, window),
    }


def arc_distance(nxt: TensorDictBase) -> torch.Tensor:
    """[N, T] the horizontal distance (m) of the aircraft from the trajectory reference's arc (the module
    docstring's cross-track error), from the flat "next" entries of a rollout."""
    reference = nxt["task", "reference_position"][..., :2]
    velocity = nxt["task", "reference_velocity"][..., :2]
    curvature = nxt["task", "reference_curvature"]
    tangent = velocity / torch.linalg.vector_norm(velocity, dim=-1, keepdim=True).clamp_min(1e-6)
    right = torch.stack([-tangent[..., 1], tangent[..., 0]], dim=-1)
    radius = 1.0 / curvature.abs().clamp_min(1e-9)
    center = reference + (torch.sign(curvature) * radius).unsqueeze(-1) * right
    distance = torch.linalg.vector_norm(nxt["state", "position_ned"][..., :2] - center, dim=-1)
    return (distance - radius).abs()


def trajectory_metrics(rollout: TensorDictBase, tolerance: float = 10.0, intercept_seconds: float = 10.0
                       ) -> dict[str, torch.Tensor]:
    """Per-episode metrics [N] of a 3D trajectory rollout (see the module docstring)."""
    nxt = flat_scalars(rollout["next"])
    valid = first_episode_mask(nxt["done"])
    dt = _step_dt(nxt)
    error = nxt["state", "position_ned"] - nxt["task", "reference_position"]  # [N, T, 3]
    distance = torch.linalg.vector_norm(error, dim=-1)
    window = valid & (nxt["state", "time"] >= intercept_seconds - 0.5 * dt)
    return {
        "survival": survival(nxt["terminated"], valid),
        "position_rmse_m": rmse(distance, window),
        "horizontal_rmse_m": rmse(torch.linalg.vector_norm(error[..., :2], dim=-1), window),
        "vertical_rmse_m": rmse(error[..., 2], window),
        "cross_track_rmse_m": rmse(arc_distance(nxt), window),
        "time_in_band": time_in_band(distance, tolerance, window),
    }


__all__ = ["arc_distance", "climb_descend_metrics", "path_following_metrics", "trajectory_metrics"]
