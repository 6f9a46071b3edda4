"""Fly the falcon-rl simulator and the exported JSBSim aircraft from the same initial state.

Planet. JSBSim flies over a round, rotating Earth. For a like-for-like run we load a planet that
is a sphere with no rotation (no Coriolis or centrifugal terms) and no J2, of radius
``PLANET_RADIUS`` (100 Earth radii by default), with GM = g0 (R + h0)^2 so that gravity is exactly
g0 = 9.80665 m/s^2 at the start height (it falls off by 2 h / R per metre climbed, 3e-9/m).
On the real Earth radius, curvature alone relieves the wing by V^2 / R (4.5e-4 m/s^2 for the
Navion at cruise), a 2 cm climb over 10 s of zero-input flight; on the default sphere it is
100 times smaller, and JSBSim still resolves altitude to about 0.1 micrometre. Pass
``planet_radius=EARTH_RADIUS`` to see it. The aircraft starts at latitude and longitude 0 heading
north over terrain at sea level; latitude and longitude become local north and east by arc
length at the current radius. Both simulators use ISA 1976 and still air; JSBSim's sea-level
pressure (2116.228 psf = 101325.54 Pa) and gas constant put its density 8.8e-6 (relative) above
ours, which shows as a sub-millimetre climb over 10 s.

Timing. Our ``Simulator.step(u_k)`` integrates [t_k, t_k+1] with RK4 and continuous actuator
states under the held command u_k. A JSBSim frame first propagates the state with the forces
computed at the end of the previous frame, then runs the flight controls and the forces on the
commands set before it: those forces drive the *next* interval. So the command held over
[t_k, t_k+1] is set before the frame that ends at t_k (``run_ic`` for k = 0). What remains is
discretisation: JSBSim's Tustin actuator filters and its default integrators (rectangular Euler
for the rotational rates, Adams-Bashforth for the rest) against our RK4, largest during the
fast part of a doublet.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch
from tqdm.auto import tqdm

from ..airframe import Airframe
from ..constants import FT, G0
from ..physics import state as S
from ..physics.dynamics import air_data
from ..physics.ground_effect import GE_INDUCED, GE_OFF
from ..physics.rotations import quaternion_to_euler
from ..physics.simulator import Simulator
from .jsbsim_engine import quiet_fdm
from .jsbsim_export import GE_SWITCH, SURFACE_CMD, SURFACE_NAMES, THROTTLE_CMD

#: WGS84 equatorial radius, m.
EARTH_RADIUS = 6_378_137.0
#: Radius of the default comparison sphere, m: 100 Earth radii make curvature negligible.
PLANET_RADIUS = 100.0 * EARTH_RADIUS
#: Channels recorded by both simulators, with their units.
CHANNELS: dict[str, str] = {
    "altitude": "m", "pitch_rate": "rad/s", "airspeed": "m/s", "alpha": "rad", "beta": "rad",
    "theta": "rad", "phi": "rad", "psi": "rad", "roll_rate": "rad/s", "yaw_rate": "rad/s",
    "u": "m/s", "v": "m/s", "w": "m/s", "north": "m", "east": "m",
}


@dataclass
class Trajectory:
    """Time series sampled at t_k = k dt, k = 0..K (the initial state included)."""

    time: np.ndarray  # [K + 1] s
    channels: dict[str, np.ndarray] = field(default_factory=dict)  # name -> [K + 1]


def falcon_channels(states: torch.Tensor) -> dict[str, np.ndarray]:
    """Channels of a state history [T, S] (still air, so the airspeed is the inertial speed)."""
    airspeed, alpha, beta = air_data(states[:, S.VELOCITY])
    euler = quaternion_to_euler(states[:, S.QUATERNION])
    rates, uvw = states[:, S.ANGULAR_RATE], states[:, S.VELOCITY]
    position = states[:, S.POSITION]
    out = {"altitude": S.height(states), "pitch_rate": rates[:, S.PITCH], "airspeed": airspeed,
           "alpha": alpha, "beta": beta, "theta": euler[:, S.PITCH], "phi": euler[:, S.ROLL],
           "psi": euler[:, S.YAW], "roll_rate": rates[:, S.ROLL], "yaw_rate": rates[:, S.YAW],
           "u": uvw[:, S.X], "v": uvw[:, S.Y], "w": uvw[:, S.Z], "north": position[:, S.NORTH],
           "east": position[:, S.EAST]}
    return {k: v.detach().cpu().numpy().astype(np.float64) for k, v in out.items()}


def fly_falcon(airframe: Airframe, initial: torch.Tensor, commands: np.ndarray, ground_effect: list[bool],
               dt: float = 0.01, progress: bool = False) -> list[Trajectory]:
    """Our simulator (torch, float64, RK4), all runs batched: initial states [N, S], commands
    [K, N, 4], ground effect on/off per run (N flags). Returns N trajectories of K + 1 samples."""
    n = initial.shape[0]
    sim = Simulator(airframe, num_envs=n, dtype=torch.float64, ground_effect=True, dt=dt)
    mode = torch.tensor([GE_INDUCED if on else GE_OFF for on in ground_effect], dtype=torch.int32)
    sim.params.assign(torch.ones(n, dtype=torch.bool), ground_effect_mode=mode)
    sim.reset(initial.to(torch.float64))
    history = [sim.x.clone()]
    for u in tqdm(torch.as_tensor(commands, dtype=torch.float64), desc=f"falcon-rl {airframe.name}",
                  unit="step", disable=not progress, leave=False):
        sim.step(u)
        history.append(sim.x.clone())
    states = torch.stack(history)  # [K + 1, N, S]
    time = np.arange(states.shape[0]) * dt
    return [Trajectory(time, falcon_channels(states[:, i])) for i in range(n)]


def write_planet(path: Path, start_height: float, radius: float = PLANET_RADIUS) -> Path:
    """A non-rotating sphere of ``radius`` m with gravity g0 at ``start_height`` (see module doc)."""
    radius_ft = radius / FT
    gm = G0 * (radius + start_height) ** 2 / FT**3
    path.write_text(
        '<?xml version="1.0"?>\n<planet name="falcon-rl comparison sphere">\n'
        f'  <semimajor_axis unit="FT">{radius_ft!r}</semimajor_axis>\n'
        f'  <semiminor_axis unit="FT">{radius_ft!r}</semiminor_axis>\n'
        '  <rotation_rate unit="RAD/SEC">0</rotation_rate>\n'
        f'  <GM unit="FT3/SEC2">{gm!r}</GM>\n  <J2>0</J2>\n</planet>\n')
    return path


def make_fdm(root: Path, airframe: Airframe, start_height: float, dt: float = 0.01,
             planet_radius: float = PLANET_RADIUS):
    """A JSBSim FDM of the exported ``airframe`` under ``root``, on the comparison planet."""
    fdm = quiet_fdm(root)
    fdm.set_dt(dt)  # before loading: JSBSim computes its filter coefficients with the dt at load time
    planet = write_planet(root / f"planet_{airframe.name}.xml", start_height, planet_radius)
    if not fdm.load_model(airframe.name):
        raise RuntimeError(f"JSBSim could not load the exported aircraft {airframe.name!r} from {root}")
    if not fdm.load_planet(str(planet), False):
        raise RuntimeError(f"JSBSim could not load the planet file {planet}")
    fdm["simulation/gravity-model"] = 0
    return fdm


def initialise_jsbsim(fdm, airframe: Airframe, initial: torch.Tensor, command: np.ndarray,
                      ground_effect: bool) -> None:
    """Set JSBSim's initial conditions, actuator trims and command from our state [S]."""
    x = initial.reshape(-1).to(torch.float64)
    phi, theta, psi = quaternion_to_euler(x[S.QUATERNION].reshape(1, 4))[0].tolist()
    fdm["ic/terrain-elevation-ft"] = 0.0
    fdm["ic/lat-geod-rad"] = 0.0
    fdm["ic/long-gc-rad"] = 0.0
    fdm["ic/h-agl-ft"] = float(S.height(x)) / FT
    for name, value in (("phi", phi), ("theta", theta), ("psi-true", psi)):
        fdm[f"ic/{name}-rad"] = value
    for name, value in zip(("u", "v", "w"), x[S.VELOCITY].tolist(), strict=True):
        fdm[f"ic/{name}-fps"] = value / FT
    for name, value in zip(("p", "q", "r"), x[S.ANGULAR_RATE].tolist(), strict=True):
        fdm[f"ic/{name}-rad_sec"] = value
    for name, value in zip(SURFACE_NAMES, x[S.SURFACE_POSITION].tolist(), strict=True):
        fdm[f"fcs/falcon/{name}-trim"] = value
    for m, value in enumerate(S.StateLayout(airframe.num_motors).field(x, "throttle").tolist()):
        fdm[f"fcs/falcon/throttle-{m}-trim"] = value
    fdm[GE_SWITCH] = 1.0 if ground_effect else 0.0
    set_command(fdm, command)
    if not fdm.run_ic():
        raise RuntimeError("JSBSim run_ic failed")


