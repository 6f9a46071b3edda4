"""TD3 (twin Q, target-policy smoothing, delayed actor) on a batched falcon-rl task, CleanRL style,
on TorchRL.

    from falcon_rl.recipes import td3
    summary = td3.train(td3.make_config("altitude", frames=2_000_000))

One iteration: the Collector rolls ``rollout_steps`` steps of all ``num_envs`` envs with Gaussian
exploration noise (random actions for the first ``init_random_frames``) into a replay buffer with
on-device storage; then ``updates_per_batch`` critic steps on sampled minibatches (TD3Loss), an
actor step and Polyak target update every ``policy_delay`` of them. The replay buffer is saved in
every checkpoint: a resumed run samples from the same transitions and goes on learning at once.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from tensordict.nn import TensorDictModule, TensorDictSequential
from torch import nn
from torchrl.modules import AdditiveGaussianModule
from torchrl.objectives import SoftUpdate, TD3Loss

from .common import OFF_POLICY_DEFAULTS, OffPolicyConfig, config_from, make_actor_net, make_train_env
from .off_policy import anneal_learning_rates, make_critic, make_replay_buffer, stored_batches
from .runner import TrainingRun, prepare


@dataclass
class TD3Config(OffPolicyConfig):
    """TD3 hyper-parameters (on top of :class:`OffPolicyConfig`)."""

    #: The actor and the targets step every ``policy_delay`` critic steps.
    policy_delay: int = 2
    #: Std of the Gaussian exploration noise on the [-1, 1] actions.
    exploration_noise: float = 0.1
    #: Target-policy smoothing noise std and its clip.
    policy_noise: float = 0.2
    noise_clip: float = 0.5


#: Task-independent defaults (the task's ``TaskSpec.training["td3"]`` goes on top).
DEFAULTS = OFF_POLICY_DEFAULTS


def make_config(task: str = "altitude", **overrides) -> TD3Config:
    """TD3Config with the recipe's defaults, the task's, then ``overrides``."""
    return config_from(TD3Config, task, "td3", DEFAULTS, **overrides)


def train(cfg: TD3Config) -> dict:
    """Train TD3 as configured; returns the run summary (and writes files under ``cfg.out``)."""
    doc = prepare("td3", cfg)  # before anything is built: the seed decides the initial weights
    env = make_train_env(cfg)
    actor_net = make_actor_net(cfg, env, scale=None)
    norm = actor_net.norm
    actor = TensorDictModule(nn.Sequential(actor_net, nn.Tanh()), ["observation"], ["action"])
    explore = TensorDictSequential(actor, AdditiveGaussianModule(
        env.action_spec_unbatched, sigma_init=cfg.exploration_noise, sigma_end=cfg.exploration_noise,
        device=cfg.device))
    loss = TD3Loss(actor, make_critic(cfg, env, norm), action_spec=env.action_spec_unbatched,
                   num_qvalue_nets=2, loss_function="l2", policy_noise=cfg.policy_noise,
                   noise_clip=cfg.noise_clip)
    loss.make_value_estimator(gamma=cfg.gamma)
    target_update = SoftUpdate(loss, tau=cfg.tau)
    optimizers = {"actor": torch.optim.Adam(loss.actor_network_params.values(True, True), lr=cfg.actor_lr),
                  "critic": torch.optim.Adam(loss.qvalue_network_params.values(True, True), lr=cfg.critic_lr)}
    buffer = make_replay_buffer(cfg)

    run = TrainingRun("td3", cfg, env, actor_net, {"actor": actor_net, "loss": loss}, optimizers,
                      replay=buffer)
    counters = run.start(doc)
    scalars: dict[str, float] = {}
    for batch, ready in stored_batches(cfg, explore, run, buffer, norm):
        if ready:
            anneal_learning_rates(cfg, optimizers, counters.frames)
            for _ in range(cfg.updates_per_batch):
                counters.updates += 1
                out = loss(buffer.sample())
                update_actor = counters.updates % cfg.policy_delay == 0
                for optimizer in optimizers.values():
                    optimizer.zero_grad(set_to_none=True)
                (out["loss_qvalue"] + (out["loss_actor"] if update_actor else 0.0)).backward()
                optimizers["critic"].step()
                if update_actor:
                    optimizers["actor"].step()
                    target_update.step()
            out = out.detach()
            scalars = {"loss/critic": float(out["loss_qvalue"]), "loss/actor": float(out["loss_actor"])}
        run.after_batch(batch, scalars)
    return run.finish()


__all__ = ["DEFAULTS", "TD3Config", "make_config", "train"]
