"""Quaternion and Euler-angle helpers (torch, batched).

Quaternions are unit, scalar first (w, x, y, z) and rotate body (FRD) vectors into NED.
Euler angles are the aerospace ZYX sequence (yaw psi, pitch theta, roll phi).
"""

from __future__ import annotations

import torch

from ._warp import warp_func, wp


def rotation_matrix(q: torch.Tensor) -> torch.Tensor:
    """Body-to-NED direction cosine matrix. q: [N, 4] -> [N, 3, 3]."""
    w, x, y, z = q.unbind(-1)
    return torch.stack(
        [
            1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
            2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
            2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y),
        ],
        dim=-1,
    ).reshape(*q.shape[:-1], 3, 3)


def body_to_ned(q: torch.Tensor, v_body: torch.Tensor) -> torch.Tensor:
    """Rotate [N, 3] body vectors into NED."""
    return (rotation_matrix(q) @ v_body.unsqueeze(-1)).squeeze(-1)


def ned_to_body(q: torch.Tensor, v_ned: torch.Tensor) -> torch.Tensor:
    """Rotate [N, 3] NED vectors into the body frame."""
    return (rotation_matrix(q).transpose(-1, -2) @ v_ned.unsqueeze(-1)).squeeze(-1)


def quaternion_derivative(q: torch.Tensor, omega_body: torch.Tensor) -> torch.Tensor:
    """q_dot = 1/2 q (x) (0, omega). q: [N, 4], omega_body: [N, 3] rad/s -> [N, 4]."""
    w, x, y, z = q.unbind(-1)
    p, qq, r = omega_body.unbind(-1)
    return 0.5 * torch.stack(
        [
            -x * p - y * qq - z * r,
            w * p + y * r - z * qq,
            w * qq + z * p - x * r,
            w * r + x * qq - y * p,
        ],
        dim=-1,
    )


def euler_to_quaternion(euler: torch.Tensor) -> torch.Tensor:
    """[N, 3] (roll, pitch, yaw) rad -> [N, 4] unit quaternion (w, x, y, z)."""
    half = 0.5 * euler
    cr, cp, cy = torch.cos(half).unbind(-1)
    sr, sp, sy = torch.sin(half).unbind(-1)
    return torch.stack(
        [
            cr * cp * cy + sr * sp * sy,
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
        ],
        dim=-1,
    )


def quaternion_to_euler(q: torch.Tensor) -> torch.Tensor:
    """[N, 4] unit quaternion -> [N, 3] (roll, pitch, yaw) rad, pitch clamped to +-pi/2."""
    w, x, y, z = q.unbind(-1)
    roll = torch.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = torch.asin(torch.clamp(2 * (w * y - z * x), -1.0, 1.0))
    yaw = torch.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return torch.stack([roll, pitch, yaw], dim=-1)


def normalize_quaternion(q: torch.Tensor) -> torch.Tensor:
    """Project [N, 4] onto the unit sphere, with a positive scalar part (q and -q are equal)."""
    q = q / torch.linalg.vector_norm(q, dim=-1, keepdim=True).clamp_min(1e-12)
    return torch.where(q[..., :1] < 0, -q, q)


# ---------------------------------------------------------------------------------------- warp twins
# Inside kernels a quaternion is a wp.vec4 in the same scalar-first order (w, x, y, z) as the torch
# state; Warp's own wp.quat is (x, y, z, w), so convert with quat_to_warp / quat_from_warp.


@warp_func
def quat_to_warp(q: wp.vec4) -> wp.quat:
    """(w, x, y, z) vec4 -> Warp quaternion (x, y, z, w)."""
    return wp.quat(q[1], q[2], q[3], q[0])


@warp_func
def quat_from_warp(q: wp.quat) -> wp.vec4:
    """Warp quaternion (x, y, z, w) -> (w, x, y, z) vec4."""
    return wp.vec4(q[3], q[0], q[1], q[2])


@warp_func
def rotation_matrix_wp(q: wp.vec4) -> wp.mat33:
    """Body-to-NED DCM of a (w, x, y, z) quaternion (twin of :func:`rotation_matrix`)."""
    w = q[0]
    x = q[1]
    y = q[2]
    z = q[3]
    return wp.mat33(
        1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - w * z), 2.0 * (x * z + w * y),
        2.0 * (x * y + w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - w * x),
        2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y),
    )


@warp_func
def quaternion_to_euler_wp(q: wp.vec4) -> wp.vec3:
    """(roll, pitch, yaw) rad of a unit (w, x, y, z) quaternion (twin of :func:`quaternion_to_euler`)."""
    w = q[0]
    x = q[1]
    y = q[2]
    z = q[3]
    return wp.vec3(
        wp.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y)),
        wp.asin(wp.clamp(2.0 * (w * y - z * x), -1.0, 1.0)),
        wp.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z)),
    )


@warp_func
def quaternion_derivative_wp(q: wp.vec4, omega: wp.vec3) -> wp.vec4:
    """q_dot = 1/2 q (x) (0, omega) (twin of :func:`quaternion_derivative`)."""
    w = q[0]
    x = q[1]
    y = q[2]
    z = q[3]
    p = omega[0]
    qq = omega[1]
    r = omega[2]
    return 0.5 * wp.vec4(
        -x * p - y * qq - z * r,
        w * p + y * r - z * qq,
        w * qq + z * p - x * r,
        w * r + x * qq - y * p,
    )


@warp_func
def normalize_quaternion_wp(q: wp.vec4) -> wp.vec4:
    """Unit quaternion with a non-negative scalar part (twin of :func:`normalize_quaternion`)."""
    n = wp.max(wp.length(q), 1.0e-12)
    u = q / n
    if u[0] < 0.0:
        u = -u
    return u
