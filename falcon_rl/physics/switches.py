"""Model switches: each physical phenomenon can be simplified, per env, for ablation studies.

    ModelSwitches()                                   # the full model (the default everywhere)
    ModelSwitches(actuators="ideal", rate_damping=False)
    Simulator("navion", 64, model={"throttle_lag": False})
    sim.set_model(mask, actuators="ideal")            # only the envs where mask [N] is True

Each switch is stored per env as an int32 row of the parameter table (``params.PARAMETER_TABLE``),
0 for the full model and 1 for the simplified form, so one batch can mix variants:

===================  ====================  ======================================================
switch               parameter row         simplified form (row = 1)
===================  ====================  ======================================================
actuators="ideal"    ideal_actuators       surfaces follow the command with zero lag: position =
                                           clamp(commanded deflection), rate = 0, the command held
                                           over the step (no actuator dynamics)
throttle_lag=False   ideal_throttle        throttle state = commanded throttle over the step
atmosphere=          constant_density      rho = ISA sea-level density (1.225 kg/m^3) at every
"constant"                                 height
rate_damping=False   no_rate_damping       the rate derivatives b[k, i] (p b/2V, q c/2V, r b/2V)
                                           contribute nothing to the aero coefficients
propeller_torque=    no_propeller_torque   no reaction torque Q a of the propellers (thrust and
False                                      its moment r x F stay)
surface="sea"        sea_surface           not a simplification: the env flies over its own wave
                                           field (``Simulator(sea=...)``, ``Simulator.set_sea``;
                                           ``surface.py``) instead of the flat ground (row = 0)
===================  ====================  ======================================================
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any

#: Allowed values of the string switches.
ACTUATOR_MODELS = ("dynamic", "ideal")
ATMOSPHERE_MODELS = ("isa", "constant")
SURFACE_MODELS = ("flat", "sea")


@dataclass(frozen=True)
class ModelSwitches:
    """Which form of each phenomenon an env simulates (defaults: the full model).

    Attributes:
        actuators: "dynamic" (first/second-order surface actuators) or "ideal" (position =
            clamped commanded deflection, rate 0, held over the step).
        throttle_lag: first-order throttle lag; False sets the throttle state to the command.
        atmosphere: "isa" (ISA density at the CG height) or "constant" (sea-level density).
        rate_damping: aero rate derivatives in the coefficients; False drops them.
        propeller_torque: propeller reaction torque about the thrust axis; False drops it.
        surface: "flat" (the ground, at height 0) or "sea" (the env's wave field; a calm sea until one
            is drawn, ``Simulator.set_sea``).
    """

    actuators: str = "dynamic"
    throttle_lag: bool = True
    atmosphere: str = "isa"
    rate_damping: bool = True
    propeller_torque: bool = True
    surface: str = "flat"

    def __post_init__(self) -> None:
        if self.actuators not in ACTUATOR_MODELS:
            raise ValueError(f"model switch 'actuators' must be one of {ACTUATOR_MODELS}, "
                             f"got {self.actuators!r}")
        if self.atmosphere not in ATMOSPHERE_MODELS:
            raise ValueError(f"model switch 'atmosphere' must be one of {ATMOSPHERE_MODELS}, "
                             f"got {self.atmosphere!r}")
        if self.surface not in SURFACE_MODELS:
            raise ValueError(f"model switch 'surface' must be one of {SURFACE_MODELS}, got {self.surface!r}")
        for name in ("throttle_lag", "rate_damping", "propeller_torque"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"model switch {name!r} must be True or False, got {getattr(self, name)!r}")

    @classmethod
    def from_spec(cls, spec: ModelSwitches | Mapping[str, Any] | None) -> ModelSwitches:
        """A ModelSwitches from None (the full model), a ModelSwitches or a mapping of field names."""
        if spec is None:
            return cls()
        if isinstance(spec, ModelSwitches):
            return spec
        if not isinstance(spec, Mapping):
            raise ValueError(f"model must be None, a ModelSwitches or a mapping, got {type(spec).__name__}")
        check_switch_names(spec)
        return cls(**spec)

    def flags(self) -> dict[str, int]:
        """The parameter rows of these switches: row name -> 0 (full model) or 1 (simplified)."""
        return {
            "ideal_actuators": int(self.actuators == "ideal"),
            "ideal_throttle": int(not self.throttle_lag),
            "constant_density": int(self.atmosphere == "constant"),
            "no_rate_damping": int(not self.rate_damping),
            "no_propeller_torque": int(not self.propeller_torque),
            "sea_surface": int(self.surface == "sea"),
        }


#: Names of the switches (the fields of :class:`ModelSwitches`).
SWITCH_NAMES: tuple[str, ...] = tuple(f.name for f in fields(ModelSwitches))
#: Switch name -> its parameter row.
SWITCH_ROWS: dict[str, str] = dict(zip(SWITCH_NAMES, ModelSwitches().flags(), strict=True))


def check_switch_names(names: Mapping[str, Any]) -> None:
    """Raise ValueError for a name that is not a switch."""
    unknown = sorted(set(names) - set(SWITCH_NAMES))
    if unknown:
        raise ValueError(f"unknown model switches {unknown}; switches: {list(SWITCH_NAMES)}")


def switch_flags(spec: ModelSwitches | Mapping[str, Any] | None, names: Mapping[str, Any] | None = None
                 ) -> dict[str, int]:
    """Flag rows of ``spec``; with ``names`` only the rows of those switches (for a partial update)."""
    flags = ModelSwitches.from_spec(spec).flags()
    if names is None:
        return flags
    return {SWITCH_ROWS[name]: flags[SWITCH_ROWS[name]] for name in names}
