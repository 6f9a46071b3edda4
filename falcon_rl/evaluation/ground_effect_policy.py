"""Ground effect and thrust demand under a controller: the policy column (Delta T_pi) of the paper's table.

For each height-over-span band h/b a controller holds altitude at the band's height on the altitude
task, once with the ground-effect correction on and once with it off (same seed, same initial
conditions), and the mean thrust over the settled window is compared:

    Delta T_pi = (T_on - T_off) / T_off          (percent)

Heights follow the trim-only table (:mod:`.ground_effect_table`): with ``height_reference="cg"`` (the
default, the table's rows) the CG flies at h = (h/b) b and the correction, which the model evaluates
at the wing quarter chord, sees the wing's own h/b (reported as ``wing_h_over_b``); with
``height_reference="wing"`` the CG is placed so that the wing quarter chord sits at (h/b) b in the
trim attitude.

The altitude task expresses the hold without a wrapper: ``target_altitudes=(h,)`` pins the commanded
altitude and ``offset_min = offset_max = 0`` starts the episode at it, in the task's straight and
level trim at cruise (solved out of ground effect, so both arms start from the same state). The
reference is then constant, h_ref = h.

A band is held when every episode of both arms survives the horizon and the settled mean |h - h_ref|
of both arms stays within the tolerance min(``tolerance_fraction`` h, ``tolerance_m``) (defaults: a
quarter of the band's height, at most the altitude task's 1 m capture band). A band that is not held
keeps its measurements but its status says why ("crashed": an episode ended before the horizon,
"not_held": the settled error is above the tolerance, "in_ground": the CG or the wing quarter chord
would start at or below the ground, not flown) and its Delta T_pi is NaN: it is never averaged into
the column, like the paper's A0S rows.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import asdict, dataclass, field

import torch
from tensordict.nn import TensorDictModuleBase
from tqdm import tqdm

from ..airframe import load_airframe
from ..defaults import BATCH_BACKENDS, DEFAULT_BACKEND
from ..envs import FixedWingEnv, make_env
from ..envs.tasks.base import TERMINATION_REASONS
from ..physics import state as S
from ..physics.params import build_params
from ..physics.rotations import rotation_matrix
from .controllers import reused_controller
from .ground_effect_trim import H_OVER_B, ground_effect_table

ControllerFactory = Callable[[FixedWingEnv], TensorDictModuleBase]

#: The paper's h/b bands (the trim-only table's rows).
PAPER_H_OVER_B: tuple[float, ...] = H_OVER_B
#: Hold tolerance: settled mean |h - h_ref| at most this fraction of the band's height ...
HOLD_TOLERANCE_FRACTION = 0.25
#: ... and at most this many metres (the altitude task's capture band).
HOLD_TOLERANCE_M = 1.0
#: Control step of the study: the paper's 10 ms (decimation 1 of the 10 ms physics step).
STUDY_DECIMATION = 1
#: Env options the study sets itself (the pinned target and start).
PINNED_OPTIONS = ("target_altitudes", "offset_min", "offset_max", "episode_seconds", "ground_effect",
                  "target_sequence")
#: Statuses of an arm and of a band.
STATUSES = ("held", "crashed", "not_held", "in_ground")
_GE_ON_MODES = (True, "induced", "paper")
#: Ground-effect diagnostics are sampled every this many env steps in the settled window.
_DIAGNOSTIC_EVERY = 10


@dataclass
class ArmResult:
    """One arm (correction on or off) of one band: statistics over the settled window of the episodes
    that survived the horizon (NaN when none did)."""

    ground_effect: bool | str
    survival: float  # fraction of episodes that survived the horizon
    thrust_n: float  # mean total thrust, N
    thrust_std_n: float  # std of the total thrust over the window and episodes, N
    mean_abs_error_m: float  # mean |h - h_ref|, m
    rmse_m: float  # sqrt(mean (h - h_ref)^2), m
    max_abs_error_m: float  # max |h - h_ref|, m
    airspeed_mps: float  # mean airspeed, m/s
    wing_h_over_b: float  # mean wing quarter-chord height over span (the correction's argument)
    lift_factor: float  # mean kappa_L applied (1 with the correction off)
    drag_factor: float  # mean kappa_D applied (1 with the correction off)
    termination: str  # most frequent termination reason of the crashed episodes ("none" if none)
    status: str  # "held" | "crashed" | "not_held" | "in_ground" (not flown: the start touches the ground)


def _in_ground_arm(ground_effect: bool | str) -> ArmResult:
    """An arm that is not flown: at the band's height the CG or the wing is at or below the ground."""
    nan = math.nan
    return ArmResult(ground_effect, 0.0, nan, nan, nan, nan, nan, nan, nan, nan, nan, "ground_contact",
                     "in_ground")


