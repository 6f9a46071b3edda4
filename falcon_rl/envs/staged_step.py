"""The env step as stages, for engines without a one-call step (``Engine.fuse`` returns None), envs
built with ``fused=False`` and torch tasks: the twin of ``physics.fused_env_step.FusedEnvStep``, with
the same call and the same outputs, so that ``FixedWingEnv`` steps every backend and task through one
path.

Stages, in the order the fused kernel runs them:

1. the action contract (``transforms.action_check.check_action``): refused unless an [N, A] real float
   tensor; a row with a NaN flies the centre command and is flagged; the rest is clamped to [-1, 1];
2. the task's command and the engine's ``step`` (the physics sub-steps and the crash state);
3. the task's step (``Task.step``): its Warp step, or a torch task's ``torch_step`` on the simulator's
   state;
4. the non-finite guard: a row whose state (integrated and derived), observation or reward left the
   finite numbers, or whose action had a NaN, ends with reason "non_finite", its non-finite outputs
   zeroed;
5. the episode step count and truncation at the horizon (not when terminated).
"""

from __future__ import annotations

from typing import Any

import torch
from tensordict import TensorDictBase

from ..transforms.action_check import check_action


class StagedEnvStep:
    """One env step as the stages of the module docstring. A call returns (observation [N, D], reward
    [N], reason [N] long, truncated [N] bool, non_finite [N] bool), new tensors each call; :attr:`state`
    is the simulator state after the step (a TensorDict), or None where the task's Warp step read the
    simulator's buffers and no state was asked for."""

    #: Its outputs are new tensors each call (no copy needed to keep them).
    reuses_buffers = False

    def __init__(self, env: Any):
        """``env``: the ``FixedWingEnv`` it steps (its config, simulator, task, step counter, horizon and
        ``non_finite_reason``; the names ``physics.fused_env_step.SteppedEnv`` lists)."""
        self.env = env
        #: The state of the last call (see the class docstring).
        self.state: TensorDictBase | None = None

    def __call__(self, action: object, with_state: bool = True) -> tuple[torch.Tensor, ...]:
        env = self.env
        task, sim, n = env.task, env.sim, env.config.num_envs
        action, nan_action = check_action(action, n, task.action_dim, sim.dtype, env.device)
        sim.step(task.command(action), substeps=env.config.decimation)
        if task.has_warp_step():
            observation, reward, reason = task.step(action)
            observation, reward = observation.to(sim.dtype), reward.to(sim.dtype)
            state = sim.state if with_state and not env.config.lean else None
            finite = (finite_step_rows(state, observation, reward) if state is not None
                      else self._finite_buffers(observation, reward))
        else:
            state = sim.state
            observation, reward, reason = task.torch_step(state, action)
            finite = finite_step_rows(state, observation, reward)
        self.state = state
        env.step_count += 1
        truncated = env.step_count >= env.max_episode_steps
        non_finite = nan_action | ~finite
        reason = torch.where(non_finite, env.non_finite_reason, reason)
        observation = observation.masked_fill(non_finite[:, None] & ~torch.isfinite(observation), 0.0)
        reward = reward.masked_fill(non_finite & ~torch.isfinite(reward), 0.0)
        return observation, reward, reason, truncated & (reason == 0), non_finite

    def torchrl_outputs(self, action: object) -> dict[str, torch.Tensor]:
        """A lean TorchRL step's outputs for ``action``: ``observation`` [N, D], ``reward`` [N, 1],
        ``termination_reason`` [N, 1] long, ``terminated``, ``truncated``, ``done`` [N, 1] bool."""
        observation, reward, reason, truncated, _ = self(action, with_state=False)
        terminated = (reason > 0).unsqueeze(-1)
        truncated = truncated.unsqueeze(-1) & ~terminated
        return {"observation": observation, "termination_reason": reason.unsqueeze(-1),
                "terminated": terminated, "truncated": truncated, "done": terminated | truncated,
                "reward": reward.unsqueeze(-1)}

    def _finite_buffers(self, observation: torch.Tensor, reward: torch.Tensor) -> torch.Tensor:
        """[N] bool: the simulator's integrated state, gusts and clock, the observation [N, D] and the
        reward [N] are finite (the check without a state TensorDict)."""
        sim, n = self.env.sim, self.env.config.num_envs
        parts = [sim.x, sim.gust_velocity_body, sim.gust_rate_body, sim.time.reshape(n, 1), observation,
                 reward.reshape(n, 1).to(observation.dtype)]
        return finite_rows(torch.cat(parts, -1))

    def __getstate__(self) -> dict[str, Any]:
        return {"env": self.env, "state": None}


def finite_rows(values: torch.Tensor) -> torch.Tensor:
    """[N] bool: every number of the row of ``values`` [N, K] (floats) is finite. Computed as
    ``sum(v - v) == 0``: v - v is exactly 0 for a finite v and NaN for a NaN or an infinity, and a NaN
    makes the sum NaN (no overflow can occur); on the CPU ~10x faster than ``isfinite(v).all(-1)``."""
    return (values - values).sum(-1) == 0


def finite_step_rows(state: TensorDictBase, observation: torch.Tensor, reward: torch.Tensor) -> torch.Tensor:
    """[N] bool: every float of the row's state (integrated and derived), observation and reward is
    finite."""
    n = reward.shape[0]
    floats = [value.reshape(n, -1) for value in state.values() if value.is_floating_point()]
    return finite_rows(torch.cat([*floats, observation.reshape(n, -1), reward.reshape(n, 1)], -1))


__all__ = ["StagedEnvStep", "finite_rows", "finite_step_rows"]
