"""The surface under each aircraft: what the dynamics, the contact and the tasks read of the sea.

An env flies over the flat ground (model switch ``surface="flat"``, the default) or over its own sea
(``surface="sea"``, ``sea.SeaSurface``). Over the sea the engine samples the surface under the aircraft
at the current state, after each physics step of dt and at a reset, into one row of its ``surface``
buffer [N, SURFACE_WIDTH] (columns :data:`SURFACE_FIELDS`; a flat env's row is zeros):

    mean_elevation        eta_bar = sum_s w_s eta_s, the span-weighted elevation under the wing (m)
    asymmetry             A = sum_s w_s (y_s / b) (eta_s / b), the surface's span asymmetry (-)
    mean_gradient         d eta_bar / d(north, east) (-)
    asymmetry_gradient    d A / d(north, east) (1/m)
    origin                (north, east) of the CG where sampled (m)
    clearance             CG height above the surface under it (m)
    lowest_tip_clearance  the lower wing tip's height above the surface under it (m)
    wave_velocity         NED velocity of the air's potential flow over the waves at the wing (m/s)
    elevation             eta under the CG (m)
    over_water            1 (the row is a sea sample)

The stations s are five points of the wing's quarter-chord line at y_s = (-1/2, -1/4, 0, 1/4, 1/2) b,
with the trapezoid weights w_s = (1, 2, 2, 2, 1) / 8 of a uniform span loading. Over a sample's dt the
surface is held as it was sampled, moved with the aircraft to first order: at a stage of the integrator
with the CG at (n, e), eta_bar + grad(eta_bar) . ((n, e) - origin) and likewise A (the clock's part of
the surface's change, at most |d eta / dt| dt, is held; the gusts are held over dt the same way). The
dynamics (``dynamics.evaluate``) then uses

- the Phillips-Hunsaker correlations at the mean clearance h/b = (h_wing - eta_bar) / b, and to first
  order in the clearance's variation along the span, the station factors kappa(x - delta_s / b)
  (delta_s = eta_s - eta_bar): the lift factor's variation rolls the aircraft away from a crest,
  dC_l = C_L,inf (d kappa_L / dx) A, and the induced drag's yaws it, dC_n = -C_Di/kappa_D (d kappa_D /
  dx) A (``aero.apply_ground_effect``). A flat sea (every eta_s = 0) gives today's flat-ground model
  exactly: the bank of the wing over a flat surface stays in the correlations' mean height, as over
  the ground;
- the wind plus ``wave_velocity``, the potential flow of the air over the waves, which decays with
  height as exp(-k h) (``sea.SeaSurface.air_velocity``).

Per component k of the field the stations cost two sine-cosine pairs (the root's phase A and the
quarter-span's B; the tips are 2B by the double-angle formulas) and one exponential; the Warp sampler's sums
over the components are native code that a CPU runs 8 components at a time (``sea_native.sea_sums_wp``).
"""

from __future__ import annotations

import itertools

import torch

from ._warp import vector_type, warp_func, wp
from .rotations import rotation_matrix
from .sea import SeaFieldWp, SeaSurface
from .sea_native import sea_sums_wp
from .state import DOWN_INDEX, POSITION, QUATERNION, StateVec

#: (name, width) of the columns of a surface sample.
SURFACE_FIELDS: tuple[tuple[str, int], ...] = (
    ("mean_elevation", 1), ("asymmetry", 1), ("mean_gradient", 2), ("asymmetry_gradient", 2), ("origin", 2),
    ("clearance", 1), ("lowest_tip_clearance", 1), ("wave_velocity", 3), ("elevation", 1), ("over_water", 1))
SURFACE_OFFSET: dict[str, int] = dict(zip(
    (name for name, _ in SURFACE_FIELDS),
    itertools.accumulate((width for _, width in SURFACE_FIELDS), initial=0), strict=False))
SURFACE_WIDTH: int = sum(width for _, width in SURFACE_FIELDS)

MEAN, ASYM, MEAN_GRAD, ASYM_GRAD = (SURFACE_OFFSET[k] for k in
                                    ("mean_elevation", "asymmetry", "mean_gradient", "asymmetry_gradient"))
ORIGIN, CLEARANCE, TIP_CLEARANCE = (SURFACE_OFFSET[k]
                                    for k in ("origin", "clearance", "lowest_tip_clearance"))
WAVE_VELOCITY, ELEVATION, OVER_WATER = (SURFACE_OFFSET[k]
                                        for k in ("wave_velocity", "elevation", "over_water"))