@dataclass
class GroundEffectPolicyRow:
    """One h/b band of the policy column (flat, for tables); percentages in %, heights in m, thrust in N."""

    h_over_b: float  # the band (CG h/b with height_reference "cg", wing h/b with "wing")
    height_m: float  # CG height held, m
    wing_h_over_b: float  # measured wing quarter-chord h/b with the correction on
    tolerance_m: float  # hold tolerance on the settled mean |h - h_ref|, m
    status: str  # "held" | "in_ground" | "crashed" | "not_held" (the worse arm, in that order)
    thrust_ge_n: float
    thrust_no_ge_n: float
    delta_percent: float  # Delta T_pi, NaN unless held
    trim_delta_percent: float  # the trim-only table's Delta T at the same CG height (NaN if not asked)
    theory_percent: float  # the trim-only table's lifting-line prediction (NaN if not asked)
    mean_abs_error_ge_m: float
    mean_abs_error_no_ge_m: float
    rmse_ge_m: float
    rmse_no_ge_m: float
    survival_ge: float
    survival_no_ge: float
    status_ge: str
    status_no_ge: str
    ge: ArmResult = field(repr=False)
    no_ge: ArmResult = field(repr=False)


@dataclass
class GroundEffectPolicyResult:
    """The policy column of one airframe and controller: one row per band, and the settings."""

    airframe: str
    controller: str
    rows: list[GroundEffectPolicyRow]
    settings: dict[str, object]

    def to_rows(self) -> list[dict[str, object]]:
        """Flat dicts (one per band, the arms' details under "ge" / "no_ge"), for tables and JSON."""
        return [asdict(r) for r in self.rows]

    def held(self) -> list[GroundEffectPolicyRow]:
        """The bands the controller held (the only ones with a Delta T_pi)."""
        return [r for r in self.rows if r.status == "held"]

    def format(self) -> str:
        """Markdown table in the paper's layout with the policy column and the hold statistics."""
        lines = [f"### {self.airframe} / {self.controller}", "",
                 "| h/b | h (m) | wing h/b | T_GE (N) | T_noGE (N) | dT_pi | dT trim | Theory | "
                 "|e| on/off (m) | RMSE on/off (m) | Surv. on/off | status |",
                 "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|:--|"]
        for r in self.rows:
            delta = "---" if math.isnan(r.delta_percent) else f"{r.delta_percent:+.2f}%"
            lines.append(
                f"| {r.h_over_b:.2f} | {r.height_m:.2f} | {r.wing_h_over_b:.3f} | {r.thrust_ge_n:.4g} | "
                f"{r.thrust_no_ge_n:.4g} | {delta} | {r.trim_delta_percent:+.2f}% | "
                f"{r.theory_percent:+.2f}% | {r.mean_abs_error_ge_m:.3g}/{r.mean_abs_error_no_ge_m:.3g} | "
                f"{r.rmse_ge_m:.3g}/{r.rmse_no_ge_m:.3g} | {r.survival_ge:.2f}/{r.survival_no_ge:.2f} | "
                f"{r.status} |")
        return "\n".join(lines)


def trim_wing_offset(airframe: str) -> float:
    """R[2, :] . r_qc (m) in the task's straight and level cruise trim (solved out of ground effect):
    the wing quarter chord sits at h - offset for a CG at h (negative: a high wing)."""
    from ..physics.trim import trim_level

    af = load_airframe(airframe)
    trim = trim_level(af, float(af.envelope.cruise_speed), 100.0, ground_effect=False)
    params = build_params(af, 1, dtype=torch.float64, ground_effect=False)
    rotation = rotation_matrix(trim.state.reshape(1, -1)[:, S.QUATERNION].to(torch.float64))
    # wing_height = h - R[2, :] . r_qc  (dynamics.evaluate)
    return float((rotation[0, 2, :] * params.wing_quarter_chord[0]).sum())


