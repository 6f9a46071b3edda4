"""The paper's four studies as experiment cells: which cells a study has at a scale, and the function
that runs one cell.

    altitude        altitude acquisition and hold (the altitude protocol), every controller
    maneuvers       the attitude task's four maneuvers (the attitude protocol), every controller
    ground-effect   the policy column: thrust change and settled error while a controller holds each
                    h/b band with the ground-effect correction on and off
    robustness      the attitude executor under sensor noise, sensor delay, action delay, turbulence
    sea-state       (falcon-rl's own) sea skimming at 0.25 b over sea states 0-5
    landing         (falcon-rl's own) the landing protocol from the same starts with ground effect on and off

Scales (:data:`SCALES`): ``quick`` (a smoke run of about a quarter of an hour on a 2-core CPU: shipped
policies, one seed, small episode counts, maneuvers cut to 20 s, the robustness grid on the circle
only) and ``paper`` (the paper's sizes: 200 altitude episodes for learned rows, 50 for LQR and MPPI,
3 training seeds, 5 MPPI draws, 25 episodes per maneuver, whole streams).

Learned controllers (ppo, sac, td3) fly, for training seed k, the shipped policy of (task, airframe,
algorithm) when k = 0 and one ships, else ``<policies>/<algorithm>_<task>_<airframe>_seed<k>/policy.pt``
when it exists (``<policies>``: the cell's ``policies`` location, :func:`policy_folder`), else, with
``train`` on, the one the recipe trains there (checkpointed, resumable); a
cell with none of these is reported as "no policy" and its table entry stays empty. LQR runs once per
cell, MPPI once per draw (the draw offsets its sampler's seed).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..defaults import DEFAULT_BACKEND
from ..envs.maneuvers import MANEUVERS
from .cells import Cell, register_cell_function
from .study_layouts import SEA_STATES

STUDIES: tuple[str, ...] = ("altitude", "maneuvers", "ground-effect", "robustness", "sea-state", "landing")
LEARNED: tuple[str, ...] = ("ppo", "sac", "td3")
#: Every controller a study can score.
CONTROLLERS: tuple[str, ...] = (*LEARNED, "lqr", "mppi", "tecs-flare")
#: The task each study flies.
STUDY_TASK: dict[str, str] = {"altitude": "altitude", "maneuvers": "attitude", "ground-effect": "altitude",
                              "robustness": "attitude", "sea-state": "sea_skimming", "landing": "landing"}
#: Controllers each study scores by default.
STUDY_CONTROLLERS: dict[str, tuple[str, ...]] = {
    "altitude": ("ppo", "sac", "td3", "lqr", "mppi"), "maneuvers": ("ppo", "sac", "td3", "lqr", "mppi"),
    "ground-effect": ("ppo", "lqr"), "robustness": ("ppo", "lqr"), "sea-state": ("ppo", "lqr", "mppi"),
    "landing": ("tecs-flare",)}
#: The paper's two reference airframes.
AIRFRAMES: tuple[str, ...] = ("airship_v7", "volantex_ranger")


@dataclass(frozen=True)
class Scale:
    """Sizes of one scale of the sweep."""

    learned_episodes: int  # altitude episodes of a learned row
    baseline_episodes: int  # altitude episodes of LQR
    mppi_episodes: int  # altitude episodes of one MPPI draw
    seeds: tuple[int, ...]  # training seeds of the learned rows
    mppi_draws: int
    maneuver_episodes: int  # per maneuver
    maneuver_seconds: float | None  # each maneuver cut to this (None: the whole stream)
    mppi_maneuver_episodes: int
    ge_episodes: int  # per h/b band and correction
    ge_seconds: float  # episode length of the ground-effect study (the last third is the settled window)
    robustness_episodes: int  # per grid cell and maneuver
    robustness_seconds: float  # each maneuver cut to this
    robustness_maneuvers: tuple[str, ...]  # the maneuvers every robustness cell flies
    sea_episodes: int = 8  # per sea state
    sea_mppi_episodes: int = 4  # per sea state, of one MPPI draw
    sea_seconds: float = 20.0  # episode length of the sea-state study
    sea_states: tuple[int, ...] = SEA_STATES  # the WMO codes the sea-state study flies
    landing_episodes: int = 20  # per ground-effect arm of the landing study


SCALES: dict[str, Scale] = {
    "quick": Scale(learned_episodes=20, baseline_episodes=10, mppi_episodes=2, seeds=(0,), mppi_draws=1,
                   maneuver_episodes=2, maneuver_seconds=20.0, mppi_maneuver_episodes=1, ge_episodes=2,
                   ge_seconds=15.0, robustness_episodes=4, robustness_seconds=10.0,
                   robustness_maneuvers=("circle",)),
    "paper": Scale(learned_episodes=200, baseline_episodes=50, mppi_episodes=50, seeds=(0, 1, 2),
                   mppi_draws=5, maneuver_episodes=25, maneuver_seconds=None, mppi_maneuver_episodes=5,
                   ge_episodes=10, ge_seconds=30.0, robustness_episodes=32, robustness_seconds=30.0,
                   robustness_maneuvers=MANEUVERS, sea_episodes=50, sea_mppi_episodes=20,
                   sea_seconds=30.0, landing_episodes=100),
}


def study_cells(study: str, airframes: tuple[str, ...], controllers: tuple[str, ...], scale: Scale,
                options: dict[str, Any], locations: dict[str, str] | None = None) -> list[Cell]:
    """The cells of ``study`` for every airframe and controller at ``scale``; ``options`` (backend,
    train) go into every cell's params, ``locations`` (``policies``: the folder of trained policies)
    into its locations."""
    if study not in STUDIES:
        raise ValueError(f"unknown study {study!r}; choose from {STUDIES}")
    cells = []
    for airframe in airframes:
        for controller in controllers:
            seeds = scale.seeds if controller in LEARNED else (0,)
            draws = range(scale.mppi_draws) if controller == "mppi" else range(1)
            for seed in seeds:
                for draw in draws:
                    params = {**options, **_study_params(study, controller, scale)}
                    if controller in LEARNED:  # a new or retrained policy file makes a new cell
                        params["policy"] = policy_identity(Cell.make(study, STUDY_TASK[study], airframe,
                                                                     controller, seed, draw, params,
                                                                     locations))
                    cells.append(Cell.make(study, STUDY_TASK[study], airframe, controller, seed, draw,
                                           params, locations))
    return cells


def _study_params(study: str, controller: str, scale: Scale) -> dict[str, Any]:
    """Episode counts and lengths of one cell."""
    if study == "altitude":
        episodes = {"mppi": scale.mppi_episodes}.get(
            controller, scale.learned_episodes if controller in LEARNED else scale.baseline_episodes)
        return {"episodes": episodes}
    if study == "maneuvers":
        episodes = scale.mppi_maneuver_episodes if controller == "mppi" else scale.maneuver_episodes
        return {"episodes": episodes, "episode_seconds": scale.maneuver_seconds}
    if study == "ground-effect":
        return {"episodes": scale.ge_episodes, "episode_seconds": scale.ge_seconds}
    if study == "sea-state":
        episodes = scale.sea_mppi_episodes if controller == "mppi" else scale.sea_episodes
        return {"episodes": episodes, "episode_seconds": scale.sea_seconds,
                "sea_states": scale.sea_states}
    if study == "landing":
        return {"episodes": scale.landing_episodes}
    return {"episodes": scale.robustness_episodes, "episode_seconds": scale.robustness_seconds,
            "maneuvers": scale.robustness_maneuvers}


# ---------------------------------------------------------------------------------------- controllers
class NoPolicyError(LookupError):
    """A learned cell has no policy to fly (none shipped, none trained, training off)."""


def policy_source(cell: Cell) -> str:
    """What ``make_controller`` flies for ``cell``: a baseline's name or a policy file (see the module
    docstring); NoPolicyError when a learned cell has none."""
    if cell.controller not in LEARNED:
        return cell.controller
    from ..policies import shipped_policy

    try:
        return str(shipped_policy(cell.task, cell.airframe, cell.controller, cell.seed))
    except ValueError:
        pass
    folder = policy_folder(cell)
    if (folder / "policy.pt").is_file():
        return str(folder / "policy.pt")
    if not cell.param_dict.get("train", False):
        raise NoPolicyError(f"no {cell.controller} policy for {cell.task} on {cell.airframe} (seed "
                            f"{cell.seed}): none ships; train one with --train")
    return _train(cell, folder)


def policy_folder(cell: Cell) -> Path:
    """Where a learned cell's policy is trained: ``<policies>/<algorithm>_<task>_<airframe>_seed<k>``
    (``<policies>``: the cell's ``policies`` location, default runs/experiment/policies)."""
    policies = dict(cell.locations).get("policies", "runs/experiment/policies")
    return Path(policies) / f"{cell.controller}_{cell.task}_{cell.airframe}_seed{cell.seed}"


def policy_identity(cell: Cell) -> str:
    """The first 16 hex digits of the sha256 of the policy file ``cell`` would fly now, "none" when
    there is none yet (part of a learned cell's key, so a new policy reruns its cells alone)."""
    import hashlib

    try:
        path = Path(policy_source(replace_train(cell, False)))
    except NoPolicyError:
        return "none"
    return hashlib.sha256(path.read_bytes()).hexdigest()[:16]


def replace_train(cell: Cell, train: bool) -> Cell:
    """``cell`` with its ``train`` param set to ``train``."""
    return Cell.make(cell.study, cell.task, cell.airframe, cell.controller, cell.seed, cell.draw,
                     {**cell.param_dict, "train": train}, cell.locations)


def _train(cell: Cell, folder: Path) -> str:
    """Train the cell's learned policy with its recipe into ``folder`` (resumable); its policy file."""
    from ..recipes import algorithm

    module = algorithm(cell.controller)
    config = module.make_config(cell.task, airframe=cell.airframe, seed=cell.seed,
                                backend=cell.param_dict.get("backend", DEFAULT_BACKEND), out=str(folder),
                                final_eval_episodes=0, resume="auto")
    return str(module.train(config)["policy"])


def factory(cell: Cell, source: str) -> Any:
    """The controller factory ``env -> policy`` of ``cell``; MPPI's sampler seeded per draw."""
    import torch

    from ..evaluation.controllers import reused_controller

    def build(env: Any) -> Any:
        policy = reused_controller(source, env)
        if cell.controller == "mppi" and isinstance(getattr(policy, "generator", None), torch.Generator):
            policy.generator.manual_seed(1000 * cell.draw + cell.seed)
        return policy
    return build


# ---------------------------------------------------------------------------------------- cell functions
def _no_policy(error: NoPolicyError) -> dict[str, Any]:
    return {"summary": {}, "status": f"no policy: {error}"}


#: Figure traces are kept at this many samples per second (the protocols step at 100 Hz).
TRACE_HZ = 10.0
#: Altitude episodes whose traces are kept for the figure.
SHOWN_EPISODES = 10


def _every(trace: Any) -> int:
    """Stride that samples a [.., T] trace of the 10 ms protocol step at :data:`TRACE_HZ`."""
    time = trace["state", "time"][0]
    dt = float(time[1] - time[0]) if time.numel() > 1 else 0.01
    return max(1, round(1.0 / (TRACE_HZ * dt)))


def _protocol_document(result: Any, traces: dict[str, Any]) -> dict[str, Any]:
    """A ProtocolResult as a cell result (summary, settings, per-episode metrics) plus ``traces``."""
    return {"summary": result.summary, "settings": result.settings, "episodes": result.episodes,
            "seconds_per_control_step": result.seconds_per_control_step, "traces": traces}


def altitude_traces(result: Any) -> dict[str, Any]:
    """The altitude figure's data at TRACE_HZ: time [T'], height, reference and target of the first
    episodes [k, T'] and the 5/50/95 % quantiles of h - h* over all episodes [3, T']."""
    import torch

    trace = result.traces["altitude"]["next"]
    every = _every(trace)
    height, target = trace["state", "height"][:, ::every], trace["task", "target_altitude"][:, ::every]
    quantiles = torch.quantile(height - target, torch.tensor([0.05, 0.5, 0.95], dtype=height.dtype), dim=0)
    return {"time": trace["state", "time"][0, ::every], "height": height[:SHOWN_EPISODES],
            "reference": trace["task", "reference_altitude"][:SHOWN_EPISODES, ::every],
            "target": target[:SHOWN_EPISODES], "error_quantiles": quantiles}


def maneuver_traces(result: Any) -> dict[str, Any]:
    """Per maneuver, episode 0 at TRACE_HZ: time, bank and bank command (rad) [T'], position_ned
    [T', 3] and quaternion [T', 4] (the track renders)."""
    out = {}
    for name, rollout in result.traces.items():
        trace = rollout["next"]
        every = _every(trace)
        out[name] = {"time": trace["state", "time"][0, ::every],
                     "bank": trace["state", "euler"][0, ::every, 0],
                     "bank_command": trace["task", "bank_command"][0, ::every],
                     "position_ned": trace["state", "position_ned"][0, ::every],
                     "quaternion": trace["state", "quaternion"][0, ::every]}
    return out


def altitude_cell(cell: Cell) -> Any:
    """One altitude-protocol row (summary: survival, acquisition, rmse_m, ...) with the figure's traces."""
    from ..evaluation.protocols import altitude_protocol

    try:
        source = policy_source(cell)
    except NoPolicyError as error:
        return _no_policy(error)
    params = cell.param_dict
    result = altitude_protocol(cell.airframe, cell.controller.upper(), factory(cell, source),
                               episodes=int(params["episodes"]), seed=cell.seed + 1000 * cell.draw,
                               backend=params.get("backend", DEFAULT_BACKEND))
    return _protocol_document(result, altitude_traces(result))


def maneuvers_cell(cell: Cell) -> Any:
    """One attitude-protocol row over the four maneuvers (summary "<maneuver>/<metric>") with the
    figures' traces."""
    from ..evaluation.protocols import attitude_protocol

    try:
        source = policy_source(cell)
    except NoPolicyError as error:
        return _no_policy(error)
    params = cell.param_dict
    seconds = params.get("episode_seconds")
    result = attitude_protocol(cell.airframe, cell.controller.upper(), factory(cell, source),
                               episodes=int(params["episodes"]), seed=cell.seed + 1000 * cell.draw,
                               backend=params.get("backend", DEFAULT_BACKEND),
                               episode_seconds=None if seconds is None or math.isnan(seconds) else seconds)
    return _protocol_document(result, maneuver_traces(result))


def ground_effect_cell(cell: Cell) -> dict[str, Any]:
    """The policy column of one airframe and controller: per h/b band (summary "<h/b>/<metric>") the
    thrust with and without the correction (N), Delta T_pi and the trim table's Delta T and theory (%),
    the settled RMSE with the correction on (m) and whether the band was held (1/0); the rows whole."""
    from ..evaluation.ground_effect_policy import ground_effect_policy_column

    try:
        source = policy_source(cell)
    except NoPolicyError as error:
        return _no_policy(error)
    params = cell.param_dict
    seconds = float(params["episode_seconds"])
    result = ground_effect_policy_column(cell.airframe, cell.controller.upper(), factory(cell, source),
                                         episodes=int(params["episodes"]), seconds=seconds,
                                         settle_seconds=seconds / 3.0, seed=cell.seed + 1000 * cell.draw,
                                         backend=params.get("backend", DEFAULT_BACKEND))
    summary: dict[str, float] = {}
    for row in result.rows:
        band = f"{row.h_over_b:g}"
        summary.update({f"{band}/thrust_ge_n": row.thrust_ge_n, f"{band}/thrust_no_ge_n": row.thrust_no_ge_n,
                        f"{band}/delta_t_pi_pct": row.delta_percent,
                        f"{band}/delta_t_trim_pct": row.trim_delta_percent,
                        f"{band}/theory_pct": row.theory_percent, f"{band}/rmse_ge_m": row.rmse_ge_m,
                        f"{band}/held": float(row.status == "held")})
    return {"summary": summary, "settings": result.settings,
            "rows": [{k: v for k, v in row.items() if k not in ("ge", "no_ge")} for row in result.to_rows()]}


def robustness_cell(cell: Cell) -> dict[str, Any]:
    """The robustness grid of one airframe and controller over the four maneuvers (each cut to the
    cell's seconds): per (family, level) (summary "<family>/<level>/<metric>") survival, bank RMSE
    (deg), climb-rate and airspeed RMSE (m/s), all from the true state; the rows whole."""
    from ..evaluation.robustness import robustness_grid

    try:
        source = policy_source(cell)
    except NoPolicyError as error:
        return _no_policy(error)
    params = cell.param_dict
    result = robustness_grid(cell.airframe, cell.controller.upper(), factory(cell, source),
                             episodes=int(params["episodes"]), seconds=float(params["episode_seconds"]),
                             maneuvers=tuple(params["maneuvers"]), seed=cell.seed + 1000 * cell.draw,
                             backend=params.get("backend", DEFAULT_BACKEND))
    rows = result.to_rows()
    summary = {f"{row['family']}/{row['level']}/{metric}": row[metric] for row in rows
               for metric in ("survival", "bank_rmse_deg", "climb_rate_rmse_mps", "airspeed_rmse_mps")}
    return {"summary": summary, "rows": rows}


def _protocol_arms(cell: Cell, protocol: Any, arms: list[tuple[str, dict[str, Any], dict[str, Any]]]
                   ) -> dict[str, Any]:
    """One protocol flown per arm of ``cell`` (``arms``: summary prefix, the row's label fields, the arm's
    protocol options): summary "<prefix>/<metric>" and one row per arm; "no policy" when none."""
    try:
        source = policy_source(cell)
    except NoPolicyError as error:
        return _no_policy(error)
    params = cell.param_dict
    summary: dict[str, float] = {}
    rows = []
    for prefix, labels, options in arms:
        result = protocol(cell.airframe, cell.controller.upper(), factory(cell, source),
                          episodes=int(params["episodes"]), seed=cell.seed + 1000 * cell.draw,
                          backend=params.get("backend", DEFAULT_BACKEND), **options)
        summary.update({f"{prefix}/{key}": value for key, value in result.summary.items()})
        rows.append({**labels, **result.summary})
    return {"summary": summary, "rows": rows}


def sea_state_cell(cell: Cell) -> dict[str, Any]:
    """The sea-skimming protocol of one airframe and controller over each sea state of the cell (at 0.25 b):
    per code (summary "<code>/<metric>") the water-contact rate, survival, clearance RMSE (spans and m), the
    tip's closest approach (m) and the power saved against free flight; the rows whole."""
    from ..evaluation.sea_skimming import sea_skimming_protocol

    seconds = float(cell.param_dict["episode_seconds"])
    return _protocol_arms(cell, sea_skimming_protocol, [
        (str(int(code)), {"sea_state": int(code)}, {"episode_seconds": seconds, "sea_state": int(code)})
        for code in cell.param_dict["sea_states"]])


def landing_cell(cell: Cell) -> dict[str, Any]:
    """The landing protocol of one airframe and controller from the same starts with ground effect on and
    off: per arm (summary "<ge|no_ge>/<metric>") the touchdowns within the limits, the touchdown's sink
    rate, pitch, bank, lateral and longitudinal position and the float; the rows whole."""
    from ..evaluation.landing import landing_protocol

    return _protocol_arms(cell, landing_protocol, [
        (arm, {"ground_effect": ground_effect}, {"ground_effect": ground_effect})
        for arm, ground_effect in (("ge", True), ("no_ge", False))])


for _study, _name in (("altitude", "altitude_cell"), ("maneuvers", "maneuvers_cell"),
                      ("ground-effect", "ground_effect_cell"), ("robustness", "robustness_cell"),
                      ("sea-state", "sea_state_cell"), ("landing", "landing_cell")):
    register_cell_function(_study, f"{__name__}:{_name}")