#: A surface sample of one env (Warp).
SurfaceVec = vector_type(SURFACE_WIDTH)


def sample_surface(x: torch.Tensor, rotation: torch.Tensor, span: torch.Tensor,
                   wing_quarter_chord: torch.Tensor,
                   sea: SeaSurface, time: torch.Tensor) -> torch.Tensor:
    """[N, SURFACE_WIDTH] the surface under the aircraft of state x [N, S] (body -> NED ``rotation`` [N, 3,
    3], span [N], wing quarter chord [N, 3] body FRD from the CG) over ``sea`` (fields [N, K]) at ``time``
    [N] s; every row is a sea sample (the caller keeps the flat rows' zeros)."""
    down = rotation[:, 2, :]
    height = -x[:, DOWN_INDEX]
    root = x[:, POSITION] + (rotation * wing_quarter_chord[:, None, :]).sum(-1)  # [N, 3] NED
    wing_height = -root[:, 2]
    half = 0.5 * span
    quarter = (0.25 * span)[:, None] * rotation[:, :2, 1]  # [N, 2] horizontal quarter-span step, right
    c, s = sea.direction_cos, sea.direction_sin
    k, a, w = sea.wavenumber, sea.amplitude, sea.frequency
    phase = k * (root[:, 0:1] * c + root[:, 1:2] * s) - w * time[:, None] + sea.phase  # [N, K]
    step = k * (quarter[:, 0:1] * c + quarter[:, 1:2] * s)
    ca, sa, cb, sb = torch.cos(phase), torch.sin(phase), torch.cos(step), torch.sin(step)
    c2b, s2b = 2.0 * cb * cb - 1.0, 2.0 * sb * cb
    mean_k = a * ca * (1.0 + 2.0 * cb + c2b) * 0.25
    mean_slope = -a * k * sa * (1.0 + 2.0 * cb + c2b) * 0.25  # d/d(travel) of mean_k
    asym_k = -(a * sa) * (sb + s2b) / (8.0 * span[:, None])
    asym_slope = -(a * k * ca) * (sb + s2b) / (8.0 * span[:, None])
    root_slope = -a * k * sa
    tip_right = (a * (ca * c2b - sa * s2b)).sum(-1)
    tip_left = (a * (ca * c2b + sa * s2b)).sum(-1)
    root_gradient = torch.stack([(root_slope * c).sum(-1), (root_slope * s).sum(-1)], -1)
    cg_offset = (x[:, POSITION] - root)[:, :2]
    elevation = (a * ca).sum(-1) + (root_gradient * cg_offset).sum(-1)
    tip_drop = half * down[:, 1]  # the right tip is this much lower than the root
    lowest_tip = torch.minimum(wing_height - tip_drop - tip_right, wing_height + tip_drop - tip_left)
    decay = a * w * torch.exp(-k * wing_height.clamp_min(0.0)[:, None])
    along = -(decay * ca)
    wave_velocity = torch.stack([(along * c).sum(-1), (along * s).sum(-1), -(decay * sa).sum(-1)], -1)
    columns = [mean_k.sum(-1, keepdim=True), asym_k.sum(-1, keepdim=True),
               (mean_slope * c).sum(-1, keepdim=True), (mean_slope * s).sum(-1, keepdim=True),
               (asym_slope * c).sum(-1, keepdim=True), (asym_slope * s).sum(-1, keepdim=True),
               x[:, POSITION][:, :2], (height - elevation)[:, None], lowest_tip[:, None], wave_velocity,
               elevation[:, None], torch.ones_like(height)[:, None]]
    return torch.cat(columns, dim=-1)


