"""Figures of the climb/descend, path-following and trajectory protocols (PNG, Agg); each takes one
``ProtocolResult`` and the PNG path, like :mod:`.evaluation`. Steps after an episode's end (crash,
stall, lost) are left blank."""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import torch

from ..evaluation.metrics import first_episode_mask
from ..evaluation.protocols import ProtocolResult
from ._figure import save_figure


def _scored(values: torch.Tensor, done: torch.Tensor) -> torch.Tensor:
    """``values`` [N, T, ...] on the CPU with the steps after each row's first episode set to NaN."""
    valid = first_episode_mask(done.cpu())
    return torch.where(valid.reshape(*valid.shape, *([1] * (values.dim() - 2))), values.cpu(), math.nan)


def _save(fig: plt.Figure, path: Path, title: str) -> Path:
    for ax in fig.axes:
        ax.grid(alpha=0.3)
    fig.suptitle(title)
    return save_figure(fig, path)


def _summary_line(result: ProtocolResult, *keys: str) -> str:
    parts = [f"{k} {result.summary.get(k, math.nan):.3g}" for k in keys]
    return f"{result.controller} on {result.airframe}: " + ", ".join(parts)


def plot_climb_descend(result: ProtocolResult, path: Path, shown: int = 8) -> Path:
    """Height vs reference (dashed) for ``shown`` episodes, climb rate vs commanded, and the
    altitude error h - h* over all episodes (5-95 % band)."""
    tr = result.traces["climb_descend"]["next"]
    t = tr["state", "time"][0].cpu()
    done = tr["done"]
    height, reference = _scored(tr["state", "height"], done), tr["task", "reference_altitude"].cpu()
    climb = _scored(-tr["state", "velocity_ned"][..., 2], done)
    commanded = tr["task", "reference_climb_rate"].cpu()
    fig, axes = plt.subplots(1, 3, figsize=(14, 4))
    for i in range(min(shown, height.shape[0])):
        axes[0].plot(t, height[i], color=f"C{i % 10}", lw=1.2)
        axes[0].plot(t, reference[i], color=f"C{i % 10}", lw=0.8, ls="--")
        axes[1].plot(t, climb[i], color=f"C{i % 10}", lw=1.0)
        axes[1].plot(t, commanded[i], color=f"C{i % 10}", lw=0.8, ls="--")
    axes[0].set(title="height (solid) vs reference (dashed)", xlabel="time (s)", ylabel="h (m)")
    axes[1].set(title="climb rate vs commanded", xlabel="time (s)", ylabel="hdot (m/s)")
    error = height - tr["task", "target_altitude"].cpu()
    q = torch.nanquantile(error, torch.tensor([0.05, 0.5, 0.95]), dim=0)
    axes[2].fill_between(t, q[0], q[2], alpha=0.3, label="5-95 %")
    axes[2].plot(t, q[1], label="median")
    axes[2].axhspan(-1, 1, color="g", alpha=0.1, label="+-1 m band")
    axes[2].set(title=f"h - h*, all {height.shape[0]} episodes", xlabel="time (s)", ylabel="m")
    axes[2].legend(fontsize=8)
    return _save(fig, path, _summary_line(result, "survival", "climb_rate_rmse_mps", "level_off"))


def plot_path_following(result: ProtocolResult, path: Path, shown: int = 8) -> Path:
    """Ground tracks (east right, north up) with each episode's path line, and the cross-track error
    over time of ``shown`` episodes with the +-5 m completion band."""
    tr = result.traces["path_following"]["next"]
    t = tr["state", "time"][0].cpu()
    position, point = _scored(tr["state", "position_ned"], tr["done"]), tr["task", "path_point"][:, 0].cpu()
    course = tr["task", "path_course"][:, 0].cpu()
    cross_track = _scored(tr["task", "cross_track_error"], tr["done"])
    fig, axes = plt.subplots(1, 2, figsize=(12, 5))
    reach = float(position[..., :2].abs().nan_to_num(0.0).max()) + 50.0
    for i in range(min(shown, position.shape[0])):
        color = f"C{i % 10}"
        axes[0].plot(position[i, :, 1], position[i, :, 0], color=color, lw=1.2)
        direction = torch.stack([torch.cos(course[i]), torch.sin(course[i])])
        ends = point[i][None] + torch.tensor([-reach, reach])[:, None] * direction
        axes[0].plot(ends[:, 1], ends[:, 0], color=color, lw=0.8, ls="--")
        axes[1].plot(t, cross_track[i], color=color, lw=1.0)
    axes[0].set(title="ground track (solid) and path (dashed)", xlabel="east (m)", ylabel="north (m)",
                xlim=(-reach, reach), ylim=(-reach, reach), aspect="equal")
    axes[1].axhspan(-5, 5, color="g", alpha=0.1, label="+-5 m band")
    axes[1].set(title="cross-track error", xlabel="time (s)", ylabel="e_y (m)")
    axes[1].legend(fontsize=8)
    return _save(fig, path, _summary_line(result, "survival", "completion", "cross_track_rmse_m"))


def plot_trajectory(result: ProtocolResult, path: Path, shown: int = 6) -> Path:
    """Ground tracks and height of aircraft (solid) and reference point (dashed) for ``shown``
    episodes, and the 3D position error over all episodes (5-95 % band)."""
    tr = result.traces["trajectory"]["next"]
    t = tr["state", "time"][0].cpu()
    position = _scored(tr["state", "position_ned"], tr["done"])
    reference = tr["task", "reference_position"].cpu()
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.5))
    for i in range(min(shown, position.shape[0])):
        color = f"C{i % 10}"
        axes[0].plot(position[i, :, 1], position[i, :, 0], color=color, lw=1.2)
        axes[0].plot(reference[i, :, 1], reference[i, :, 0], color=color, lw=0.8, ls="--")
        axes[1].plot(t, -position[i, :, 2], color=color, lw=1.2)
        axes[1].plot(t, -reference[i, :, 2], color=color, lw=0.8, ls="--")
    axes[0].set(title="ground track (dashed: reference)", xlabel="east (m)", ylabel="north (m)",
                aspect="equal")
    axes[1].set(title="height (dashed: reference)", xlabel="time (s)", ylabel="h (m)")
    error = _scored(tr["task", "position_error"], tr["done"])
    q = torch.nanquantile(error, torch.tensor([0.05, 0.5, 0.95]), dim=0)
    axes[2].fill_between(t, q[0], q[2], alpha=0.3, label="5-95 %")
    axes[2].plot(t, q[1], label="median")
    axes[2].axhline(10.0, color="g", ls=":", label="10 m band")
    axes[2].set(title=f"|p - p_ref|, all {error.shape[0]} episodes", xlabel="time (s)", ylabel="m")
    axes[2].legend(fontsize=8)
    return _save(fig, path, _summary_line(result, "survival", "position_rmse_m", "time_in_band"))


__all__ = ["plot_climb_descend", "plot_path_following", "plot_trajectory"]
