"""Named layout of the integrated state vector.

    [0:3]    position_ned           m, NED, flat ground at z = 0 (height h = -z)
    [3:7]    quaternion             (w, x, y, z), body FRD -> NED
    [7:10]   velocity_body          m/s, inertial velocity in body axes (u, v, w)
    [10:13]  angular_rate_body      rad/s (p, q, r)
    [13:16]  surface_position       rad (elevator, aileron, rudder)
    [16:19]  surface_rate           rad/s (second-order actuators; 0 for first order)
    [19:19+M] throttle              [0, 1] per motor (first-order lag)

Turbulence filter states are discrete (advanced once per step, not integrated) and live
beside this vector in the Simulator: ``Simulator.turbulence.filter`` [N, 8] (see ``wind.py``).
"""

from __future__ import annotations

from dataclasses import dataclass

from ._warp import vector_type

POSITION = slice(0, 3)
QUATERNION = slice(3, 7)
VELOCITY = slice(7, 10)
ANGULAR_RATE = slice(10, 13)
SURFACE_POSITION = slice(13, 16)
SURFACE_RATE = slice(16, 19)
THROTTLE_START = 19
# Integer offsets of the slices above, for the Warp kernels (which index one element at a time).
QUATERNION_START = 3
VELOCITY_START = 7
ANGULAR_RATE_START = 10
SURFACE_POSITION_START = 13
SURFACE_RATE_START = 16
NUM_CONTROLS = 4
#: Most motors the Warp kernels support: their state is a fixed-length vector (unused slots zero).
WARP_MAX_MOTORS = 8
#: Warp twin of one env's state row, padded to ``WARP_MAX_MOTORS`` throttles.
StateVec = vector_type(THROTTLE_START + WARP_MAX_MOTORS)


@dataclass(frozen=True)
class StateLayout:
    """State size and throttle slice for an airframe with ``num_motors`` motors."""

    num_motors: int

    @property
    def size(self) -> int:
        return THROTTLE_START + self.num_motors

    @property
    def throttle(self) -> slice:
        return slice(THROTTLE_START, THROTTLE_START + self.num_motors)
