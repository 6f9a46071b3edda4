"""TorchRL transforms for robustness studies: sensors, observation/action delay, domain randomisation;
and the flight recorder (:class:`FlightRecorder`, trajectories to a recording file for the viewers).

    env = make_env("attitude", "navion", num_envs=256, sensors="mild", obs_delay_ms=20,
                   action_delay_ms=(20, 60), randomize=True, turbulence="moderate")

or compose them yourself on a :class:`~falcon_rl.envs.FixedWingEnv`:

    env = TransformedEnv(base, Compose(DomainRandomization(), SensorTransform(SensorConfig(...)),
                                       ObservationDelay(50.0), ActionDelay(60.0)))

The true state stays under ("state", ...) (metrics, rewards); what the policy perceives is
"observation" and ("measured", ...). Every transform keeps per-env buffers and resets only the rows
of a partial reset. Presets of the paper's robustness grid are in :mod:`.presets`. The transforms reach
the base env only through the flight-env interface documented on FixedWingEnv (:func:`flight_env`).

The public names load on first use (PEP 562): importing this package imports no transform.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._lazy import lazy_exports

if TYPE_CHECKING:
    from ._env import FLIGHT_ENV_INTERFACE, FlightEnv, flight_env
    from .delay import ActionDelay, ObservationDelay
    from .flight_recorder import FlightRecorder
    from .presets import (
        GRID,
        delay_preset,
        grid_turbulence,
        resolve_turbulence,
        robustness_transforms,
        sensor_preset,
    )
    from .randomize import DomainRandomization, RandomizationConfig
    from .sensors import SENSOR_FIELDS, SensorChannel, SensorConfig, SensorTransform

#: Public name -> the submodule that defines it.
_LAZY = {
    **dict.fromkeys(("FLIGHT_ENV_INTERFACE", "FlightEnv", "flight_env"), "_env"),
    **dict.fromkeys(("ActionDelay", "ObservationDelay"), "delay"),
    **dict.fromkeys(("GRID", "delay_preset", "grid_turbulence", "resolve_turbulence", "robustness_transforms",
                     "sensor_preset"), "presets"),
    **dict.fromkeys(("DomainRandomization", "RandomizationConfig"), "randomize"),
    "FlightRecorder": "flight_recorder",
    **dict.fromkeys(("SENSOR_FIELDS", "SensorChannel", "SensorConfig", "SensorTransform"), "sensors"),
}

__all__ = ["FLIGHT_ENV_INTERFACE", "GRID", "SENSOR_FIELDS", "ActionDelay", "DomainRandomization", "FlightEnv",
           "FlightRecorder", "ObservationDelay", "RandomizationConfig", "SensorChannel", "SensorConfig",
           "SensorTransform", "delay_preset", "flight_env", "grid_turbulence", "resolve_turbulence",
           "robustness_transforms", "sensor_preset"]


__getattr__, __dir__ = lazy_exports(__name__, _LAZY, __all__)