def band_heights(airframe: str, bands_h_over_b: tuple[float, ...], height_reference: str = "cg"
                 ) -> list[float]:
    """CG heights (m) of the bands: (h/b) b for "cg"; for "wing" the CG height that puts the wing
    quarter chord at (h/b) b in the task's trim attitude (see :func:`trim_wing_offset`)."""
    if height_reference not in ("cg", "wing"):
        raise ValueError(f"height_reference must be 'cg' or 'wing', got {height_reference!r}")
    span = float(load_airframe(airframe).geometry.span)
    offset = trim_wing_offset(airframe) if height_reference == "wing" else 0.0
    return [r * span + offset for r in bands_h_over_b]


def _check_arguments(airframe: str, controller: str, bands: tuple[float, ...], episodes: int,
                     seconds: float, settle_seconds: float, backend: str, ground_effect: bool | str,
                     tolerance_fraction: float, tolerance_m: float, env_options: dict[str, object]) -> None:
    if not isinstance(airframe, str) or not airframe:
        raise ValueError(f"airframe must be a non-empty name, got {airframe!r}")
    if not isinstance(controller, str) or not controller:
        raise ValueError(f"controller must be a non-empty name, got {controller!r}")
    if len(bands) == 0:
        raise ValueError("bands_h_over_b must hold at least one h/b band")
    if any(not isinstance(b, (int, float)) or not math.isfinite(b) or b <= 0 for b in bands):
        raise ValueError(f"every h/b band must be a finite number > 0, got {tuple(bands)}")
    if isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < 1:
        raise ValueError(f"episodes must be an integer >= 1, got {episodes!r}")
    if not math.isfinite(seconds) or seconds <= 0:
        raise ValueError(f"seconds must be finite and > 0, got {seconds!r}")
    if not math.isfinite(settle_seconds) or not 0 <= settle_seconds < seconds:
        raise ValueError(f"settle_seconds must lie in [0, seconds={seconds}), got {settle_seconds!r}")
    if backend not in BATCH_BACKENDS:
        raise ValueError(f"backend must be one of {', '.join(BATCH_BACKENDS)}, got {backend!r}")
    if not (ground_effect is True or (isinstance(ground_effect, str) and ground_effect in _GE_ON_MODES)):
        raise ValueError(f"ground_effect (the 'on' arm) must be True, 'induced' or 'paper', "
                         f"got {ground_effect!r}")
    if not tolerance_fraction > 0 or not tolerance_m > 0:
        raise ValueError(f"tolerances must be > 0, got fraction {tolerance_fraction!r}, {tolerance_m!r} m")
    pinned = sorted(set(env_options) & set(PINNED_OPTIONS))
    if pinned:
        raise ValueError(f"env options {pinned} are set by the study itself (target, start, horizon, arm)")


