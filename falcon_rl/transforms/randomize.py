"""Domain randomisation as a TorchRL transform: per-env model parameters redrawn at each reset.

Before the base env resets, the rows being reset get fresh draws (the other rows keep theirs),
written with the base env's ``set_physical_parameters`` (one masked write; on FixedWingEnv it wraps
``ModelParams.assign``, which the Warp backend sees without rebinding). Draws are uniform, relative to
the env's ``nominal_physical_parameters`` unless stated:

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
    model switches                 each switch (``physics.switches.ModelSwitches`` field) in its
                                   simplified form with probability p, else the full model (for
                                   mixed-model training or ablation batches)

A range of None leaves that parameter nominal. The specs are unchanged. Draws come from the
transform's own stream (``SeededTransform``: seeded from the env). The draws happen before the base
env resets; a ``reset(seed=s)`` reseeds the base env only after that, so then the reset rows are drawn
again, from the new stream, right after the base reset (the reset's own output still reflects the
previous draw; ``env.set_seed(s)`` before ``reset()`` has no such lag).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
from tensordict import TensorDictBase

from ..physics.switches import SWITCH_NAMES, SWITCH_ROWS
from ._buffers import SeededTransform, reset_mask
from ._env import flight_env, seed_record

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
    #: {switch: p}: each ``ModelSwitches`` field in its simplified form with probability p per episode
    #: (e.g. {"actuators": 0.5}); None or a missing switch: the env's own setting.
    model_switches: dict[str, float] | None = None

    def __post_init__(self) -> None:
        for name, p in (self.model_switches or {}).items():
            if name not in SWITCH_NAMES:
                raise ValueError(f"model_switches: unknown switch {name!r}; switches: {list(SWITCH_NAMES)}")
            if not 0.0 <= float(p) <= 1.0:
                raise ValueError(f"model_switches[{name!r}] must be a probability in [0, 1], got {p}")


#: Model parameters drawn at each reset (all written, nominal where the range is None).
_FIELDS = ("mass", "inertia", "aero_coefficients", "aero_rates", "wing_quarter_chord", "motor_position",
           "thrust_coefficient", "actuator_time_constant", "actuator_natural_frequency",
           "throttle_time_constant")
#: Reference lengths of the CG-shift moment transfer (read, never written).
_REFERENCE_FIELDS = ("chord", "span")


class DomainRandomization(SeededTransform):
    """Redraw model parameters, wind and turbulence severity of the reset rows before each reset."""

    def __init__(self, config: RandomizationConfig | None = None, seed: int | None = None):
        super().__init__(seed)
        self.config = config or RandomizationConfig()
        self._nominal: dict[str, torch.Tensor] | None = None

    def _uniform(self, bounds: Range, n: int, like: torch.Tensor, default: float = 1.0) -> torch.Tensor:
        if bounds is None:
            return torch.full((n,), default, dtype=like.dtype, device=like.device)
        u = torch.rand(n, generator=self.stream("cpu"), dtype=like.dtype).to(like.device)
        return bounds[0] + (bounds[1] - bounds[0]) * u

    def _sample_params(self, n: int) -> dict[str, torch.Tensor]:
        """Fresh draws {field: [N, ...]} of every field in ``_FIELDS`` for all N envs."""
        cfg, nom = self.config, self._nominal
        assert nom is not None
        like = nom["mass"]
        out = {"mass": nom["mass"] * self._uniform(cfg.mass_scale, n, like),
               "inertia": nom["inertia"] * self._uniform(cfg.inertia_scale, n, like)[:, None, None]}
        aero_scale = torch.stack([self._uniform(cfg.aero_scale, n, like) for _ in range(6)], -1)  # [N, 6]
        coeffs = nom["aero_coefficients"] * aero_scale[:, None, :]
        rates = nom["aero_rates"] * aero_scale[:, :, None]
        dx = self._uniform(cfg.cg_shift, n, like, default=0.0)
        shift = torch.stack([dx, torch.zeros_like(dx), torch.zeros_like(dx)], -1)
        cm = -(dx / nom["chord"])[:, None]
        cn = -(dx / nom["span"])[:, None]
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
        env = flight_env(self, "nominal_physical_parameters", "set_physical_parameters")
        self._randomize(reset_mask(tensordict, env.batch_size[0], env.device))
        return tensordict

    def _reset(self, tensordict: TensorDictBase, tensordict_reset: TensorDictBase) -> TensorDictBase:
        record = seed_record(self)
        if record is not None and record != self._record:  # the base reset took a seed: draw again
            self._randomize(reset_mask(tensordict, tensordict_reset.batch_size[0], tensordict_reset.device))
        return tensordict_reset

    def _randomize(self, mask: torch.Tensor) -> None:
        """Draw every randomised quantity for all N envs and write the rows of ``mask`` [N] bool."""
        env = flight_env(self, "nominal_physical_parameters", "set_physical_parameters")
        n = env.batch_size[0]
        self.stream("cpu")  # follow a reseed of the env before drawing (even when nothing is drawn)
        if self._nominal is None:
            self._nominal = env.nominal_physical_parameters(_FIELDS + _REFERENCE_FIELDS)
        values = self._sample_params(n)
        cfg, like = self.config, self._nominal["mass"]
        if cfg.wind_speed is not None:
            speed = self._uniform(cfg.wind_speed, n, like)
            heading = self._uniform((0.0, 2.0 * math.pi), n, like)
            values["wind_ned"] = torch.stack([speed * torch.cos(heading), speed * torch.sin(heading),
                                              0.0 * speed], -1)
        if cfg.turbulence_w20 is not None:
            values["turbulence_w20"] = self._uniform(cfg.turbulence_w20, n, like)
        for name, p in (cfg.model_switches or {}).items():
            simplified = self._uniform((0.0, 1.0), n, like) < float(p)
            row = SWITCH_ROWS[name]
            values[row] = simplified.to(torch.int32)
        env.set_physical_parameters(mask, **values)

    def sampled(self) -> dict[str, torch.Tensor]:
        """Current per-env values {name: [N, ...]} of what this transform draws (copies): the model
        fields, wind_ned, and turbulence_w20 and the model-switch rows when it draws them."""
        env = flight_env(self, "physical_parameters")
        cfg = self.config
        names = (*_FIELDS, "wind_ned", *(("turbulence_w20",) if cfg.turbulence_w20 is not None else ()),
                 *(SWITCH_ROWS[name] for name in cfg.model_switches or {}))
        return env.physical_parameters(names)
