"""A JSBSim aircraft's engine and propeller, sampled in steady state into a thrust map.

For each (altitude, airspeed) the aircraft is put at that state with its translational and rotational
integrators switched off (JSBSim integrator 0: the state does not move), the engine running and the
mixture full rich, the magnetos on; an engine that is not running then (JSBSim's ``set-running`` does
not start some engines at low airspeed, e.g. the c182's behind its constant-speed propeller) or that
stops is cranked with the starter for ``START_S``. Each throttle is then held until the engine speed
settles (``SETTLE_S``) and the
thrust, the propeller's roll moment and the engine properties the aero functions read (prop-wash
induced velocity, thrust coefficient) are recorded. The map is the falcon-rl "thrust_map" propeller
model: airspeed (axial inflow) x throttle x density, multilinear, clamped.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..constants import FT
from .jsbsim_functions import multilinear

LBF = 4.4482216152605  # N
SLUG_FT3 = 515.378818  # kg/m^3 per slug/ft^3
#: Seconds a throttle is held before reading (the engine speed settles within a few seconds).
SETTLE_S = 8.0
#: Seconds the starter cranks an engine that is not running.
START_S = 3.0
RUNNING = "propulsion/engine[0]/set-running"
THRUST = "propulsion/engine[0]/thrust-lbs"
ROLL_MOMENT = "moments/l-prop-lbsft"


def quiet_fdm(root: Path):
    """A JSBSim executive over ``root`` without its banner."""
    import jsbsim

    previous = os.environ.get("JSBSIM_DEBUG")
    os.environ["JSBSIM_DEBUG"] = "0"
    try:
        fdm = jsbsim.FGFDMExec(str(root))
    finally:
        if previous is None:
            del os.environ["JSBSIM_DEBUG"]
        else:
            os.environ["JSBSIM_DEBUG"] = previous
    fdm.set_debug_level(0)
    fdm.disable_output()
    return fdm


@dataclass
class EngineMap:
    """Sampled steady-state engine: grids (airspeed m/s, throttle, density kg/m^3) and arrays on them."""

    airspeed: np.ndarray
    throttle: np.ndarray
    density: np.ndarray
    thrust: np.ndarray  # [A, T, D] N
    torque: np.ndarray  # [A, T, D] N m, reaction on the airframe about body x
    properties: dict[str, np.ndarray] = field(default_factory=dict)  # JSBSim units, [A, T, D]

    def __call__(
        self, name: str, airspeed: np.ndarray, throttle: np.ndarray, density: np.ndarray
    ) -> np.ndarray:
        """A sampled engine property at the given points (broadcast together)."""
        key = name.replace("propulsion/engine/", "propulsion/engine[0]/")
        if key not in self.properties:
            raise KeyError(name)
        shape = np.broadcast_shapes(np.shape(airspeed), np.shape(throttle), np.shape(density))
        points = [
            np.broadcast_to(np.asarray(a, dtype=float), shape).reshape(-1)
            for a in (airspeed, throttle, density)
        ]
        grids = (self.airspeed, self.throttle, self.density)
        return multilinear(grids, self.properties[key], points).reshape(shape)


def crank(fdm, frames: int) -> None:
    """Run the starter for ``frames`` frames, then release it."""
    fdm["propulsion/starter_cmd"] = 1
    for _ in range(frames):
        fdm.run()
    fdm["propulsion/starter_cmd"] = 0


def sample_engine(
    root: Path,
    model: str,
    airspeeds: np.ndarray,
    throttles: np.ndarray,
    altitudes_m: np.ndarray,
    properties: tuple[str, ...] = (),
) -> EngineMap:
    """Steady-state thrust map of JSBSim aircraft ``model`` under ``root`` (see the module doc)."""
    fdm = quiet_fdm(root)
    if not fdm.load_model(model):
        raise RuntimeError(f"JSBSim could not load {model!r} from {root}")
    names = tuple(p.replace("propulsion/engine/", "propulsion/engine[0]/") for p in properties)
    shape = (len(altitudes_m), len(airspeeds), len(throttles))
    thrust, torque, density = np.zeros(shape), np.zeros(shape), np.zeros(len(altitudes_m))
    recorded = {p: np.zeros(shape) for p in names}
    frames = round(SETTLE_S / fdm.get_delta_t())
    for a, height in enumerate(altitudes_m):
        for s, speed in enumerate(airspeeds):
            fdm["ic/h-sl-ft"] = float(height) / FT
            fdm["ic/vt-fps"] = float(speed) / FT
            for angle in ("alpha", "beta", "theta", "phi"):
                fdm[f"ic/{angle}-rad"] = 0.0
            fdm.run_ic()
            fdm["propulsion/set-running"] = -1
            fdm["fcs/mixture-cmd-norm"] = 1.0
            for integrator in (
                "rate/rotational",
                "rate/translational",
                "position/rotational",
                "position/translational",
            ):
                fdm[f"simulation/integrator/{integrator}"] = 0
            fdm["propulsion/magneto_cmd"] = 3
            for t, throttle in enumerate(throttles):
                fdm["fcs/throttle-cmd-norm"] = float(throttle)
                if not fdm[RUNNING]:
                    crank(fdm, round(START_S / fdm.get_delta_t()))
                for _ in range(frames):
                    fdm.run()
                thrust[a, s, t] = fdm[THRUST] * LBF
                torque[a, s, t] = fdm[ROLL_MOMENT] * LBF * FT
                for p in names:
                    recorded[p][a, s, t] = fdm[p]
            density[a] = fdm["atmosphere/rho-slugs_ft3"] * SLUG_FT3
    order = np.argsort(density)

    def arrange(values: np.ndarray) -> np.ndarray:  # [alt, speed, throttle] -> [speed, throttle, density]
        return np.transpose(values[order], (1, 2, 0))

    return EngineMap(
        np.asarray(airspeeds, float),
        np.asarray(throttles, float),
        density[order],
        arrange(thrust),
        arrange(torque),
        {p: arrange(v) for p, v in recorded.items()},
    )
