"""SAC (twin Q, learned temperature) on a batched falcon-rl task, CleanRL style, on TorchRL.

    from falcon_rl.recipes import sac
    summary = sac.train(sac.make_config("altitude", frames=2_000_000))

One iteration: the Collector rolls ``rollout_steps`` steps of all ``num_envs`` envs (random actions
for the first ``init_random_frames``) into a replay buffer with on-device storage; then
``updates_per_batch`` gradient steps on sampled minibatches minimise SACLoss (critic, actor and
temperature losses), each followed by a Polyak update of the target critics. The replay buffer is saved
in every checkpoint: a resumed run samples from the same transitions and goes on learning at once.
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from tensordict.nn import TensorDictModule
from torchrl.modules import ProbabilisticActor, TanhNormal
from torchrl.objectives import SACLoss, SoftUpdate

from .common import OFF_POLICY_DEFAULTS, OffPolicyConfig, config_from, make_actor_net, make_train_env
from .off_policy import anneal_learning_rates, make_critic, make_replay_buffer, stored_batches
from .runner import TrainingRun, prepare


@dataclass
class SACConfig(OffPolicyConfig):
    """SAC hyper-parameters (on top of :class:`OffPolicyConfig`)."""

    alpha_lr: float = 3e-4
    alpha_init: float = 0.1
    #: Entropy the temperature steers the policy to, nats ("auto": minus the action count, TorchRL's
    #: default). Lower keeps the exploration noise smaller, which a precise hold needs.
    target_entropy: float | str = "auto"


#: Task-independent defaults (the task's ``TaskSpec.training["sac"]`` goes on top).
DEFAULTS = OFF_POLICY_DEFAULTS


def make_config(task: str = "altitude", **overrides) -> SACConfig:
    """SACConfig with the recipe's defaults, the task's, then ``overrides``."""
    return config_from(SACConfig, task, "sac", DEFAULTS, **overrides)


def train(cfg: SACConfig) -> dict:
    """Train SAC as configured; returns the run summary (and writes files under ``cfg.out``)."""
    doc = prepare("sac", cfg)  # before anything is built: the seed decides the initial weights
    env = make_train_env(cfg)
    actor_net = make_actor_net(cfg, env, scale="head")
    norm = actor_net.norm
    actor = ProbabilisticActor(TensorDictModule(actor_net, ["observation"], ["loc", "scale"]),
                               in_keys=["loc", "scale"], spec=env.action_spec, distribution_class=TanhNormal)
    loss = SACLoss(actor, make_critic(cfg, env, norm), num_qvalue_nets=2, loss_function="l2",
                   alpha_init=cfg.alpha_init, action_spec=env.action_spec_unbatched,
                   target_entropy=cfg.target_entropy)
    loss.make_value_estimator(gamma=cfg.gamma)
    target_update = SoftUpdate(loss, tau=cfg.tau)
    optimizers = {"actor": torch.optim.Adam(loss.actor_network_params.values(True, True), lr=cfg.actor_lr),
                  "critic": torch.optim.Adam(loss.qvalue_network_params.values(True, True), lr=cfg.critic_lr),
                  "alpha": torch.optim.Adam([loss.log_alpha], lr=cfg.alpha_lr)}
    buffer = make_replay_buffer(cfg)

    run = TrainingRun("sac", cfg, env, actor_net, {"actor": actor_net, "loss": loss}, optimizers,
                      replay=buffer)
    counters = run.start(doc)
    scalars: dict[str, float] = {}
    for batch, ready in stored_batches(cfg, actor, run, buffer, norm):
        if ready:
            anneal_learning_rates(cfg, optimizers, counters.frames)
            for _ in range(cfg.updates_per_batch):
                out = loss(buffer.sample())
                for optimizer in optimizers.values():
                    optimizer.zero_grad(set_to_none=True)
                # each loss only reaches its own parameters (SACLoss detaches the others)
                (out["loss_qvalue"] + out["loss_actor"] + out["loss_alpha"]).backward()
                for optimizer in optimizers.values():
                    optimizer.step()
                target_update.step()
                counters.updates += 1
            out = out.detach()
            scalars = {"loss/critic": float(out["loss_qvalue"]), "loss/actor": float(out["loss_actor"]),
                       "train/alpha": float(out["alpha"]), "train/entropy": float(out["entropy"])}
        run.after_batch(batch, scalars)
    return run.finish()


__all__ = ["DEFAULTS", "SACConfig", "make_config", "train"]
