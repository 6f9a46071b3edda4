"""Cross-validation runs: falcon-rl against its JSBSim export from identical trimmed states.

Each case starts from our trimmed level flight at cruise speed at height h0 and flies either with
the trim command held ("trim", zero-input free flight) or with an elevator doublet on top of it
("doublet"). Ground-effect settings (falcon-rl, JSBSim):

- ``off``:  (off, off), the like-for-like comparison of the two simulators.
- ``on``:   (on, off), the reference paper's comparison: JSBSim aircraft do not carry our
  ground-effect correction, so near the ground the runs diverge systematically.
- ``both``: (on, on), the export's own Phillips-Hunsaker functions switched on: the divergence of
  ``on`` disappears, which pins it on the ground-effect terms alone.

Zero-input free flight from an exact trim keeps every channel almost constant, so Pearson r there
correlates residual drifts (or rounding noise) and is not a meaningful score; RMSE is. The doublet
excites the short period and the phugoid and is the case in which r measures agreement.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from tqdm.auto import tqdm

from ..airframe import Airframe
from ..physics.dynamics import evaluate
from ..physics.params import build_params
from ..physics.trim import trim_level
from .jsbsim_export import export_aircraft
from .jsbsim_fly import CHANNELS, PLANET_RADIUS, Trajectory, fly_falcon, fly_jsbsim

#: Ground-effect settings: name -> (falcon-rl on, JSBSim export on). An imported airframe's comparison
#: (``jsbsim_model_compare``) is "both": falcon-rl reads JSBSim's own ground-effect tables.
GE_SETTINGS: dict[str, tuple[bool, bool]] = {"off": (False, False), "on": (True, False), "both": (True, True)}
EXCITATIONS: tuple[str, ...] = ("trim", "doublet")
#: The channels of the reference paper's table.
HEADLINE: tuple[str, ...] = ("altitude", "pitch_rate", "airspeed")
#: Below this standard deviation (SI units) a channel is taken as constant and r is undefined.
MIN_STD = 1e-9


@dataclass(frozen=True)
class Doublet:
    """Elevator doublet added to the trim command: -amplitude (nose up) for ``width`` s from
    ``start`` s, then +amplitude for ``width`` s; amplitude in normalised command units."""

    amplitude: float = 0.05
    start: float = 1.0
    width: float = 0.5

    def commands(self, trim_command: np.ndarray, steps: int, dt: float) -> np.ndarray:
        """Commands [steps, 4]; command k is held over [k dt, (k + 1) dt]."""
        out = np.tile(np.asarray(trim_command, dtype=np.float64), (steps, 1))
        t = np.arange(steps) * dt + 1e-9
        out[(t >= self.start) & (t < self.start + self.width), 0] -= self.amplitude
        out[(t >= self.start + self.width) & (t < self.start + 2 * self.width), 0] += self.amplitude
        return np.clip(out, -1.0, 1.0)


@dataclass(frozen=True)
class Case:
    height: float  # m, initial CG height
    ground_effect: str  # key of GE_SETTINGS
    excitation: str  # "trim" or "doublet"


@dataclass
class CaseResult:
    """Both trajectories of one case and their agreement per channel."""

    airframe: str
    case: Case
    falcon: Trajectory
    jsbsim: Trajectory
    metrics: dict[str, dict[str, float | None]]  # channel -> {"r", "rmse"}
    kappa: tuple[float, float] = (1.0, 1.0)  # Phillips-Hunsaker (kappa_L, kappa_D) at the start
    #: Agreement of the excitation's response: each simulator's run minus its own zero-input flight from
    #: the same trim (removes what a trim's residual accelerations add to both runs); None when not flown.
    response: dict[str, dict[str, float | None]] | None = None

    @property
    def min_altitude(self) -> float:
        return float(min(self.falcon.channels["altitude"].min(), self.jsbsim.channels["altitude"].min()))

    def row(self) -> dict[str, Any]:
        """One JSON row: condition, ground-contact flag and each channel's r and RMSE."""
        falcon_ge, jsbsim_ge = GE_SETTINGS[self.case.ground_effect]
        return {"airframe": self.airframe, "height_m": self.case.height,
                "ground_effect": self.case.ground_effect, "falcon_ground_effect": falcon_ge,
                "jsbsim_ground_effect": jsbsim_ge, "excitation": self.case.excitation,
                "duration_s": float(self.falcon.time[-1]), "min_altitude_m": self.min_altitude,
                "below_ground": self.min_altitude <= 0.0, "kappa_lift_0": self.kappa[0],
                "kappa_drag_0": self.kappa[1],
                "channels": {k: {"unit": CHANNELS[k], **v} for k, v in self.metrics.items()},
                **({} if self.response is None else
                   {"response_channels": {k: {"unit": CHANNELS[k], **v} for k, v in self.response.items()}})}


