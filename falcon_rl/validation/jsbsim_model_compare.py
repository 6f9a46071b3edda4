"""Cross-validation of an imported airframe against the JSBSim aircraft it was imported from.

Each case is a level-flight condition (airspeed, height above flat ground) and an excitation:
"trim" (zero-input free flight), "elevator" or "aileron" (a doublet of the surface). Both simulators
start from their *own* level trim at that condition (same airspeed, height, attitude level; each
model's trim deflections and throttle), so neither starts out of balance.

Driving by physical deflection. JSBSim's flight controls map normalised commands to deflections with
asymmetric gains (e.g. the c172p's elevator -28/+23 deg), so the doublet is a normalised JSBSim command
added to its trim command, and JSBSim's resulting surface positions (``fcs/*-pos-rad``, read after each
frame: the positions that drive the next interval) are recorded. falcon-rl then flies with ideal
actuators on its trim deflections plus the same increments, so both see the same physical deflection
history. falcon-rl: torch backend, float64, RK4, ground effect "tables" (JSBSim's own kCLge/kCDge).

Response. JSBSim's trim stops within its tolerance (about 1e-3 ft/s^2 of residual acceleration), so
its zero-input flight drifts: the pa28 trimmed at 45 m/s climbs 1.7 cm and slows by 2.7 mm/s in 20 s,
where falcon-rl's exact trim holds. When the "trim" case is flown, each doublet case also reports the
agreement of the *response*, each simulator's doublet run minus its own free flight.

Planet: JSBSim flies over the comparison sphere of ``jsbsim_fly`` (no rotation, gravity g0 at the start
height), the CG height above terrain at sea level equal to falcon-rl's.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import torch

from ..airframe import Airframe
from ..physics import state as S
from ..physics.actuators import normalised_command
from ..physics.simulator import Simulator
from ..physics.trim import trim_level
from .jsbsim_compare import Case, CaseResult, channel_metrics
from .jsbsim_engine import RUNNING, START_S, crank, quiet_fdm
from .jsbsim_fly import CHANNELS, PLANET_RADIUS, Trajectory, falcon_channels, jsbsim_row, write_planet
from .jsbsim_import import SURFACE_OUTPUTS

EXCITATIONS: tuple[str, ...] = ("trim", "elevator", "aileron")
#: Normalised JSBSim command of each surface's doublet channel.
DOUBLET_COMMANDS = {"elevator": "fcs/elevator-cmd-norm", "aileron": "fcs/aileron-cmd-norm"}
#: The channels the issue's targets are set on: name -> target Pearson r.
TARGETS: dict[str, float] = {"altitude": 0.999, "airspeed": 0.999, "pitch_rate": 0.999, "roll_rate": 0.99,
                             "phi": 0.99}
SURFACES = ("elevator", "aileron", "rudder")
#: JSBSim's integrators, switched off (the state held) while an engine is cranked before the trim.
FROZEN = tuple(f"simulation/integrator/{name}" for name in ("rate/rotational", "rate/translational",
                                                             "position/rotational", "position/translational"))


@dataclass(frozen=True)
class ModelDoublet:
    """A doublet of normalised JSBSim command: +amplitude for ``width`` s from ``start`` s, then
    -amplitude for ``width`` s (elevator +: trailing edge down, nose down; aileron +: right roll)."""

    amplitude: float = 0.1
    start: float = 1.0
    width: float = 0.5

    def offset(self, t: np.ndarray) -> np.ndarray:
        """Command offset [K] at times t [K] s."""
        first = (t >= self.start) & (t < self.start + self.width)
        second = (t >= self.start + self.width) & (t < self.start + 2 * self.width)
        return self.amplitude * (first.astype(float) - second.astype(float))


def jsbsim_trimmed(root: Path, model: str, airspeed: float, height: float, dt: float, workdir: Path):
    """JSBSim's ``model`` trimmed level at (airspeed m/s, CG height m) on the comparison sphere."""
    fdm = quiet_fdm(root)
    fdm.set_dt(dt)
    if not fdm.load_model(model):
        raise RuntimeError(f"JSBSim could not load {model!r}")
    planet = write_planet(workdir / f"planet_{model}_{height:g}.xml", height, PLANET_RADIUS)
    if not fdm.load_planet(str(planet), False):
        raise RuntimeError(f"JSBSim could not load the planet file {planet}")
    fdm["simulation/gravity-model"] = 0
    for name, value in (("terrain-elevation-ft", 0.0), ("lat-geod-rad", 0.0), ("long-gc-rad", 0.0),
                        ("h-agl-ft", height / 0.3048), ("vt-fps", airspeed / 0.3048), ("gamma-deg", 0.0),
                        ("psi-true-rad", 0.0)):
        fdm[f"ic/{name}"] = value
    fdm.run_ic()
    fdm["propulsion/set-running"] = -1
    fdm["fcs/mixture-cmd-norm"] = 1.0
    fdm["propulsion/magneto_cmd"] = 3
    if not fdm[RUNNING]:  # JSBSim's set-running leaves some engines stopped at low airspeed (the c182's)
        frozen = {name: fdm[name] for name in FROZEN}
        for name in FROZEN:
            fdm[name] = 0
        fdm["fcs/throttle-cmd-norm"] = 0.5
        crank(fdm, round(START_S / dt))
        for name, value in frozen.items():
            fdm[name] = value
    fdm["simulation/do_simple_trim"] = 1
    return fdm


