"""Named layout of the integrated state vector.

    [0:3]    position_ned           m, NED, flat ground at z = 0 (height h = -z)
    [3:7]    quaternion             (w, x, y, z), body FRD -> NED
    [7:10]   velocity_body          m/s, inertial velocity in body axes (u, v, w)
    [10:13]  angular_rate_body      rad/s (p, q, r)
    [13:16]  surface_position       rad (elevator, aileron, rudder)
    [16:19]  surface_rate           rad/s (second-order actuators; 0 for first order)
    [19:19+M] throttle              [0, 1] per motor (first-order lag)

Code outside the Warp kernels reads and writes the vector by name: ``StateLayout(M).pack(fields)``
and ``.unpack(x)`` (dicts keyed like the env's ("state", ...) entries), ``STATE_INDEX`` for single
entries, and the component indices below (``DOWN``, ``PITCH``, ``ELEVATOR``, ...) inside a field.

Turbulence filter states are discrete (advanced once per step, not integrated) and live
beside this vector in the Simulator: ``Simulator.turbulence.filter`` [N, 8] (see ``wind.py``).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import torch

from ..airframe import CONTROL_NAMES
from ._warp import vector_type

#: Physical ranges a reset state must lie in (the model is subsonic, rigid and above the ground):
#: speed relative to the ground, m/s; body rates, rad/s; |position| components, m.
MAX_RESET_SPEED = 300.0
MAX_RESET_RATE = 20.0
MAX_RESET_POSITION = 1.0e7
#: A quaternion shorter than this cannot be normalised into an attitude (it is refused at reset).
MIN_QUATERNION_NORM = 1.0e-3

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

# Components inside a field (the last axis of a [N, 3] field, not state-vector indices).
#: NED axes of position_ned and velocity_ned.
NORTH, EAST, DOWN = 0, 1, 2
#: Body axes of velocity_body (u, v, w) and of any body vector.
X, Y, Z = 0, 1, 2
#: Euler angles (phi, theta, psi) and the body rates about x, y, z (p, q, r).
ROLL, PITCH, YAW = 0, 1, 2
#: Channels of the normalised command [N, 4]; the first three also index surface_position/rate [N, 3].
COMMAND_CHANNELS: tuple[str, ...] = CONTROL_NAMES
ELEVATOR, AILERON, RUDDER, THROTTLE = 0, 1, 2, 3
assert COMMAND_CHANNELS == ("elevator", "aileron", "rudder", "throttle")


@dataclass(frozen=True)
class StateField:
    """One named block of the state vector: ``x[..., slice]`` in ``unit``."""

    name: str
    slice: slice
    unit: str
    components: tuple[str, ...]

    @property
    def size(self) -> int:
        return self.slice.stop - self.slice.start


#: The motor-independent fields, in vector order (throttle follows, one entry per motor).
FIELDS: tuple[StateField, ...] = (
    StateField("position_ned", POSITION, "m", ("north", "east", "down")),
    StateField("quaternion", QUATERNION, "1", ("w", "x", "y", "z")),
    StateField("velocity_body", VELOCITY, "m/s", ("u", "v", "w")),
    StateField("angular_rate_body", ANGULAR_RATE, "rad/s", ("p", "q", "r")),
    StateField("surface_position", SURFACE_POSITION, "rad", COMMAND_CHANNELS[:3]),
    StateField("surface_rate", SURFACE_RATE, "rad/s", COMMAND_CHANNELS[:3]),
)
#: State-vector indices of each motor-independent field, e.g. ``STATE_INDEX["velocity_body"][X]`` = 7.
STATE_INDEX: dict[str, range] = {f.name: range(f.slice.start, f.slice.stop) for f in FIELDS}
#: State-vector index of the down position z; the height above the flat ground is ``-x[:, DOWN_INDEX]``.
DOWN_INDEX = STATE_INDEX["position_ned"][DOWN]
#: Fields :meth:`StateLayout.pack` fills with zeros when they are not given.
OPTIONAL_FIELDS: frozenset[str] = frozenset({"surface_rate"})


def height(x: torch.Tensor) -> torch.Tensor:
    """Height above the flat ground [...] of states x [..., S] (m; -z of position_ned)."""
    return -x[..., DOWN_INDEX]


@dataclass(frozen=True)
class StateLayout:
    """State size, field table and throttle slice for an airframe with ``num_motors`` motors."""

    num_motors: int

    @property
    def size(self) -> int:
        return THROTTLE_START + self.num_motors

    @property
    def throttle(self) -> slice:
        return slice(THROTTLE_START, THROTTLE_START + self.num_motors)

    @property
    def fields(self) -> tuple[StateField, ...]:
        """Every field in vector order, throttle last ([0, 1] per motor)."""
        motors = tuple(f"motor_{m}" for m in range(self.num_motors))
        return (*FIELDS, StateField("throttle", self.throttle, "1", motors))

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(f.name for f in self.fields)

    def slice_of(self, name: str) -> slice:
        """Slice of field ``name`` in the state vector."""
        for f in self.fields:
            if f.name == name:
                return f.slice
        raise KeyError(f"no state field {name!r}; the fields are {list(self.names)}")

    def field(self, x: torch.Tensor, name: str) -> torch.Tensor:
        """Field ``name`` of states x [..., S] (a view [..., size])."""
        return x[..., self.slice_of(name)]

    def unpack(self, x: torch.Tensor) -> dict[str, torch.Tensor]:
        """States x [..., S] -> {field name: view [..., size]} (writes go through to x)."""
        if x.shape[-1] != self.size:
            raise ValueError(f"state vector has {x.shape[-1]} entries; the {self.num_motors}-motor "
                             f"layout has {self.size}")
        return {f.name: x[..., f.slice] for f in self.fields}

    def pack(self, fields: Mapping[str, torch.Tensor]) -> torch.Tensor:
        """Named fields (each [N, size]) -> states [N, S]. Every field is required except
        ``surface_rate`` (zeros); throttle may be [N] for a single motor. Other keys are ignored,
        so the env's ("state", ...) TensorDict packs as it is."""
        missing = [f.name for f in self.fields if f.name not in fields and f.name not in OPTIONAL_FIELDS]
        if missing:
            raise ValueError(f"state fields {missing} missing (need {list(self.names)})")
        position = fields["position_ned"]
        n = position.shape[0] if position.dim() == 2 else "N"
        blocks = []
        for f in self.fields:
            value = fields.get(f.name, None)
            if value is None:
                value = torch.zeros_like(fields["surface_position"])
            elif f.name == "throttle" and value.dim() == 1 and self.num_motors == 1:
                value = value.unsqueeze(-1)
            if tuple(value.shape) != (n, f.size):
                raise ValueError(f"state field {f.name!r} has shape {list(value.shape)}, "
                                 f"expected [{n}, {f.size}]")
            blocks.append(value)
        return torch.cat(blocks, dim=-1)
