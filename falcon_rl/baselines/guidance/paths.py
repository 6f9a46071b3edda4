"""Batched path geometry for lateral guidance: the path at the point closest to each aircraft.

Positions and vectors are horizontal (north, east), in m and m/s, one row per env ([N, 2]). A guidance law
reads a :class:`PathFrame`: the unit tangent of the path at the closest point, the signed track error
(m, positive right of the path, looking along it) and the path's curvature (1/m, positive for a path
turning right, i.e. clockwise seen from above). PX4's NPFG takes exactly these three inputs; ArduPilot's
L1 takes a line (two waypoints) or a loiter circle, from which this frame is built the same way.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch


def cross2(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """z of the 2D cross product a x b of [..., 2] (north, east) vectors: [...] (positive when b is
    clockwise of a, seen from above)."""
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def unit(vector: torch.Tensor, fallback: torch.Tensor | None = None, eps: float = 1e-6) -> torch.Tensor:
    """[..., 2] unit vectors of ``vector``; rows shorter than ``eps`` take ``fallback`` (north when None)."""
    norm = vector.norm(dim=-1, keepdim=True)
    if fallback is None:
        fallback = torch.zeros_like(vector)
        fallback[..., 0] = 1.0
    return torch.where(norm > eps, vector / norm.clamp_min(eps), fallback)


@dataclass
class PathFrame:
    """The path at each aircraft's closest point: ``tangent`` [N, 2] (unit, direction of travel),
    ``track_error`` [N] (m, positive right of the path) and ``curvature`` [N] (1/m, positive turning
    right; 0 on a line)."""

    tangent: torch.Tensor
    track_error: torch.Tensor
    curvature: torch.Tensor


def line_frame(position: torch.Tensor, point: torch.Tensor, course: torch.Tensor) -> PathFrame:
    """The frame of infinite straight lines through ``point`` [N, 2] with ``course`` [N] (rad from north,
    clockwise) at ``position`` [N, 2]."""
    tangent = torch.stack([torch.cos(course), torch.sin(course)], dim=-1)
    error = cross2(tangent, position - point)
    return PathFrame(tangent, error, torch.zeros_like(error))


def segment_frame(position: torch.Tensor, start: torch.Tensor, end: torch.Tensor) -> PathFrame:
    """The frame of the lines from waypoint ``start`` to ``end`` ([N, 2] each) at ``position`` [N, 2];
    a zero-length segment points from the aircraft to ``end`` (track error 0)."""
    along = end - start
    direct = unit(end - position)
    tangent = unit(along, fallback=direct)
    short = along.norm(dim=-1) <= 1e-6
    error = torch.where(short, torch.zeros_like(along[..., 0]), cross2(tangent, position - start))
    return PathFrame(tangent, error, torch.zeros_like(error))


def circle_frame(position: torch.Tensor, center: torch.Tensor, radius: torch.Tensor, direction: torch.Tensor,
                 velocity: torch.Tensor | None = None) -> PathFrame:
    """The frame of loiter circles (``center`` [N, 2], ``radius`` [N] m, ``direction`` [N] +1 clockwise /
    -1 counter-clockwise seen from above) at ``position`` [N, 2]. At the centre (closer than 0.1 m) the
    closest point is taken along ``velocity`` [N, 2] (north when it is ~0), as PX4 does."""
    offset = position - center
    distance = offset.norm(dim=-1)
    along = unit(velocity) if velocity is not None else None
    radial = unit(offset, fallback=along, eps=0.1)
    tangent = direction.unsqueeze(-1) * torch.stack([-radial[..., 1], radial[..., 0]], dim=-1)
    error = -direction * (distance - radius)
    return PathFrame(tangent, error, direction / radius)


__all__ = ["PathFrame", "circle_frame", "cross2", "line_frame", "segment_frame", "unit"]