def _fly_arm(airframe: str, factory: ControllerFactory, height: float, ground_effect: bool | str,
             episodes: int, seconds: float, settle_seconds: float, seed: int, backend: str, device: str,
             tolerance: float, env_options: dict[str, object]) -> ArmResult:
    """Hold ``height`` (CG, m) for ``seconds`` with ``episodes`` envs under ``factory(env)``; statistics
    over [settle_seconds, seconds] of the surviving episodes."""
    options = {"decimation": STUDY_DECIMATION, **env_options}
    env = make_env("altitude", airframe, num_envs=episodes, backend=backend, device=device, seed=seed,
                   target_altitudes=(float(height),), offset_min=0.0, offset_max=0.0, target_sequence=False,
                   episode_seconds=float(seconds), ground_effect=ground_effect, **options)
    sim = getattr(env, "base_env", env).sim
    policy = factory(env)
    steps = int(env.max_episode_steps)
    control_dt = float(getattr(env, "control_dt", seconds / steps))
    start = min(round(settle_seconds / control_dt), steps - 1)
    n = episodes
    thrust = torch.zeros(n, steps, dtype=torch.float64)
    h = torch.zeros(n, steps, dtype=torch.float64)
    airspeed = torch.zeros(n, steps, dtype=torch.float64)
    terminated = torch.zeros(n, steps, dtype=torch.bool)
    reason = torch.zeros(n, dtype=torch.long)
    diagnostics: list[torch.Tensor] = []  # [N, 3] (wing h/b, kappa_L, kappa_D) samples in the window
    td = env.reset()
    with torch.no_grad():
        for k in range(steps):
            td = policy(td)
            td = env.step(td)
            nxt = td["next"]
            thrust[:, k] = nxt["state", "thrust"].reshape(n).double().cpu()
            h[:, k] = nxt["state", "height"].reshape(n).double().cpu()
            airspeed[:, k] = nxt["state", "airspeed"].reshape(n).double().cpu()
            ended = nxt["terminated"].reshape(n).cpu()
            first = ended & ~terminated[:, :k].any(-1) if k else ended
            reason = torch.where(first, nxt["termination_reason"].reshape(n).cpu(), reason)
            terminated[:, k] = ended
            if k >= start and (k - start) % _DIAGNOSTIC_EVERY == 0:
                s = sim.state
                diagnostics.append(torch.stack([s[key].reshape(n).double().cpu() for key in
                                                ("ge_h_over_b", "ge_lift_factor", "ge_drag_factor")], -1))
            td = env.step_mdp(td)
    survived = ~terminated.any(-1)  # [N]
    survival = float(survived.double().mean())
    crashed_reasons = reason[~survived]
    termination = "none"
    if crashed_reasons.numel():
        termination = TERMINATION_REASONS[int(torch.mode(crashed_reasons).values)]
    nan = math.nan
    if not bool(survived.any()):
        return ArmResult(ground_effect, survival, nan, nan, nan, nan, nan, nan, nan, nan, nan, termination,
                         "crashed")
    window = slice(start, steps)
    error = (h[survived, window] - height)
    thrust_w = thrust[survived, window]
    diag = torch.stack(diagnostics, 1)[survived]  # [S, K, 3]
    mean_abs = float(error.abs().mean())
    status = "crashed" if survival < 1.0 else ("held" if mean_abs <= tolerance else "not_held")
    return ArmResult(
        ground_effect=ground_effect, survival=survival, thrust_n=float(thrust_w.mean()),
        thrust_std_n=float(thrust_w.std(unbiased=False)), mean_abs_error_m=mean_abs,
        rmse_m=float(error.pow(2).mean().sqrt()), max_abs_error_m=float(error.abs().max()),
        airspeed_mps=float(airspeed[survived, window].mean()), wing_h_over_b=float(diag[..., 0].mean()),
        lift_factor=float(diag[..., 1].mean()), drag_factor=float(diag[..., 2].mean()),
        termination=termination, status=status)


