"""Per-env model parameters as tensors shaped [N, ...], built from an :class:`Airframe`.

Every field is per env so that domain randomisation is one masked write (``assign``); the aero
monomial exponents are shared by all envs (they fix the structure, not the values).
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import torch

from ..airframe import SURFACES, Airframe
from ._warp import vector_type, warp_struct, wp
from .ground_effect import WingConstants, ground_effect_mode, wing_constants


@dataclass
class ModelParams:
    """Model parameters. N = envs, T = aero monomials, M = motors."""

    mass: torch.Tensor  # [N] kg
    inertia: torch.Tensor  # [N, 3, 3] kg m^2
    inertia_inv: torch.Tensor  # [N, 3, 3]
    gravity: torch.Tensor  # [N] m/s^2
    wing_area: torch.Tensor  # [N] m^2
    span: torch.Tensor  # [N] m
    chord: torch.Tensor  # [N] m
    aspect_ratio: torch.Tensor  # [N]
    taper_ratio: torch.Tensor  # [N]
    oswald: torch.Tensor  # [N]
    wing_constants: torch.Tensor  # [N, 5] ground_effect.wing_constants(aspect_ratio, taper_ratio)
    wing_quarter_chord: torch.Tensor  # [N, 3] m, body, relative to the CG
    aero_coefficients: torch.Tensor  # [N, T, 6]
    aero_rates: torch.Tensor  # [N, 6, 3]
    alpha_range: torch.Tensor  # [N, 2] rad
    beta_range: torch.Tensor  # [N, 2] rad
    ground_effect_mode: torch.Tensor  # [N] int (0 off, 1 induced, 2 paper)
    motor_position: torch.Tensor  # [N, M, 3] m
    motor_axis: torch.Tensor  # [N, M, 3]
    motor_spin: torch.Tensor  # [N, M]
    disk_area: torch.Tensor  # [N, M] m^2
    thrust_coefficient: torch.Tensor  # [N, M]
    discharge_speed: torch.Tensor  # [N, M] m/s
    torque_coefficient: torch.Tensor  # [N, M]
    torque_speed_constant: torch.Tensor  # [N, M]
    throttle_time_constant: torch.Tensor  # [N, M] s
    actuator_second_order: torch.Tensor  # [N, 3] bool
    actuator_time_constant: torch.Tensor  # [N, 3] s (first order; 1 where unused)
    actuator_natural_frequency: torch.Tensor  # [N, 3] rad/s (second order)
    actuator_damping: torch.Tensor  # [N, 3]
    surface_min: torch.Tensor  # [N, 3] rad
    surface_max: torch.Tensor  # [N, 3] rad
    aero_exponents: torch.Tensor  # [T, 5] long, shared

    @property
    def num_envs(self) -> int:
        return self.mass.shape[0]

    def per_env_fields(self) -> list[str]:
        return [f.name for f in fields(self) if f.name != "aero_exponents"]

    def to(self, device: torch.device | str | None = None, dtype: torch.dtype | None = None
           ) -> ModelParams:
        out = {}
        for f in fields(self):
            value = getattr(self, f.name)
            if value.is_floating_point():
                out[f.name] = value.to(device=device, dtype=dtype)
            else:
                out[f.name] = value.to(device=device)
        return ModelParams(**out)

    def assign(self, mask: torch.Tensor, **values: torch.Tensor) -> None:
        """Overwrite named per-env fields on the rows where ``mask`` [N] is True (in place)."""
        for name, value in values.items():
            if name not in self.per_env_fields():
                raise KeyError(f"unknown per-env parameter {name!r}")
            target = getattr(self, name)
            target[mask] = value.to(target.dtype).expand_as(target)[mask]
        if "inertia" in values:
            self.inertia_inv[mask] = torch.linalg.inv(self.inertia[mask])
        if "aspect_ratio" in values or "taper_ratio" in values:
            self.wing_constants[mask] = wing_constants(self.aspect_ratio[mask], self.taper_ratio[mask])


def build_params(
    airframe: Airframe,
    num_envs: int,
    device: torch.device | str = "cpu",
    dtype: torch.dtype = torch.float32,
    ground_effect: bool | str = True,
    gravity: float = 9.80665,
) -> ModelParams:
    """Tensors for ``num_envs`` copies of ``airframe`` (contiguous, independently writable)."""
    n = num_envs

    def rep(values, dt=dtype) -> torch.Tensor:
        t = torch.as_tensor(values, dtype=torch.float64).to(dt)
        return t.unsqueeze(0).repeat(n, *([1] * t.dim())).to(device)

    g = airframe.geometry
    a = airframe.aero
    m = airframe.motors
    acts = [airframe.actuators[s] for s in SURFACES]
    inertia = torch.as_tensor(airframe.inertia, dtype=torch.float64)
    return ModelParams(
        mass=rep(airframe.mass),
        inertia=rep(inertia),
        inertia_inv=rep(torch.linalg.inv(inertia)),
        gravity=rep(gravity),
        wing_area=rep(g.wing_area),
        span=rep(g.span),
        chord=rep(g.mean_chord),
        aspect_ratio=rep(g.aspect_ratio),
        taper_ratio=rep(g.taper_ratio),
        oswald=rep(a.oswald_efficiency),
        wing_constants=rep(wing_constants(torch.tensor(g.aspect_ratio, dtype=torch.float64),
                                          torch.tensor(g.taper_ratio, dtype=torch.float64))),
        wing_quarter_chord=rep(g.wing_quarter_chord),
        aero_coefficients=rep(a.coefficients),
        aero_rates=rep(a.rate_derivatives),
        alpha_range=rep(a.alpha_range),
        beta_range=rep(a.beta_range),
        ground_effect_mode=rep(ground_effect_mode(ground_effect), torch.int32),
        motor_position=rep([mo.position for mo in m]),
        motor_axis=rep([mo.thrust_axis for mo in m]),
        motor_spin=rep([float(mo.spin) for mo in m]),
        disk_area=rep([mo.disk_area for mo in m]),
        thrust_coefficient=rep([mo.thrust_coefficient for mo in m]),
        discharge_speed=rep([mo.discharge_speed for mo in m]),
        torque_coefficient=rep([mo.torque_coefficient for mo in m]),
        torque_speed_constant=rep([mo.torque_speed_constant for mo in m]),
        throttle_time_constant=rep([mo.time_constant for mo in m]),
        actuator_second_order=rep([ac.order == 2 for ac in acts], torch.bool),
        actuator_time_constant=rep([ac.time_constant if ac.order == 1 else 1.0 for ac in acts]),
        actuator_natural_frequency=rep([ac.natural_frequency for ac in acts]),
        actuator_damping=rep([ac.damping_ratio for ac in acts]),
        surface_min=rep([ac.limits[0] for ac in acts]),
        surface_max=rep([ac.limits[1] for ac in acts]),
        aero_exponents=torch.as_tensor(a.exponents, dtype=torch.long, device=device),
    )


# ---------------------------------------------------------------------------------------- warp twin
#: Bits per exponent in a packed monomial code (:func:`pack_exponents`).
EXPONENT_BITS = 3
EXPONENT_MASK = (1 << EXPONENT_BITS) - 1


def pack_exponents(exponents: torch.Tensor) -> torch.Tensor:
    """[T] int32 codes of the [T, V] exponent table, EXPONENT_BITS bits per variable (variable j
    in bits 3j..3j+2). The warp aero table (``aero.aero_coefficients_oge_wp``) reads one code per
    monomial and unpacks it with shifts and masks into indices that are provably in range; five
    int64 reads with sign fix-ups cost three times as many instructions (the table was a third of
    the CPU step)."""
    if exponents.numel() and (int(exponents.min()) < 0 or int(exponents.max()) > EXPONENT_MASK):
        raise ValueError(f"aero exponents must be in [0, {EXPONENT_MASK}] to be packed")
    shifts = torch.arange(exponents.shape[-1], device=exponents.device) * EXPONENT_BITS
    return (exponents.long() << shifts).sum(-1).to(torch.int32).contiguous()


Vec6 = vector_type(6)  # one aero-table row (CL, CD, CY, Cl, Cm, Cn)


@warp_struct
class WarpParams:
    """Warp views of :class:`ModelParams` (zero-copy, same memory; shapes as in ModelParams).

    [N, 3] fields are arrays of vec3, [N, 3, 3] arrays of mat33, [N, M, 3] 2-D arrays of vec3.
    Writes to the torch tensors (``ModelParams.assign``) are seen by the next launch without
    rebinding or recompiling.
    """

    mass: wp.array(dtype=wp.float32)
    inertia: wp.array(dtype=wp.mat33)
    inertia_inv: wp.array(dtype=wp.mat33)
    gravity: wp.array(dtype=wp.float32)
    wing_area: wp.array(dtype=wp.float32)
    span: wp.array(dtype=wp.float32)
    chord: wp.array(dtype=wp.float32)
    aspect_ratio: wp.array(dtype=wp.float32)
    taper_ratio: wp.array(dtype=wp.float32)
    oswald: wp.array(dtype=wp.float32)
    wing_constants: wp.array(dtype=WingConstants)
    wing_quarter_chord: wp.array(dtype=wp.vec3)
    aero_coefficients: wp.array2d(dtype=Vec6)  # [N, T] rows (CL, CD, CY, Cl, Cm, Cn)
    aero_rates: wp.array3d(dtype=wp.float32)
    alpha_range: wp.array(dtype=wp.vec2)
    beta_range: wp.array(dtype=wp.vec2)
    ground_effect_mode: wp.array(dtype=wp.int32)
    motor_position: wp.array2d(dtype=wp.vec3)
    motor_axis: wp.array2d(dtype=wp.vec3)
    motor_spin: wp.array2d(dtype=wp.float32)
    disk_area: wp.array2d(dtype=wp.float32)
    thrust_coefficient: wp.array2d(dtype=wp.float32)
    discharge_speed: wp.array2d(dtype=wp.float32)
    torque_coefficient: wp.array2d(dtype=wp.float32)
    torque_speed_constant: wp.array2d(dtype=wp.float32)
    throttle_time_constant: wp.array2d(dtype=wp.float32)
    actuator_second_order: wp.array2d(dtype=wp.bool)
    actuator_time_constant: wp.array(dtype=wp.vec3)
    actuator_natural_frequency: wp.array(dtype=wp.vec3)
    actuator_damping: wp.array(dtype=wp.vec3)
    surface_min: wp.array(dtype=wp.vec3)
    surface_max: wp.array(dtype=wp.vec3)
    aero_exponent_codes: wp.array(dtype=wp.int32)  # [T] aero.pack_exponents(aero_exponents)
    num_terms: int
    num_motors: int


_WARP_VECTOR_FIELDS = {
    "aero_coefficients": "Vec6", "wing_constants": "WingConstants",
    "inertia": "mat33", "inertia_inv": "mat33", "wing_quarter_chord": "vec3", "alpha_range": "vec2",
    "beta_range": "vec2", "motor_position": "vec3", "motor_axis": "vec3",
    "actuator_time_constant": "vec3", "actuator_natural_frequency": "vec3", "actuator_damping": "vec3",
    "surface_min": "vec3", "surface_max": "vec3",
}


def bind_warp_params(p: ModelParams) -> WarpParams:
    """Zero-copy Warp views of float32 ``p`` (its tensors must stay allocated and contiguous)."""
    out = WarpParams()
    for f in fields(p):
        if f.name == "aero_exponents":
            continue
        tensor = getattr(p, f.name)
        if tensor.is_floating_point() and tensor.dtype != torch.float32:
            raise TypeError(f"the warp backend runs in float32; {f.name} is {tensor.dtype}")
        if not tensor.is_contiguous():
            raise ValueError(f"parameter {f.name} must be contiguous to be bound zero-copy")
        name = _WARP_VECTOR_FIELDS.get(f.name)
        dtype = None if name is None else {"Vec6": Vec6, "WingConstants": WingConstants}.get(name) or getattr(
            wp, name)
        setattr(out, f.name, wp.from_torch(tensor, dtype=dtype))
    out.aero_exponent_codes = wp.from_torch(pack_exponents(p.aero_exponents))
    out.num_terms = int(p.aero_exponents.shape[0])
    out.num_motors = int(p.motor_spin.shape[1])
    return out
