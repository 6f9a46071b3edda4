"""The robustness study of the attitude executor: one disturbance family at a time, over the grid.

Each cell of the grid is a (family, level) pair of :mod:`falcon_rl.transforms.presets`, in physical
units:

    family          unit            nominal  mild   medium  severe
    sensors         x noise floor   0        1      2.5     5      (SENSOR_FLOORS: GPS, attitude, gyro, pitot)
    obs_delay       ms              0        20     50      80
    action_delay    ms              0        20     60      100
    turbulence      sigma_u / V_a   0        0.05   0.10    0.15   (Dryden, at the trim airspeed and height)

Every cell flies the same attitude-task episodes: the paper's maneuver streams (``episodes`` envs per
maneuver, the whole stream or its first ``seconds``) or random command streams ("random"), at the
protocols' 10 ms control step, with the same seed, so the nominal cell is the same for every family
(it is flown once and shared).

The controller sees what the disturbance leaves of the flight: a controller that reads the state
("state", ...) (the LQR, MPPI) reads the state the sensors report, ("measured", ...), whenever a
transform publishes it (:class:`MeasuredView`); a learned policy reads "observation", which the
transforms recompute from the measured state and delay. Every metric is computed from the true
state: survival (no crash or stall termination in the first episode of an env), and bank,
climb-rate and airspeed RMSE pooled over the alive steps of every episode of the cell (the steps of
each env's first episode, its terminating step included), so a cell where nothing survives still has
an RMSE (of the flight up to the departure).

    result = robustness_grid("volantex_ranger", "ppo", episodes=1)
    for row in result.to_rows():
        print(row)
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field

import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModuleBase
from tqdm import tqdm

from ..defaults import DEFAULT_BACKEND
from ..envs import FixedWingEnv, make_env
from ..envs.layout import flat_scalars
from ..envs.maneuvers import MANEUVERS
from ..transforms.presets import (
    ACTION_DELAY_MS,
    GRID,
    OBS_DELAY_MS,
    SENSOR_SCALE,
    SEVERE_TURBULENCE_RATIO,
    TURBULENCE_RATIO,
)
from .controllers import reused_controller
from .metrics import first_episode_mask, survival
from .protocols import PROTOCOL_DECIMATION
from .rollout_storage import StepRecord

ControllerFactory = Callable[[FixedWingEnv], TensorDictModuleBase]

#: The disturbance families of the grid, one at a time.
FAMILIES: tuple[str, ...] = ("sensors", "obs_delay", "action_delay", "turbulence")
#: The unit each family's severity is given in.
UNITS: dict[str, str] = {"sensors": "x noise floor", "obs_delay": "ms", "action_delay": "ms",
                         "turbulence": "sigma_u/V_a"}
#: The command streams a cell can fly: the paper's maneuvers and the random training streams.
STREAMS: tuple[str, ...] = (*MANEUVERS, "random")
#: Episode length (s) of the random command stream when ``seconds`` is None.
RANDOM_STREAM_SECONDS = 30.0


def severity(family: str, level: str) -> float:
    """The physical size of ``level`` in ``family``: the noise-floor multiple (sensors), the delay in ms
    (obs_delay, action_delay) or sigma_u / V_a (turbulence); 0 at "nominal"."""
    if family not in FAMILIES:
        raise ValueError(f"unknown disturbance family {family!r}; choose from {FAMILIES}")
    if level not in GRID:
        raise ValueError(f"unknown severity level {level!r}; choose from {GRID}")
    if level == "nominal":
        return 0.0
    if family == "sensors":
        return float(SENSOR_SCALE[level])
    if family == "obs_delay":
        return float(OBS_DELAY_MS[level])
    if family == "action_delay":
        return float(ACTION_DELAY_MS[level])
    return float(SEVERE_TURBULENCE_RATIO if level == "severe" else TURBULENCE_RATIO[level])


def disturbance_options(family: str, level: str) -> dict[str, object]:
    """The ``make_env`` options of one cell: {} at "nominal", else the family's option in physical
    units (sensors by preset name, delays in ms, turbulence as the float sigma_u / V_a)."""
    value = severity(family, level)
    if level == "nominal":
        return {}
    if family == "sensors":
        return {"sensors": level}
    if family == "obs_delay":
        return {"obs_delay_ms": value}
    if family == "action_delay":
        return {"action_delay_ms": value}
    return {"turbulence": value}


class MeasuredView(TensorDictModuleBase):
    """Runs a policy that reads ("state", ...) on ("measured", ...) when the env publishes it (a sensor
    or observation-delay transform); on the true state otherwise. Writes only "action"."""

    def __init__(self, policy: TensorDictModuleBase):
        super().__init__()
        self.policy = policy
        self.in_keys = [("measured", *k[1:]) if isinstance(k, tuple) and k[0] == "state" else k
                        for k in policy.in_keys]
        self.out_keys = ["action"]

    def forward(self, td: TensorDictBase) -> TensorDictBase:
        measured = td.get("measured", None)
        view = td.clone(False)
        if measured is not None:
            view.set("state", measured)
        td.set("action", self.policy(view).get("action"))
        return td


def reads_state(policy: TensorDictModuleBase) -> bool:
    """Whether ``policy`` reads the state (an in-key under "state"), as the LQR and MPPI do, rather
    than the observation vector of a learned policy."""
    keys = getattr(policy, "in_keys", None) or []
    return any(isinstance(k, tuple) and len(k) > 1 and k[0] == "state" for k in keys)


@dataclass(frozen=True)
class RobustnessCell:
    """One (family, level) cell: the severity in physical units and metrics from the true state.

    ``seen_bank_rmse_deg`` is the bank RMSE of the state the sensors report (("measured", ...) when a
    transform publishes it, else the truth), over the same steps: what the controller believed."""

    family: str
    level: str
    severity: float  # in ``unit``
    unit: str
    survival: float  # fraction of episodes with no crash / stall termination
    bank_rmse_deg: float  # deg, pooled over alive steps, true state
    climb_rate_rmse_mps: float  # m/s, pooled over alive steps, true state
    airspeed_rmse_mps: float  # m/s, pooled over alive steps, true state
    episodes: int  # episodes flown in the cell (all streams)
    seen_bank_rmse_deg: float  # deg, pooled over alive steps, the state the controller was shown
    alive_steps: int  # control steps the RMSEs average over


@dataclass
class RobustnessResult:
    """The grid of one controller on one airframe: ``cells[(family, level)]``."""

    airframe: str
    controller: str
    cells: dict[tuple[str, str], RobustnessCell]
    settings: dict[str, object] = field(default_factory=dict)

    def cell(self, family: str, level: str) -> RobustnessCell:
        """The cell of (``family``, ``level``); ValueError when the grid did not fly it."""
        if (family, level) not in self.cells:
            raise ValueError(f"no cell ({family!r}, {level!r}) in this grid; cells: {sorted(self.cells)}")
        return self.cells[(family, level)]

    def to_rows(self) -> list[dict[str, object]]:
        """One flat dict per cell (airframe, controller, then the cell's fields), family-major in the
        order flown: rows for a table or a CSV."""
        return [{"airframe": self.airframe, "controller": self.controller, **asdict(c)}
                for c in self.cells.values()]

    def as_nested(self, metrics: Sequence[str] = ("survival", "bank_rmse_deg")
                  ) -> dict[str, dict[str, dict[str, float]]]:
        """{family: {level: {metric: value}}} for ``metrics`` (RobustnessCell field names)."""
        out: dict[str, dict[str, dict[str, float]]] = {}
        for (family, level), c in self.cells.items():
            out.setdefault(family, {})[level] = {m: getattr(c, m) for m in metrics}
        return out


def _sums(rollout: TensorDictBase) -> dict[str, float]:
    """Sums over the alive steps of an attitude-task rollout [N, T]: squared errors (rad^2, (m/s)^2),
    alive steps, episodes and surviving episodes."""
    nxt = flat_scalars(rollout["next"])
    alive = first_episode_mask(nxt["done"])
    command = nxt["task", "bank_command"]
    errors = {
        "bank": nxt["state", "euler"][..., 0] - command,
        "climb_rate": -nxt["state", "velocity_ned"][..., 2] - nxt["task", "climb_rate_command"],
        "airspeed": nxt["state", "airspeed"] - nxt["task", "airspeed_command"],
    }
    measured = nxt.get("measured", None)
    errors["seen_bank"] = errors["bank"] if measured is None else measured["euler"][..., 0] - command
    out = {name: float(torch.where(alive, e.double() ** 2, 0.0).sum()) for name, e in errors.items()}
    out["alive_steps"] = float(alive.sum())
    out["episodes"] = float(alive.shape[0])
    out["survived"] = float(survival(nxt["terminated"], alive).sum())
    return out


def _scores(sums: dict[str, float]) -> dict[str, float | int]:
    """Cell metrics from summed :func:`_sums` (RMSEs NaN without alive steps)."""
    count = sums["alive_steps"]

    def rmse(name: str) -> float:
        return math.sqrt(sums[name] / count) if count > 0 else math.nan

    return {
        "survival": sums["survived"] / sums["episodes"],
        "bank_rmse_deg": math.degrees(rmse("bank")),
        "climb_rate_rmse_mps": rmse("climb_rate"),
        "airspeed_rmse_mps": rmse("airspeed"),
        "episodes": int(sums["episodes"]),
        "seen_bank_rmse_deg": math.degrees(rmse("seen_bank")),
        "alive_steps": int(count),
    }


def score_rollouts(rollouts: Sequence[TensorDictBase]) -> dict[str, float | int]:
    """Cell metrics of attitude-task rollouts [N, T] (their "next" entries; streams of any lengths):
    survival (fraction of episodes), bank RMSE (deg), climb-rate and airspeed RMSE (m/s) from the true
    ("state", ...), pooled over the alive steps of every episode; the bank RMSE of ("measured", ...)
    where published (else of the truth), "seen_bank_rmse_deg"; episodes and alive steps."""
    if not rollouts:
        raise ValueError("score_rollouts needs at least one rollout")
    parts = [_sums(r) for r in rollouts]
    return _scores({k: sum(p[k] for p in parts) for k in parts[0]})


def _fly(env: FixedWingEnv, policy: TensorDictModuleBase, steps: int) -> TensorDictBase:
    """Roll ``steps`` env steps without resets: the rollout [N, T] of each step's "next" entries (what
    :func:`score_rollouts` reads)."""
    record = StepRecord(steps)
    td = env.reset()
    with torch.no_grad():
        for t in range(steps):
            td = env.step(policy(td))
            record.record(t, td.select("next"))
            td = env.step_mdp(td)
    return record.rollout()


def run_cell(airframe: str, factory: ControllerFactory, family: str, level: str,
             maneuvers: Sequence[str] = MANEUVERS, episodes: int = 1, seconds: float | None = None,
             seed: int = 0, backend: str = DEFAULT_BACKEND, device: str = "cpu",
             keep_rollouts: bool = False) -> tuple[RobustnessCell, list[TensorDictBase]]:
    """Fly one (family, level) cell: ``episodes`` envs on each stream of ``maneuvers`` (the whole
    stream, or its first ``seconds`` s; "random": ``seconds`` s, default ``RANDOM_STREAM_SECONDS``),
    at the 10 ms control step with ``seed``. Returns the cell and, with ``keep_rollouts``, the
    rollouts [episodes, T] of each stream (their "next" entries; else an empty list)."""
    options = disturbance_options(family, level)
    rollouts = []
    for stream in maneuvers:
        stream_options: dict[str, object] = {"maneuver": stream}
        if stream == "random":
            stream_options["episode_seconds"] = RANDOM_STREAM_SECONDS if seconds is None else seconds
        env = make_env("attitude", airframe, num_envs=episodes, backend=backend, device=device, seed=seed,
                       decimation=PROTOCOL_DECIMATION, **stream_options, **options)
        policy = factory(env)
        actor = MeasuredView(policy) if reads_state(policy) else policy
        steps = env.max_episode_steps
        if seconds is not None:
            steps = max(1, min(steps, round(seconds / env.control_dt)))
        rollouts.append(_fly(env, actor, steps))
    scores = score_rollouts(rollouts)
    cell = RobustnessCell(family=family, level=level, severity=severity(family, level), unit=UNITS[family],
                          **scores)
    return cell, rollouts if keep_rollouts else []


def robustness_grid(airframe: str, controller: str, factory: ControllerFactory | None = None,
                    families: Sequence[str] = FAMILIES, levels: Sequence[str] = GRID, episodes: int = 1,
                    seconds: float | None = None, maneuvers: Sequence[str] = MANEUVERS, seed: int = 0,
                    backend: str = DEFAULT_BACKEND, device: str = "cpu", progress: bool = True
                    ) -> RobustnessResult:
    """Fly ``controller`` on ``airframe``'s attitude task through the robustness grid: one cell per
    (family, level) of ``families`` x ``levels`` (see the module docstring for the units).

    ``factory(env) -> policy`` builds the controller for each cell's env (default:
    ``reused_controller(controller, env)``: "lqr" (designed once), "mppi", "trim", "ppo" (shipped) or a
    policy file). ``maneuvers``: the command streams each cell flies, ``episodes`` envs each (the
    paper: the four maneuvers, one episode each); "random" flies random command streams. ``seconds``:
    the first ``seconds`` s of each stream (None: the whole maneuver; 30 s of a random stream). Every
    cell uses ``seed``, so the nominal cell (flown once) is the one of every family. A progress bar
    counts the cells (``progress=False`` hides it). Torch's thread count is the caller's: the CLI and the
    sweep set one thread, the fastest for these small batches (on a busy 2-core CPU a script left at two
    threads flew a paper-scale grid about 4x slower)."""
    families, levels, maneuvers = tuple(families), tuple(levels), tuple(maneuvers)
    if not families or not levels or not maneuvers:
        raise ValueError("families, levels and maneuvers must each name at least one entry")
    for family in families:
        if family not in FAMILIES:
            raise ValueError(f"unknown disturbance family {family!r}; choose from {FAMILIES}")
    for level in levels:
        if level not in GRID:
            raise ValueError(f"unknown severity level {level!r}; choose from {GRID}")
    for stream in maneuvers:
        if stream not in STREAMS:
            raise ValueError(f"unknown command stream {stream!r}; choose from {STREAMS}")
    if isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < 1:
        raise ValueError(f"episodes must be a positive integer (per stream), got {episodes!r}")
    number = isinstance(seconds, int | float) and not isinstance(seconds, bool)
    if seconds is not None and not (number and math.isfinite(seconds) and seconds > 0):
        raise ValueError(f"seconds must be a positive number of seconds or None, got {seconds!r}")
    if factory is None:
        def factory(env: FixedWingEnv) -> TensorDictModuleBase:
            return reused_controller(controller, env)

    todo = [(f, lv) for f in families for lv in levels]
    cells: dict[tuple[str, str], RobustnessCell] = {}
    nominal: RobustnessCell | None = None
    bar = tqdm(todo, desc=f"robustness {controller} {airframe}", unit="cell", disable=not progress)
    for family, level in bar:
        bar.set_postfix_str(f"{family} {level}")
        if level == "nominal" and nominal is not None:  # the same env and seed in every family
            cells[(family, level)] = RobustnessCell(**{**asdict(nominal), "family": family,
                                                       "unit": UNITS[family]})
            continue
        cell, _ = run_cell(airframe, factory, family, level, maneuvers, episodes, seconds, seed, backend,
                           device)
        cells[(family, level)] = cell
        if level == "nominal":
            nominal = cell
    settings = {"families": list(families), "levels": list(levels), "maneuvers": list(maneuvers),
                "episodes": episodes, "seconds": seconds, "seed": seed, "backend": backend, "device": device,
                "decimation": PROTOCOL_DECIMATION}
    return RobustnessResult(airframe, controller, cells, settings)


__all__ = ["FAMILIES", "STREAMS", "UNITS", "MeasuredView", "RobustnessCell", "RobustnessResult",
           "disturbance_options", "reads_state", "robustness_grid", "run_cell", "score_rollouts", "severity"]