def fly_model(fdm, excitation: str, doublet: ModelDoublet, steps: int, dt: float
              ) -> tuple[Trajectory, np.ndarray]:
    """Fly the trimmed ``fdm`` ``steps`` frames; (trajectory, deflections [steps, 3] rad that drive each
    interval: elevator, left aileron, rudder)."""
    base = {name: fdm[name] for name in DOUBLET_COMMANDS.values()}
    offsets = doublet.offset(np.arange(1, steps + 1) * dt + 1e-9)
    rows, positions = [jsbsim_row(fdm)], [[fdm[SURFACE_OUTPUTS[s]] for s in SURFACES]]
    for k in range(steps):
        if excitation in DOUBLET_COMMANDS:
            prop = DOUBLET_COMMANDS[excitation]
            fdm[prop] = float(np.clip(base[prop] + offsets[k], -1.0, 1.0))
        fdm.run()
        rows.append(jsbsim_row(fdm))
        positions.append([fdm[SURFACE_OUTPUTS[s]] for s in SURFACES])
    trajectory = Trajectory(np.arange(steps + 1) * dt, {c: np.array([r[c] for r in rows]) for c in CHANNELS})
    return trajectory, np.asarray(positions[:-1])


def fly_imported(airframe: Airframe, airspeed: float, height: float, increments: np.ndarray, dt: float
                 ) -> Trajectory:
    """falcon-rl (torch, float64, ground effect "tables", ideal actuators) from its own level trim with
    zero sideslip (JSBSim's full trim: a propeller's p-factor leaves a small bank), the surfaces at trim +
    ``increments`` [K, 3] rad over each interval."""
    trim = trim_level(airframe, airspeed, height, ground_effect="tables", lateral="zero_sideslip")
    sim = Simulator(airframe, num_envs=1, dtype=torch.float64, ground_effect="tables", dt=dt,
                    model={"actuators": "ideal"})
    x0 = trim.state.to(torch.float64)
    sim.reset(x0)
    surfaces = x0[:, S.SURFACE_POSITION] + torch.as_tensor(increments, dtype=torch.float64)
    throttle = trim.commands[0, 3].to(torch.float64) * 0.5 + 0.5
    commands = normalised_command(surfaces, throttle.expand(len(increments)), sim.params)
    history = [sim.x.clone()]
    for u in commands:
        sim.step(u.unsqueeze(0))
        history.append(sim.x.clone())
    states = torch.stack(history)[:, 0]
    return Trajectory(np.arange(states.shape[0]) * dt, falcon_channels(states))


def validate_model(airframe: Airframe, model: str, workdir: str | Path, airspeeds: tuple[float, ...],
                   heights: tuple[float, ...], excitations: tuple[str, ...] = EXCITATIONS,
                   duration: float = 20.0, dt: float = 0.01, doublet: ModelDoublet | None = None,
                   root: Path | None = None) -> tuple[list[CaseResult], list[str]]:
    """Fly every (airspeed, height, excitation) case in JSBSim's ``model`` (under the JSBSim ``root``,
    default the package's) and in ``airframe``; (results, skipped conditions with the reason)."""
    import jsbsim

    from ..physics.trim import TrimError

    bad = [e for e in excitations if e not in EXCITATIONS]
    if bad:
        raise ValueError(f"unknown excitation {bad}; expected {list(EXCITATIONS)}")
    root, work = Path(root or jsbsim.get_default_root_dir()), Path(workdir)
    work.mkdir(parents=True, exist_ok=True)
    doublet = doublet or ModelDoublet()
    steps = round(duration / dt)
    results, skipped = [], []
    for v in airspeeds:
        for h in heights:
            flown: dict[str, CaseResult] = {}
            for excitation in excitations:
                try:
                    fdm = jsbsim_trimmed(root, model, v, h, dt, work)
                    jsb, positions = fly_model(fdm, excitation, doublet, steps, dt)
                    ours = fly_imported(airframe, v, h, positions - positions[0], dt)
                except (RuntimeError, TrimError) as exc:  # JSBSim's trim raises RuntimeError
                    skipped.append(f"{v:g} m/s, {h:g} m, {excitation}: {str(exc).strip()}")
                    continue
                case = Case(h, "both", f"{excitation} {v:g} m/s")
                flown[excitation] = CaseResult(airframe.name, case, ours, jsb, channel_metrics(ours, jsb))
            free = flown.get("trim")
            for excitation, result in flown.items():
                if free is not None and excitation != "trim":
                    result = replace(result, response=channel_metrics(
                        response(result.falcon, free.falcon), response(result.jsbsim, free.jsbsim)))
                results.append(result)
    return results, skipped


def response(run: Trajectory, free: Trajectory) -> Trajectory:
    """``run`` minus the zero-input flight ``free`` from the same trim, channel by channel."""
    return Trajectory(run.time, {name: run.channels[name] - free.channels[name] for name in run.channels})
