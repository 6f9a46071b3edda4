"""Named presets of the paper's robustness grid: "nominal" | "mild" | "medium" | "severe".

One disturbance family at a time, severities in physical units:

    family            nominal   mild                 medium               severe
    sensors           off       noise floors x1      x2.5                 x5       (see SENSOR_FLOORS)
    obs_delay_ms      0         20                   50                   80
    action_delay_ms   0         20                   60                   100
    turbulence        off       sigma_u/V_a = 0.05   0.10                 0.15

The turbulence ratio is turned into W20 at the task's trim airspeed and nominal height (the
attitude/path tasks' initial height, the mean of the altitude task's targets), so sigma_u / V_a has
the stated value there and follows MIL-F-8785C elsewhere. ``turbulence`` also takes the MIL names
very_light / light / moderate / severe (W20 = 2 / 15 / 30 / 45 kt). The name "severe" is the MIL
severity (as in ``Simulator(turbulence="severe")``); the grid's severe turbulence cell is the ratio
0.15, given as a float (``turbulence=0.15``) or through :func:`grid_turbulence`.
"""

from __future__ import annotations

from dataclasses import replace

from ..physics.wind import TurbulenceConfig, turbulence_config
from .delay import ActionDelay, ObservationDelay
from .randomize import DomainRandomization, RandomizationConfig
from .sensors import SensorChannel, SensorConfig, SensorTransform

GRID = ("nominal", "mild", "medium", "severe")
OBS_DELAY_MS = {"nominal": 0.0, "mild": 20.0, "medium": 50.0, "severe": 80.0}
ACTION_DELAY_MS = {"nominal": 0.0, "mild": 20.0, "medium": 60.0, "severe": 100.0}
TURBULENCE_RATIO = {"mild": 0.05, "medium": 0.10}
SEVERE_TURBULENCE_RATIO = 0.15
SENSOR_SCALE = {"mild": 1.0, "medium": 2.5, "severe": 5.0}
#: Mild noise floors (1 sigma): GPS 0.5 m / 0.05 m/s, attitude 0.2 deg, gyro 0.005 rad/s, pitot 0.2 m/s.
SENSOR_FLOORS = {"gps_position": 0.5, "gps_velocity": 0.05, "attitude": 0.0035, "gyro": 0.005,
                 "airspeed": 0.2}


def sensor_preset(spec: str | SensorConfig | None) -> SensorConfig | None:
    """A SensorConfig from a grid name (None / "nominal": no sensor transform)."""
    if spec is None or isinstance(spec, SensorConfig):
        return spec
    if spec == "nominal":
        return None
    if spec not in SENSOR_SCALE:
        raise ValueError(f"unknown sensors preset {spec!r}; choose one of {GRID} or give a SensorConfig")
    k = SENSOR_SCALE[spec]
    return SensorConfig(**{name: SensorChannel(noise_std=k * floor) for name, floor in SENSOR_FLOORS.items()})


def delay_preset(spec: str | float | tuple[float, float] | None, table: dict[str, float]
                 ) -> float | tuple[float, float] | None:
    """Delay in ms (fixed or a range) from a grid name or a value; None / 0 / "nominal" -> None."""
    if isinstance(spec, str):
        if spec not in table:
            raise ValueError(f"unknown delay preset {spec!r}; choose one of {GRID} or give milliseconds")
        spec = table[spec]
    if spec is None or (isinstance(spec, int | float) and spec == 0):
        return None
    return spec


def nominal_height(task_config: object) -> float:
    """The height (m) a task flies at: its ``initial_height``, else the mean target, else 100 m."""
    height = getattr(task_config, "initial_height", None)
    if height is not None:
        return float(height)
    targets = getattr(task_config, "target_altitudes", None)
    return float(sum(targets) / len(targets)) if targets else 100.0


def resolve_turbulence(spec: object, airspeed: float, height: float) -> TurbulenceConfig | None:
    """TurbulenceConfig from a grid name ("mild", "medium": sigma_u/V_a), a MIL name, a float
    (sigma_u / V_a) or a config; ``airspeed`` (m/s) and ``height`` (m) calibrate the ratio and are the
    reference height of a config given by sigma_u without one."""
    if isinstance(spec, str) and spec in ("nominal", "off", "none"):
        return None
    ratio = None
    if isinstance(spec, str) and spec in TURBULENCE_RATIO:
        ratio = TURBULENCE_RATIO[spec]
    elif isinstance(spec, int | float) and not isinstance(spec, bool):
        ratio = float(spec)
    if ratio is not None:
        return TurbulenceConfig(sigma_u=ratio * airspeed, reference_height=height)
    config = turbulence_config(spec)
    if config is not None and config.sigma_u is not None and config.reference_height is None:
        config = replace(config, reference_height=height)
    return config


def grid_turbulence(level: str, airspeed: float, height: float) -> TurbulenceConfig | None:
    """The turbulence family of the grid ("severe" means sigma_u/V_a = 0.15 here, not MIL severe)."""
    if level == "severe":
        return TurbulenceConfig(sigma_u=SEVERE_TURBULENCE_RATIO * airspeed, reference_height=height)
    return resolve_turbulence(level, airspeed, height)




def robustness_transforms(sensors: object = None, obs_delay_ms: object = None, action_delay_ms: object = None,
                          randomize: object = None, seed: int | None = None) -> list:
    """The transforms ``make_env`` appends, in order: domain randomisation (before the base reset),
    action delay, sensors, observation delay (after the sensors). Empty when all are off.

    sensors: grid name or SensorConfig; delays: grid name, ms, or a (low, high) ms range drawn per
    episode; randomize: True (default ranges), a RandomizationConfig, or None / False. ``seed``: the
    root seed of every transform (each derives its own stream from it and its place in the chain);
    None: they follow the seed of the env they are appended to (fresh entropy when it has none).
    """
    out: list = []
    if randomize is not None and randomize is not False:
        config = None if randomize is True else randomize
        if config is not None and not isinstance(config, RandomizationConfig):
            raise TypeError(f"randomize must be True, False, None or a RandomizationConfig, "
                            f"got {randomize!r}")
        out.append(DomainRandomization(config, seed=seed))
    action = delay_preset(action_delay_ms, ACTION_DELAY_MS)
    if action is not None:
        out.append(ActionDelay(action, seed=seed))
    sensor_config = sensor_preset(sensors)
    if sensor_config is not None:
        out.append(SensorTransform(sensor_config, seed=seed))
    observation = delay_preset(obs_delay_ms, OBS_DELAY_MS)
    if observation is not None:
        out.append(ObservationDelay(observation, seed=seed))
    return out