def channel_metrics(a: Trajectory, b: Trajectory) -> dict[str, dict[str, float | None]]:
    """Pearson r (None for a constant channel) and RMSE of b against a, per channel; headings
    are compared as wrapped differences."""
    out: dict[str, dict[str, float | None]] = {}
    for name in CHANNELS:
        x, y = a.channels[name], b.channels[name]
        diff = y - x
        if name == "psi":
            diff = np.angle(np.exp(1j * diff))
            y = x + diff
        rmse = float(np.sqrt(np.mean(diff**2)))
        r = None if min(x.std(), y.std()) < MIN_STD else float(np.corrcoef(x, y)[0, 1])
        out[name] = {"r": r, "rmse": rmse}
    return out


def _initial_states(airframe: Airframe, cases: list[Case]) -> tuple[torch.Tensor, torch.Tensor]:
    """Trimmed states [N, S] and trim commands [N, 4] at cruise for each case's height and
    falcon-rl ground-effect setting."""
    states, commands = [], []
    cache: dict[tuple[float, bool], tuple[torch.Tensor, torch.Tensor]] = {}
    for case in cases:
        ge = GE_SETTINGS[case.ground_effect][0]
        key = (case.height, ge)
        if key not in cache:
            trim = trim_level(airframe, airframe.envelope.cruise_speed, case.height,
                              ground_effect="induced" if ge else "off")
            cache[key] = (trim.state[0], trim.commands[0])
        states.append(cache[key][0])
        commands.append(cache[key][1])
    return torch.stack(states), torch.stack(commands)


def initial_kappas(airframe: Airframe, initial: torch.Tensor) -> torch.Tensor:
    """Phillips-Hunsaker (kappa_L, kappa_D) [N, 2] at states [N, S], ground effect on."""
    ev = evaluate(initial, build_params(airframe, initial.shape[0], dtype=torch.float64, ground_effect=True))
    return torch.stack([ev.kappa_lift, ev.kappa_drag], dim=-1)


def validate_jsbsim(airframe: Airframe, workdir: str | Path, heights: tuple[float, ...] = (1.0, 10.0, 100.0),
                    ground_effect: tuple[str, ...] = ("off", "on", "both"),
                    excitations: tuple[str, ...] = EXCITATIONS, duration: float = 10.0, dt: float = 0.01,
                    doublet: Doublet | None = None, planet_radius: float = PLANET_RADIUS,
                    progress: bool = False) -> list[CaseResult]:
    """Export ``airframe`` under ``workdir`` and fly every (height, ground effect, excitation)
    case in both simulators for ``duration`` s; returns one :class:`CaseResult` per case."""
    bad = [g for g in ground_effect if g not in GE_SETTINGS]
    bad += [e for e in excitations if e not in EXCITATIONS]
    if bad:
        raise ValueError(f"unknown ground-effect setting or excitation {bad}; expected "
                         f"{list(GE_SETTINGS)} and {list(EXCITATIONS)}")
    if not duration > 0 or not dt > 0:
        raise ValueError(f"duration and dt must be > 0, got {duration}, {dt}")
    doublet = doublet or Doublet()
    root = Path(workdir)
    export_aircraft(airframe, root)
    cases = [Case(float(h), g, e) for h in heights for g in ground_effect for e in excitations]
    initial, trim_commands = _initial_states(airframe, cases)
    steps = round(duration / dt)
    commands = np.stack([
        doublet.commands(c.numpy(), steps, dt) if case.excitation == "doublet"
        else np.tile(c.numpy(), (steps, 1)) for case, c in zip(cases, trim_commands, strict=True)
    ], axis=1)  # [K, N, 4]
    falcon = fly_falcon(airframe, initial, commands, [GE_SETTINGS[c.ground_effect][0] for c in cases], dt,
                        progress)
    kappas = initial_kappas(airframe, initial).tolist()
    results = []
    for i, case in enumerate(tqdm(cases, desc=f"JSBSim {airframe.name}", unit="run", disable=not progress,
                                  leave=False)):
        jsb = fly_jsbsim(root, airframe, initial[i], commands[:, i], GE_SETTINGS[case.ground_effect][1], dt,
                         planet_radius)
        results.append(CaseResult(airframe.name, case, falcon[i], jsb, channel_metrics(falcon[i], jsb),
                                  (kappas[i][0], kappas[i][1])))
    return results
