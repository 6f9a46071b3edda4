"""Controllers by name for the evaluation harness: a factory takes the env, returns a policy.

The baselines that apply to a task are the ones its ``TaskSpec.controllers`` lists: "lqr" and "mppi"
(the classical baselines, where they apply) and "trim" (holds the trim commands, a floor every
controller must beat; every task has it). "ppo", "sac" and "td3" are the shipped policies of that
algorithm, task and airframe (``policy_seed`` picks the training seed, 0 by default); any other string
is the path of a saved policy of the task (or of a task it derives from, e.g. an
altitude policy on climb_descend, which keeps the altitude MDP).
"""

from __future__ import annotations

import copy
from pathlib import Path

from tensordict import TensorDictBase
from tensordict.nn import TensorDictModuleBase

from ..envs import FixedWingEnv
from ..envs.tasks import TASK_SPECS, TaskSpec, task_spec
from ..policies import ALGORITHMS, load_policy, shipped_policy

CONTROLLERS = ("lqr", "mppi", "trim", "ppo")


class TrimHold(TensorDictModuleBase):
    """Action = the env's ``trim_action()`` [A], the task's trim command in its action channels (open
    loop)."""

    def __init__(self, env: FixedWingEnv):
        super().__init__()
        self.in_keys = ["observation"]
        self.out_keys = ["action"]
        self.action = env.trim_action()

    def forward(self, td: TensorDictBase) -> TensorDictBase:
        td.set("action", self.action.expand(*td.batch_size, -1).clone())
        return td


def baseline_names() -> set[str]:
    """Names of the baselines of every registered task (and the shipped ones: lqr, mppi, trim)."""
    return {"lqr", "mppi", "trim"}.union(*(spec.controllers for spec in TASK_SPECS.values()))


def make_controller(name: str, env: FixedWingEnv, policy_seed: int = 0) -> TensorDictModuleBase:
    """Build controller ``name`` for ``env``'s task: one of its spec's baselines, "ppo", "sac" or "td3" (the
    shipped policy of that algorithm, task and airframe trained with ``policy_seed``) or a policy file.
    A baseline that does not apply, or a policy of another task, is a one-line ValueError."""
    spec = task_spec(env.config.task)
    if name in spec.controllers or name in baseline_names():
        return spec.controller(name)(env)  # ValueError naming the task's controllers if not among them
    path = Path(name)
    if name in ALGORITHMS:  # the shipped policy (package data) of this task and airframe
        path = shipped_policy(spec.name, env.config.airframe, name, policy_seed)
    if not path.is_file():
        raise ValueError(f"controller {name!r} is neither one of task {spec.name!r}'s controllers "
                         f"{sorted(spec.controllers)} nor a policy file")
    policy = load_policy(path, env)
    _check_policy_task(path, getattr(policy, "meta", {}).get("task"), spec)
    return policy


#: Designed LQRs by (task, airframe, control step, ground-effect mode, device, dtype): a design trims
#: and linearises a grid of points (seconds), and depends on nothing else of the env.
_LQR_DESIGNS: dict[tuple, TensorDictModuleBase] = {}


def reused_controller(name: str, env: FixedWingEnv) -> TensorDictModuleBase:
    """:func:`make_controller`, with an LQR designed once per (task, airframe, control step, ground-effect
    mode, device, dtype) and handed out as a fresh copy (no integrator state crosses envs): for sweeps
    that build many envs of one airframe (the robustness grid, the ground-effect bands)."""
    if name != "lqr":
        return make_controller(name, env)
    key = (env.config.task, env.sim.airframe.name, env.control_dt, str(env.config.ground_effect),
           str(env.device), env.sim.dtype)
    if key not in _LQR_DESIGNS:
        _LQR_DESIGNS[key] = make_controller(name, env)
    return copy.deepcopy(_LQR_DESIGNS[key])


def _check_policy_task(path: Path, trained_on: str | None, spec: TaskSpec) -> None:
    """A policy flies its own task or one derived from it (a subclass keeps its parent's MDP)."""
    if trained_on is None or trained_on == spec.name:
        return
    parent = TASK_SPECS.get(trained_on)
    if parent is None or not issubclass(spec.task, parent.task):
        raise ValueError(f"{path}: a policy of task {trained_on!r} does not fly task {spec.name!r}")


__all__ = ["CONTROLLERS", "TrimHold", "baseline_names", "make_controller", "reused_controller"]
