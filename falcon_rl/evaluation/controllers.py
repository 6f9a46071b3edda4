"""Controllers by name for the evaluation harness: a factory takes the env, returns a policy.

"lqr" and "mppi" are the classical baselines, "trim" holds the trim commands (a floor every
controller must beat), "ppo" the shipped PPO policy of the task and airframe; any other string is a
path to a saved policy.
"""

from __future__ import annotations

from pathlib import Path

from tensordict import TensorDictBase
from tensordict.nn import TensorDictModuleBase

from ..envs import FixedWingEnv

CONTROLLERS = ("lqr", "mppi", "trim", "ppo")


class TrimHold(TensorDictModuleBase):
    """Action = the task's trim command in its action channels (open loop)."""

    def __init__(self, env: FixedWingEnv):
        super().__init__()
        self.in_keys = ["observation"]
        self.out_keys = ["action"]
        task = env.task
        self.action = task.trim.command[list(task.action_channels)].clone()

    def forward(self, td: TensorDictBase) -> TensorDictBase:
        td.set("action", self.action.expand(*td.batch_size, -1).clone())
        return td


def make_controller(name: str, env: FixedWingEnv) -> TensorDictModuleBase:
    """Build controller ``name`` (or load a saved policy from a path) for ``env``'s task."""
    task = env.config.task
    if name == "trim":
        return TrimHold(env)
    if name == "lqr":
        from ..baselines.lqr import AltitudeLQR, AttitudeLQR

        if task == "altitude":
            return AltitudeLQR(env.sim.airframe, env.env_dt, env.config.ground_effect, env.device,
                               env.sim.dtype)
        if task == "attitude":
            return AttitudeLQR(env.sim.airframe, env.env_dt, env.device, env.sim.dtype)
        raise ValueError(f"the LQR baseline serves the altitude and attitude tasks, not {task!r}")
    if name == "mppi":
        from ..baselines.mppi import make_mppi

        return make_mppi(env)
    path = Path(name)
    if name == "ppo":  # the shipped policy (package data) of this task and airframe
        from ..policies import shipped_policy
        path = shipped_policy(task, env.config.airframe)
    if not path.is_file():
        raise ValueError(f"controller must be one of {list(CONTROLLERS)} or a policy file; {name!r} is "
                         "neither")
    from ..recipes.export import load_policy

    return load_policy(path, env)


__all__ = ["CONTROLLERS", "TrimHold", "make_controller"]
