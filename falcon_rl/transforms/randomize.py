"""Domain randomisation as a TorchRL transform: per-env model parameters redrawn at each reset.

Before the base env resets, the rows being reset get fresh draws (the other rows keep theirs),
written with ``ModelParams.assign`` (one masked write per field; the Warp backend sees them without
rebinding). Draws are uniform, relative to the nominal airframe unless stated:

    mass, inertia                  x U(lo, hi)   (inertia: the whole tensor by one factor)
    CG shift along body x          U(lo, hi) m   moves the wing and motors by -dx and transfers the
                                                 moments of lift and side force: dC_m = -(dx/c) C_L,
                                                 dC_n = -(dx/b) C_Y (drag and alpha rotation neglected)
    aero coefficient scales        x U(lo, hi)   each of C_L, C_D, C_Y, C_l, C_m, C_n (all its terms)
    motor constant                 x U(lo, hi)   thrust coefficient
    actuator bandwidth             x U(lo, hi)   surface bandwidth (time constants / natural frequencies)
                                                 and throttle time constants
    wind                           |w| ~ U(lo, hi) m/s, horizontal, direction U(0, 2 pi)
    turbulence W20                 U(lo, hi) m/s  (needs turbulence on in the env)

A range of None leaves that parameter nominal. The specs are unchanged.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
from tensordict import TensorDictBase
from torchrl.envs import Transform

from ..physics.params import ModelParams
from ._buffers import reset_mask

Range = tuple[float, float] | None


@dataclass
class RandomizationConfig:
    """Uniform ranges of the randomised quantities (None: nominal); see the module docstring."""

    mass_scale: Range = (0.9, 1.1)
    inertia_scale: Range = (0.85, 1.15)
    cg_shift: Range = (-0.02, 0.02)
    aero_scale: Range = (0.9, 1.1)
    motor_scale: Range = (0.9, 1.1)
    actuator_bandwidth_scale: Range = (0.8, 1.2)
    wind_speed: Range = None
    turbulence_w20: Range = None


_FIELDS = ("mass", "inertia", "aero_coefficients", "aero_rates", "wing_quarter_chord", "motor_position",
           "thrust_coefficient", "actuator_time_constant", "actuator_natural_frequency",
           "throttle_time_constant")


class DomainRandomization(Transform):
    """Redraw model parameters, wind and turbulence severity of the reset rows before each reset."""

    def __init__(self, config: RandomizationConfig | None = None, seed: int = 0):
        super().__init__(in_keys=[], out_keys=[])
        self.config = config or RandomizationConfig()
        self.generator = torch.Generator().manual_seed(int(seed))
        self._nominal: dict[str, torch.Tensor] | None = None

    def _uniform(self, bounds: Range, n: int, like: torch.Tensor, default: float = 1.0) -> torch.Tensor:
        if bounds is None:
            return torch.full((n,), default, dtype=like.dtype, device=like.device)
        u = torch.rand(n, generator=self.generator, dtype=like.dtype).to(like.device)
        return bounds[0] + (bounds[1] - bounds[0]) * u

    def _sample_params(self, p: ModelParams, n: int) -> dict[str, torch.Tensor]:
        cfg, nom = self.config, self._nominal
        assert nom is not None
        like = p.mass
        out = {"mass": nom["mass"] * self._uniform(cfg.mass_scale, n, like),
               "inertia": nom["inertia"] * self._uniform(cfg.inertia_scale, n, like)[:, None, None]}
        aero_scale = torch.stack([self._uniform(cfg.aero_scale, n, like) for _ in range(6)], -1)  # [N, 6]
        coeffs = nom["aero_coefficients"] * aero_scale[:, None, :]
        rates = nom["aero_rates"] * aero_scale[:, :, None]
        dx = self._uniform(cfg.cg_shift, n, like, default=0.0)
        shift = torch.stack([dx, torch.zeros_like(dx), torch.zeros_like(dx)], -1)
        cm = -(dx / p.chord)[:, None]
        cn = -(dx / p.span)[:, None]
        coeffs = coeffs.clone()
        coeffs[..., 4] = coeffs[..., 4] + cm * coeffs[..., 0]
        coeffs[..., 5] = coeffs[..., 5] + cn * coeffs[..., 2]
        rates = rates.clone()
        rates[:, 4] = rates[:, 4] + cm * rates[:, 0]
        rates[:, 5] = rates[:, 5] + cn * rates[:, 2]
        out.update(aero_coefficients=coeffs, aero_rates=rates,
                   wing_quarter_chord=nom["wing_quarter_chord"] - shift,
                   motor_position=nom["motor_position"] - shift[:, None, :],
                   thrust_coefficient=nom["thrust_coefficient"]
                   * self._uniform(cfg.motor_scale, n, like)[:, None])
        band = self._uniform(cfg.actuator_bandwidth_scale, n, like)
        out.update(actuator_time_constant=nom["actuator_time_constant"] / band[:, None],
                   actuator_natural_frequency=nom["actuator_natural_frequency"] * band[:, None],
                   throttle_time_constant=nom["throttle_time_constant"] / band[:, None])
        return out

    def _reset_env_preprocess(self, tensordict: TensorDictBase | None) -> TensorDictBase | None:
        sim = self.parent.base_env.sim
        n = sim.num_envs
        mask = reset_mask(tensordict, n, sim.device)
        p = sim.params
        if self._nominal is None:
            self._nominal = {name: getattr(p, name).clone() for name in _FIELDS}
        p.assign(mask, **self._sample_params(p, n))
        cfg = self.config
        if cfg.wind_speed is not None:
            speed = self._uniform(cfg.wind_speed, n, p.mass)
            heading = self._uniform((0.0, 2.0 * math.pi), n, p.mass)
            wind = torch.stack([speed * torch.cos(heading), speed * torch.sin(heading), 0.0 * speed], -1)
            sim.wind_ned[mask] = wind[mask]
        if cfg.turbulence_w20 is not None:
            if sim.turbulence is None:
                raise ValueError("turbulence_w20 randomisation needs turbulence on in the env "
                                 "(make_env(..., turbulence=...))")
            sim.turbulence.w20[mask] = self._uniform(cfg.turbulence_w20, n, p.mass)[mask]
        return tensordict

    def sampled(self) -> dict[str, torch.Tensor]:
        """Current per-env values of the randomised fields (views of the simulator's tensors)."""
        sim = self.parent.base_env.sim
        out = {name: getattr(sim.params, name) for name in _FIELDS}
        out["wind_ned"] = sim.wind_ned
        if sim.turbulence is not None:
            out["turbulence_w20"] = sim.turbulence.w20
        return out