def ground_effect_policy_column(airframe: str, controller: str, factory: ControllerFactory | None = None,
                                bands_h_over_b: tuple[float, ...] = PAPER_H_OVER_B, episodes: int = 4,
                                seconds: float = 30.0, settle_seconds: float = 10.0, seed: int = 0,
                                backend: str = DEFAULT_BACKEND, device: str = "cpu", *,
                                ground_effect: bool | str = True, height_reference: str = "cg",
                                tolerance_fraction: float = HOLD_TOLERANCE_FRACTION,
                                tolerance_m: float = HOLD_TOLERANCE_M, compare_trim: bool = True,
                                progress: bool = True, **env_options: object) -> GroundEffectPolicyResult:
    """Thrust a controller needs to hold each h/b band with the ground-effect correction on and off.

    ``controller`` names the controller (a label; with ``factory`` None it is built by
    :func:`~.controllers.reused_controller`: "lqr" (designed once), "mppi", "trim", "ppo" or a policy file).
    ``factory(env) -> policy`` builds it for each arm's env (the arm's ground-effect mode included).
    ``episodes`` parallel envs per arm fly ``seconds`` (s) at the paper's 10 ms control step; the
    statistics use [``settle_seconds``, ``seconds``] of the episodes that survived. ``ground_effect``
    is the "on" arm's mode (True = "induced", or "paper"); the "off" arm has no correction.
    ``height_reference`` "cg" flies the CG at (h/b) b (the trim table's rows), "wing" the wing quarter
    chord. ``compare_trim`` adds the trim-only table's Delta T and theory at the same CG heights.
    ``env_options`` go to :func:`~falcon_rl.envs.make_env` (turbulence, wind, sensors, dt, ...), the
    target, start, horizon and ground-effect options excepted (the study sets them).
    """
    bands = tuple(bands_h_over_b)
    _check_arguments(airframe, controller, bands, episodes, seconds, settle_seconds, backend, ground_effect,
                     tolerance_fraction, tolerance_m, env_options)
    heights = band_heights(airframe, bands, height_reference)
    wing_offset = trim_wing_offset(airframe)
    if factory is None:
        def factory(env: FixedWingEnv) -> TensorDictModuleBase:
            return reused_controller(controller, env)
    span = float(load_airframe(airframe).geometry.span)
    airborne = [i for i, h in enumerate(heights) if h > 0.0 and h - wing_offset > 0.0]
    trim_delta, theory = [math.nan] * len(bands), [math.nan] * len(bands)
    if compare_trim and airborne:
        model = "induced" if ground_effect is True else str(ground_effect)
        ratios = tuple(heights[i] / span for i in airborne)  # CG h/b, the trim table's rows
        table = ground_effect_table(load_airframe(airframe), h_over_b=ratios, model=model)
        for i, row in zip(airborne, table, strict=True):
            trim_delta[i], theory[i] = row.delta_percent, row.theory_percent
    rows = []
    bar = tqdm(list(zip(bands, heights, strict=True)), desc=f"ground effect {controller} {airframe}",
               unit="band", disable=not progress)
    for i, (ratio, height) in enumerate(bar):
        bar.set_postfix(h_over_b=ratio)
        tolerance = min(tolerance_fraction * height, tolerance_m)
        if i not in airborne:  # the start itself touches the ground
            on, off = _in_ground_arm(ground_effect), _in_ground_arm(False)
        else:
            on, off = (_fly_arm(airframe, factory, height, mode, episodes, seconds, settle_seconds, seed,
                                backend, device, tolerance, env_options) for mode in (ground_effect, False))
        statuses = (on.status, off.status)
        status = next(s for s in ("in_ground", "crashed", "not_held", "held") if s in statuses)
        delta = 100.0 * (on.thrust_n - off.thrust_n) / off.thrust_n if status == "held" else math.nan
        rows.append(GroundEffectPolicyRow(
            h_over_b=float(ratio), height_m=float(height), wing_h_over_b=on.wing_h_over_b,
            tolerance_m=tolerance, status=status, thrust_ge_n=on.thrust_n, thrust_no_ge_n=off.thrust_n,
            delta_percent=delta,
            trim_delta_percent=trim_delta[i], theory_percent=theory[i],
            mean_abs_error_ge_m=on.mean_abs_error_m, mean_abs_error_no_ge_m=off.mean_abs_error_m,
            rmse_ge_m=on.rmse_m, rmse_no_ge_m=off.rmse_m, survival_ge=on.survival,
            survival_no_ge=off.survival,
            status_ge=on.status, status_no_ge=off.status, ge=on, no_ge=off))
    settings: dict[str, object] = {
        "bands_h_over_b": list(bands), "episodes": episodes, "seconds": seconds,
        "settle_seconds": settle_seconds, "seed": seed, "backend": backend, "device": device,
        "ground_effect": ground_effect, "height_reference": height_reference, "span_m": span,
        "tolerance_fraction": tolerance_fraction, "tolerance_m": tolerance_m,
        "decimation": env_options.get("decimation", STUDY_DECIMATION),
        "task": "altitude (target_altitudes=(h,), offset_min=offset_max=0)", **env_options}
    return GroundEffectPolicyResult(airframe, controller, rows, settings)


__all__ = ["HOLD_TOLERANCE_FRACTION", "HOLD_TOLERANCE_M", "PAPER_H_OVER_B", "STATUSES", "ArmResult",
           "GroundEffectPolicyResult", "GroundEffectPolicyRow", "band_heights", "ground_effect_policy_column"]
