"""What SAC and TD3 share: the twin-Q critic, the replay buffer and the collect-and-store loop.

Each recipe keeps its own loss and update step; this module holds the parts that are the same idea
in both, so that a change to collection or storage is made once.
"""

from __future__ import annotations

from collections.abc import Iterator

from tensordict import TensorDictBase
from tensordict.nn import TensorDictModuleBase
from torchrl.data import LazyTensorStorage, ReplayBuffer
from torchrl.envs import TransformedEnv
from torchrl.modules import ValueOperator

from .common import TRANSITION, OffPolicyConfig, QNet, RunningNorm, observation_dims
from .runner import TrainingRun


def make_critic(cfg: OffPolicyConfig, env: TransformedEnv, norm: RunningNorm) -> ValueOperator:
    """Q(observation, action) -> "state_action_value" on the actor's observation normaliser; the
    losses clone it into their twin critics."""
    obs_dim, act_dim = observation_dims(env)
    qnet = QNet(norm, obs_dim, act_dim, cfg.critic_cells, cfg.critic_activation).to(cfg.device)
    return ValueOperator(qnet, in_keys=["observation", "action"], out_keys=["state_action_value"])


def make_replay_buffer(cfg: OffPolicyConfig) -> ReplayBuffer:
    """Replay buffer with storage on ``cfg.device`` (saved in checkpoints by :class:`TrainingRun`)."""
    return ReplayBuffer(storage=LazyTensorStorage(cfg.buffer_size, device=cfg.device),
                        batch_size=cfg.batch_size)


def stored_batches(cfg: OffPolicyConfig, policy: TensorDictModuleBase, run: TrainingRun,
                   buffer: ReplayBuffer, norm: RunningNorm) -> Iterator[tuple[TensorDictBase, bool]]:
    """Collect the remaining frames in batches of [num_envs, rollout_steps] (``run.batches``: uniform
    random actions for the run's first ``init_random_frames``); yield each batch after scaling its
    reward, storing its transitions and updating the normaliser, with a flag that says whether the
    buffer holds enough to learn from (``init_random_frames`` transitions, at least a minibatch; a
    resumed run has its buffer back, so it decides as the uninterrupted run would)."""
    learn_after = max(cfg.batch_size, min(cfg.init_random_frames, cfg.buffer_size))
    for batch in run.batches(policy, cfg.num_envs * cfg.rollout_steps, cfg.init_random_frames):
        batch["next", "reward"] = batch["next", "reward"] * cfg.reward_scale
        buffer.extend(batch.select(*TRANSITION).reshape(-1))
        norm.update(batch["observation"])
        yield batch, len(buffer) >= learn_after


__all__ = ["make_critic", "make_replay_buffer", "stored_batches"]
