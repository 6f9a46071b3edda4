"""The derived state: what every engine computes from its state for ``Simulator.state``, declared once.

Each engine's ``derived()`` returns one [N, DERIVED_WIDTH] tensor whose columns follow
:data:`DERIVED_FIELDS` (name, width); the Warp evaluation kernel writes the same columns at the
offsets :data:`DERIVED_OFFSET` gives, and :func:`split_derived` names them for the facade. Adding a
derived quantity is one row here plus the line that computes it in each backend
(``dynamics.derived_columns`` and ``warp_kernels.evaluate_kernel``), checked by the parity tests.

    airspeed [N]           m/s, air-relative speed
    alpha, beta [N]        rad, aerodynamic angles (wind and gusts included)
    height [N]             m, CG height above the flat ground (-z)
    wing_height [N]        m, height of the wing quarter chord (attitude included)
    surface_position [N, 3] rad, deflections clamped to the actuator limits
    thrust [N]             N, total thrust of all motors
    aero_coefficients [N, 6] C_L, C_D, C_Y, C_l, C_m, C_n (ground effect included)
    lowest_tip_height [N]  m, the lower wing tip (quarter chord +-b/2) above ground
    velocity_ned [N, 3]    m/s, inertial velocity in NED
    euler [N, 3]           rad, aerospace ZYX roll, pitch, yaw

and the diagnostics that the plots show (what the model computed, not a re-derivation):

    aero_force_body [N, 3]  N, aerodynamic force in body FRD (propulsion and gravity excluded)
    aero_moment_body [N, 3] N m, aerodynamic moment about the CG in body FRD
    motor_thrust [N, 8]     N, thrust per motor, padded with zeros to ``MAX_MOTORS`` columns
                            (``Simulator.state`` keeps the airframe's motors only)
    ge_h_over_b [N]         wing quarter-chord height over span, the ground-effect argument
    ge_lift_factor [N]      Phillips-Hunsaker lift influence ratio (-> 1 far from the ground; 1 when off)
    ge_drag_factor [N]      Phillips-Hunsaker induced-drag influence ratio (likewise)

and the surface under the aircraft (``surface.py``; over the flat ground: elevation 0, the heights):

    surface_elevation [N]     m, the surface's elevation under the CG (the sea's eta; 0 over the ground)
    surface_clearance [N]     m, CG height above the surface under it (what a radar altimeter reads)
    lowest_tip_clearance [N]  m, the lower wing tip's height above the surface under it
    over_water [N]            1 over the env's sea, 0 over the ground
    wave_velocity_ned [N, 3]  m/s, the air's flow over the waves at the wing, added to the wind

``split_derived`` adds the contacts: ``ground_contact`` (the CG or a wing tip at or below the ground)
and ``water_contact`` (the same against the water under them).
"""

from __future__ import annotations

import itertools

import torch

from .state import WARP_MAX_MOTORS

#: Columns of the per-motor thrust (the most motors an engine supports; unused ones read 0).
MAX_MOTORS: int = WARP_MAX_MOTORS

#: (name, width) of each derived field, in column order.
DERIVED_FIELDS: tuple[tuple[str, int], ...] = (
    ("airspeed", 1), ("alpha", 1), ("beta", 1), ("height", 1), ("wing_height", 1),
    ("surface_position", 3), ("thrust", 1), ("aero_coefficients", 6), ("lowest_tip_height", 1),
    ("velocity_ned", 3), ("euler", 3),
    ("aero_force_body", 3), ("aero_moment_body", 3), ("motor_thrust", MAX_MOTORS), ("ge_h_over_b", 1),
    ("ge_lift_factor", 1), ("ge_drag_factor", 1), ("surface_elevation", 1), ("surface_clearance", 1),
    ("lowest_tip_clearance", 1), ("over_water", 1), ("wave_velocity_ned", 3),
)
#: First column of each derived field.
DERIVED_OFFSET: dict[str, int] = dict(zip(
    (name for name, _ in DERIVED_FIELDS),
    itertools.accumulate((width for _, width in DERIVED_FIELDS), initial=0), strict=False))
#: Columns of the derived tensor.
DERIVED_WIDTH: int = sum(width for _, width in DERIVED_FIELDS)
_WIDTHS: list[int] = [width for _, width in DERIVED_FIELDS]


def surface_contact(clearance: torch.Tensor, lowest_tip_clearance: torch.Tensor) -> torch.Tensor:
    """[N] bool: the CG or the lower wing tip is at or below the surface under it (the one definition;
    over the flat ground the clearances are the heights)."""
    return (clearance <= 0.0) | (lowest_tip_clearance <= 0.0)


def pack_derived(fields: dict[str, torch.Tensor]) -> torch.Tensor:
    """[N, DERIVED_WIDTH] from named fields ([N] or [N, width]), in :data:`DERIVED_FIELDS` order."""
    columns = []
    for name, width in DERIVED_FIELDS:
        value = fields[name]
        value = value.unsqueeze(-1) if value.dim() == 1 else value
        if value.shape[-1] != width:
            raise ValueError(f"derived field {name!r} has width {value.shape[-1]}, declared {width}")
        columns.append(value)
    return torch.cat(columns, dim=-1)


def split_derived(derived: torch.Tensor, copy: bool = True) -> dict[str, torch.Tensor]:
    """Named fields ([N] for width 1) of a [N, DERIVED_WIDTH] tensor, plus ``ground_contact`` and
    ``water_contact`` [N] bool:
    fresh tensors, or views of ``derived`` with ``copy=False`` (for a tensor the caller owns)."""
    if derived.shape[-1] != DERIVED_WIDTH:
        raise ValueError(f"derived tensor has {derived.shape[-1]} columns, expected {DERIVED_WIDTH}")
    out = {}
    # One split for every field's columns (per-field indexing cost ~2 us each on a one-env state).
    for (name, width), column in zip(DERIVED_FIELDS, derived.split(_WIDTHS, dim=-1), strict=True):
        column = column.squeeze(-1) if width == 1 else column
        out[name] = column.clone() if copy else column
    contact = surface_contact(out["surface_clearance"], out["lowest_tip_clearance"])
    water = out["over_water"] != 0
    out["ground_contact"] = contact & ~water
    out["water_contact"] = contact & water
    return out