def held_surface(x: torch.Tensor, sample: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """(eta_bar [N] m, A [N]) at state x [N, S] from the held ``sample`` [N, SURFACE_WIDTH]: the sampled
    values moved with the CG's horizontal displacement from the sample's origin (zeros on flat rows)."""
    moved = x[:, POSITION][:, :2] - sample[:, ORIGIN:ORIGIN + 2]
    mean = sample[:, MEAN] + (sample[:, MEAN_GRAD:MEAN_GRAD + 2] * moved).sum(-1)
    asym = sample[:, ASYM] + (sample[:, ASYM_GRAD:ASYM_GRAD + 2] * moved).sum(-1)
    return mean, asym


def flat_clearances(height: torch.Tensor, lowest_tip_height: torch.Tensor, sample: torch.Tensor | None
                    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """(CG clearance, lower tip clearance, over_water) [N]: the sample's over water, the heights over
    the flat ground elsewhere (``sample`` None: every env over the ground)."""
    if sample is None:
        return height, lowest_tip_height, torch.zeros_like(height)
    water = sample[:, OVER_WATER] != 0
    return (torch.where(water, sample[:, CLEARANCE], height),
            torch.where(water, sample[:, TIP_CLEARANCE], lowest_tip_height), sample[:, OVER_WATER])


def state_rotation(x: torch.Tensor) -> torch.Tensor:
    """[N, 3, 3] body -> NED of state x [N, S]."""
    return rotation_matrix(x[:, QUATERNION])


# ---------------------------------------------------------------------------------------- warp twins
@warp_func
def sample_surface_wp(sea: SeaFieldWp, s: StateVec, rot: wp.mat33, span: float, wing_quarter_chord: wp.vec3,
                      time: float, i: int) -> SurfaceVec:
    """Env i's surface sample (twin of :func:`sample_surface`)."""
    position = wp.vec3(s[DOWN_INDEX - 2], s[DOWN_INDEX - 1], s[DOWN_INDEX])
    root = position + rot * wing_quarter_chord
    wing_height = -root[2]
    qn = 0.25 * span * rot[0, 1]
    qe = 0.25 * span * rot[1, 1]
    sums = sea_sums_wp(sea.amplitude, sea.wavenumber, sea.frequency, sea.direction_cos, sea.direction_sin,
                       sea.phase, i, root[0], root[1], qn, qe, time, wp.max(wing_height, 0.0),
                       1.0 / (8.0 * span))
    level = wp.vec3(sums[0], sums[1], sums[2])  # (eta_bar, A, eta at the root)
    north = wp.vec3(sums[3], sums[4], sums[5])  # d/d north of level
    east = wp.vec3(sums[6], sums[7], sums[8])  # d/d east of level
    tips = wp.vec2(sums[9], sums[10])  # eta at the (right, left) tip
    wave = wp.vec3(sums[11], sums[12], sums[13])  # the air's flow (north, east, up)
    elevation = level[2] + north[2] * (position[0] - root[0]) + east[2] * (position[1] - root[1])
    tip_drop = 0.5 * span * rot[2, 1]
    out = SurfaceVec()
    out[MEAN] = level[0]
    out[ASYM] = level[1]
    out[MEAN_GRAD] = north[0]
    out[MEAN_GRAD + 1] = east[0]
    out[ASYM_GRAD] = north[1]
    out[ASYM_GRAD + 1] = east[1]
    out[ORIGIN] = position[0]
    out[ORIGIN + 1] = position[1]
    out[CLEARANCE] = -position[2] - elevation
    out[TIP_CLEARANCE] = wp.min(wing_height - tip_drop - tips[0], wing_height + tip_drop - tips[1])
    out[WAVE_VELOCITY] = wave[0]
    out[WAVE_VELOCITY + 1] = wave[1]
    out[WAVE_VELOCITY + 2] = -wave[2]
    out[ELEVATION] = elevation
    out[OVER_WATER] = 1.0
    return out


@warp_func
def held_surface_wp(s: StateVec, sample: SurfaceVec) -> wp.vec2:
    """(eta_bar, A) at state s from the held sample (twin of :func:`held_surface`)."""
    dn = s[DOWN_INDEX - 2] - sample[ORIGIN]
    de = s[DOWN_INDEX - 1] - sample[ORIGIN + 1]
    return wp.vec2(sample[MEAN] + sample[MEAN_GRAD] * dn + sample[MEAN_GRAD + 1] * de,
                   sample[ASYM] + sample[ASYM_GRAD] * dn + sample[ASYM_GRAD + 1] * de)


@warp_func
def load_surface(surface: wp.array2d(dtype=wp.float32), i: int) -> SurfaceVec:
    """Row i of a [N, SURFACE_WIDTH] surface buffer."""
    out = SurfaceVec()
    for k in range(SURFACE_WIDTH):
        out[k] = surface[i, k]
    return out


@warp_func
def store_surface(surface: wp.array2d(dtype=wp.float32), i: int, sample: SurfaceVec):
    """Row i of a [N, SURFACE_WIDTH] surface buffer <- ``sample``."""
    for k in range(SURFACE_WIDTH):
        surface[i, k] = sample[k]


__all__ = ["SURFACE_FIELDS", "SURFACE_OFFSET", "SURFACE_WIDTH", "SurfaceVec",
           "flat_clearances", "held_surface", "held_surface_wp", "load_surface", "sample_surface",
           "sample_surface_wp", "state_rotation", "store_surface"]
