"""What SAC and TD3 share: the twin-Q critic, the replay buffer and the collect-and-store loop.

Each recipe keeps its own loss and update step; this module holds the parts that are the same idea
in both, so that a change to collection or storage is made once.
"""

from __future__ import annotations

import functools
from collections.abc import Iterator

import torch
from tensordict import TensorDictBase
from tensordict.nn import TensorDictModuleBase
from torchrl.data import LazyTensorStorage, ReplayBuffer
from torchrl.data.postprocs import MultiStep
from torchrl.envs import TransformedEnv
from torchrl.modules import ValueOperator

from .common import (
    STEPS_TO_NEXT,
    OffPolicyConfig,
    QNet,
    RunningNorm,
    annealed_lr,
    observation_dims,
    transition_keys,
)
from .runner import TrainingRun


def make_critic(cfg: OffPolicyConfig, env: TransformedEnv, norm: RunningNorm) -> ValueOperator:
    """Q(observation, action) -> "state_action_value" on the actor's observation normaliser; the
    losses clone it into their twin critics."""
    obs_dim, act_dim = observation_dims(env)
    qnet = QNet(norm, obs_dim, act_dim, cfg.critic_cells, cfg.critic_activation,
                cfg.critic_layer_norm).to(cfg.device)
    return ValueOperator(qnet, in_keys=["observation", "action"], out_keys=["state_action_value"])


def make_replay_buffer(cfg: OffPolicyConfig) -> ReplayBuffer:
    """Replay buffer with storage on ``cfg.device`` (saved in checkpoints by :class:`TrainingRun`)."""
    return ReplayBuffer(storage=LazyTensorStorage(cfg.buffer_size, device=cfg.device),
                        batch_size=cfg.batch_size)


@functools.cache
def _multi_step(gamma: float, n_step: int) -> MultiStep:
    """One stateless MultiStep per (gamma, n_step), built once rather than for every batch."""
    return MultiStep(gamma=gamma, n_steps=n_step)


def n_step_transitions(batch: TensorDictBase, gamma: float, n_step: int) -> TensorDictBase:
    """Batch [B, T] of one-step transitions -> [B, T] ``n_step``-step ones (TorchRL's MultiStep): the
    reward is the discounted sum over up to ``n_step`` steps, cut at an episode's end and at the
    batch's end; ("next", "observation") is the observation after the last of them and
    :data:`STEPS_TO_NEXT` their count k (the losses' TD(0) target discounts by gamma**k). The done
    flags are those of the last summed step: MultiStep keeps the first step's, which would bootstrap
    past a crash inside the window."""
    if n_step <= 1:
        return batch
    out = _multi_step(gamma, n_step)(batch)
    last = (torch.arange(batch.shape[-1], device=batch.device) + out[STEPS_TO_NEXT] - 1)
    for key in ("done", "terminated"):
        flag = batch["next", key]
        out["next", key] = flag.gather(-2, last.unsqueeze(-1).expand_as(flag))
    return out


def anneal_learning_rates(cfg: OffPolicyConfig, optimizers: dict[str, torch.optim.Optimizer],
                          frames: int) -> None:
    """With ``cfg.anneal_lr``: set the "actor" and "critic" optimizers' learning rates for ``frames``
    trained frames (:func:`annealed_lr` of ``actor_lr`` / ``critic_lr``); a no-op otherwise."""
    if not cfg.anneal_lr:
        return
    for name, lr in (("actor", cfg.actor_lr), ("critic", cfg.critic_lr)):
        for group in optimizers[name].param_groups:
            group["lr"] = annealed_lr(lr, frames, cfg.frames)


def stored_batches(cfg: OffPolicyConfig, policy: TensorDictModuleBase, run: TrainingRun,
                   buffer: ReplayBuffer, norm: RunningNorm) -> Iterator[tuple[TensorDictBase, bool]]:
    """Collect the remaining frames in batches of [num_envs, rollout_steps] (``run.batches``: uniform
    random actions for the run's first ``init_random_frames``); yield each batch after scaling its
    reward, storing its (``cfg.n_step``-step) transitions and updating the normaliser, with a flag that
    says whether the buffer holds enough to learn from (``init_random_frames`` transitions, at least a
    minibatch; a resumed run has its buffer back, so it decides as the uninterrupted run would)."""
    learn_after = max(cfg.batch_size, min(cfg.init_random_frames, cfg.buffer_size))
    keys = transition_keys(cfg.n_step)
    for batch in run.batches(policy, cfg.num_envs * cfg.rollout_steps, cfg.init_random_frames):
        batch["next", "reward"] = batch["next", "reward"] * cfg.reward_scale
        stored = n_step_transitions(batch, cfg.gamma, cfg.n_step)
        buffer.extend(stored.select(*keys).reshape(-1))
        norm.update(batch["observation"])
        yield batch, len(buffer) >= learn_after


__all__ = ["anneal_learning_rates", "make_critic", "make_replay_buffer", "n_step_transitions",
           "stored_batches"]
