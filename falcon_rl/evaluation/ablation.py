"""Ablation study: a controller's score with each physical phenomenon simplified in turn.

For one task, airframe and controller, the task's protocol (its ``TaskSpec``) is flown on the full
model and then once per arm of :data:`ABLATIONS`, each the full model with one phenomenon switched
to its simplified form (``physics.switches.ModelSwitches``, or ground effect off). The controller is
built on each arm's env as usual (an LQR is still designed on the full model's trims: the ablation
asks how much of its error each phenomenon causes). Every arm uses the same seed, so the episodes
(targets, starts, maneuvers) are the same draws.

The headline of a task is its first metric with a unit (altitude: RMSE in m; attitude: bank RMSE in
deg, averaged over the maneuvers); the change per arm is headline(arm) - headline(full).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

from tqdm import tqdm

from ..defaults import DEFAULT_BACKEND
from ..envs import FixedWingEnv, task_spec
from .protocols import ProtocolResult

#: (label, env options) of each arm: one phenomenon simplified, the rest the full model.
ABLATIONS: tuple[tuple[str, dict[str, object]], ...] = (
    ("ideal actuators", {"model": {"actuators": "ideal"}}),
    ("no throttle lag", {"model": {"throttle_lag": False}}),
    ("constant density", {"model": {"atmosphere": "constant"}}),
    ("no rate damping", {"model": {"rate_damping": False}}),
    ("no propeller torque", {"model": {"propeller_torque": False}}),
    ("no ground effect", {"ground_effect": False}),
)
FULL = "full model"


@dataclass
class AblationResult:
    """One task x airframe x controller: the headline metric per arm (full model first)."""

    task: str
    airframe: str
    controller: str
    headline: str  # metric key, e.g. "rmse_m"
    unit: str
    values: dict[str, float] = field(default_factory=dict)  # arm label -> headline value
    survival: dict[str, float] = field(default_factory=dict)  # arm label -> survival
    results: dict[str, ProtocolResult] = field(default_factory=dict)

    def change(self, arm: str) -> float:
        """headline(arm) - headline(full model)."""
        return self.values[arm] - self.values[FULL]


def headline_metric(task: str) -> tuple[str, str]:
    """(key, unit) of the task's first metric that has a unit."""
    for metric in task_spec(task).metrics:
        if metric.unit:
            return metric.key, metric.unit
    raise ValueError(f"task {task!r} has no metric with a unit to ablate")


def _mean_over_cases(summary: dict[str, float], key: str) -> float:
    """summary[key], or the mean of "<case>/<key>" entries (the attitude maneuvers)."""
    if key in summary:
        return float(summary[key])
    values = [v for k, v in summary.items() if k.endswith("/" + key) and math.isfinite(v)]
    return sum(values) / len(values) if values else math.nan


def run_ablation(task: str, airframe: str, controller: str,
                 factory: Callable[[FixedWingEnv], object], episodes: int = 20, seed: int = 0,
                 backend: str = DEFAULT_BACKEND, device: str = "cpu", episode_seconds: float | None = None,
                 arms: tuple[tuple[str, dict[str, object]], ...] = ABLATIONS) -> AblationResult:
    """Fly the task's protocol (episodes of ``episode_seconds``, None: the protocol's own) on the full
    model and on each arm; see the module docstring."""
    spec = task_spec(task)
    protocol = spec.protocol_function()
    key, unit = headline_metric(task)
    out = AblationResult(task, airframe, controller, key, unit)
    for label, options in tqdm(((FULL, {}), *arms), desc=f"ablation {controller} {task} {airframe}",
                               unit="arm", leave=False):
        result = protocol(airframe, controller, factory, episodes=episodes, seed=seed, backend=backend,
                          device=device, episode_seconds=episode_seconds, **options)
        out.results[label] = result
        out.values[label] = _mean_over_cases(result.summary, key)
        out.survival[label] = _mean_over_cases(result.summary, "survival")
    return out


def ablation_markdown(results: list[AblationResult]) -> str:
    """One table per task: rows = arms, columns = controllers (headline value and change; "-" where
    no episode survived to be scored)."""
    lines: list[str] = []
    for task in dict.fromkeys(r.task for r in results):
        rows = [r for r in results if r.task == task]
        first = rows[0]
        lines += [f"### {task_spec(task).title} ({first.airframe}): {first.headline}", "",
                  "| arm | " + " | ".join(f"{r.controller} ({r.unit}) | change | survival"
                                         for r in rows) + " |",
                  "|---|" + "---:|---:|---:|" * len(rows)]
        for arm in first.values:
            cells = []
            for r in rows:
                if not math.isfinite(r.values[arm]):  # no episode survived to be scored
                    cells.append(f"- | - | {r.survival[arm]:.2f}")
                    continue
                change = "" if arm == FULL else f"{r.change(arm):+.3f}"
                cells.append(f"{r.values[arm]:.3f} | {change} | {r.survival[arm]:.2f}")
            lines.append(f"| {arm} | " + " | ".join(cells) + " |")
        lines.append("")
    return "\n".join(lines)


def ablation_document(results: list[AblationResult]) -> list[dict[str, object]]:
    """JSON-ready rows: task, airframe, controller, headline, unit, values, changes, survival."""
    return [{"task": r.task, "airframe": r.airframe, "controller": r.controller, "headline": r.headline,
             "unit": r.unit, "values": r.values, "survival": r.survival,
             "changes": {arm: r.change(arm) for arm in r.values if arm != FULL}} for r in results]


__all__ = ["ABLATIONS", "FULL", "AblationResult", "ablation_document", "ablation_markdown",
           "headline_metric", "run_ablation"]