def set_command(fdm, command: np.ndarray) -> None:
    """Normalised command [4] (elevator, aileron, rudder, throttle) in [-1, 1]."""
    for prop, value in zip((*SURFACE_CMD, THROTTLE_CMD), command, strict=True):
        fdm[prop] = float(value)


def jsbsim_row(fdm) -> dict[str, float]:
    """The channels (SI) of JSBSim's current state."""
    radius_m = fdm["position/radius-to-vehicle-ft"] * FT
    return {"altitude": fdm["position/h-agl-ft"] * FT, "pitch_rate": fdm["velocities/q-rad_sec"],
            "airspeed": fdm["velocities/vt-fps"] * FT, "alpha": fdm["aero/alpha-rad"],
            "beta": fdm["aero/beta-rad"], "theta": fdm["attitude/theta-rad"], "phi": fdm["attitude/phi-rad"],
            "psi": fdm["attitude/psi-rad"], "roll_rate": fdm["velocities/p-rad_sec"],
            "yaw_rate": fdm["velocities/r-rad_sec"], "u": fdm["velocities/u-fps"] * FT,
            "v": fdm["velocities/v-fps"] * FT, "w": fdm["velocities/w-fps"] * FT,
            "north": radius_m * fdm["position/lat-geod-rad"], "east": radius_m * fdm["position/long-gc-rad"]}


def fly_jsbsim(root: Path, airframe: Airframe, initial: torch.Tensor, commands: np.ndarray,
               ground_effect: bool, dt: float = 0.01, planet_radius: float = PLANET_RADIUS) -> Trajectory:
    """The aircraft exported under ``root`` from our state ``initial`` [S] under ``commands`` [K, 4]
    (command k held over [t_k, t_k+1]; see the module doc for the frame alignment)."""
    fdm = make_fdm(root, airframe, -float(initial.reshape(-1)[2]), dt, planet_radius)
    initialise_jsbsim(fdm, airframe, initial, commands[0], ground_effect)
    rows = [jsbsim_row(fdm)]
    for k in range(len(commands)):
        set_command(fdm, commands[min(k + 1, len(commands) - 1)])
        fdm.run()
        rows.append(jsbsim_row(fdm))
    return Trajectory(np.arange(len(rows)) * dt, {c: np.array([r[c] for r in rows]) for c in CHANNELS})
