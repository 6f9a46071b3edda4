"""PPO (clipped objective, GAE) on a batched falcon-rl task, CleanRL style, on TorchRL.

    from falcon_rl.recipes import ppo
    summary = ppo.train(ppo.make_config("altitude", airframe="volantex_ranger", frames=20_000_000))

One iteration: the Collector rolls ``rollout_steps`` steps of all ``num_envs`` envs (batch
[N, T]); GAE writes advantages and value targets; ``epochs`` passes of ``minibatches`` shuffled
minibatches minimise ClipPPOLoss (clipped surrogate + value loss - entropy bonus); the running
observation statistics absorb the batch after the update (so that every batch is scored with the
statistics it was collected with).
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from tensordict.nn import TensorDictModule
from torchrl.modules import ProbabilisticActor, TanhNormal, ValueOperator
from torchrl.objectives import ClipPPOLoss
from torchrl.objectives.value import GAE

from .common import (
    TrainConfig,
    ValueNet,
    annealed_lr,
    config_from,
    make_actor_net,
    make_train_env,
    observation_dims,
)
from .runner import TrainingRun, prepare


@dataclass
class PPOConfig(TrainConfig):
    """PPO hyper-parameters (on top of :class:`TrainConfig`)."""

    #: Steps per env per iteration (T); a batch holds num_envs x T frames.
    rollout_steps: int = 32
    #: Passes over each batch, and minibatches per pass.
    epochs: int = 4
    minibatches: int = 4
    #: Adam learning rate, linearly annealed to 5 % of it over ``frames`` when ``anneal_lr``.
    lr: float = 3e-4
    anneal_lr: bool = True
    #: Discount and GAE lambda (gamma 0.99 looks 100 control steps ahead: 5 s at the tasks' 20 Hz
    #: training control, 1 s at the paper's 100 Hz).
    gamma: float = 0.99
    gae_lambda: float = 0.95
    #: PPO ratio clip, entropy bonus and value-loss weight.
    clip_epsilon: float = 0.2
    entropy_coeff: float = 1e-4
    critic_coeff: float = 0.5
    max_grad_norm: float = 0.5
    #: Initial log-std of the (learned, state-independent) Gaussian before the tanh.
    init_log_std: float = -1.0


#: Task-independent defaults: none beyond PPOConfig's. Each task's ``TaskSpec.training["ppo"]`` sets its
#: own (altitude and attitude: 256 envs x 32 steps, 8 M frames, 20 Hz control; see their modules).
DEFAULTS: dict = {}


def make_config(task: str = "altitude", **overrides) -> PPOConfig:
    """PPOConfig with the task's defaults (its TaskSpec), then ``overrides``."""
    return config_from(PPOConfig, task, "ppo", DEFAULTS, **overrides)


def train(cfg: PPOConfig) -> dict:
    """Train PPO as configured; returns the run summary (and writes files under ``cfg.out``)."""
    doc = prepare("ppo", cfg)  # before anything is built: the seed decides the initial weights
    env = make_train_env(cfg)
    obs_dim, _ = observation_dims(env)
    actor_net = make_actor_net(cfg, env, scale="param", init_log_std=cfg.init_log_std)
    norm = actor_net.norm
    actor = ProbabilisticActor(TensorDictModule(actor_net, ["observation"], ["loc", "scale"]),
                               in_keys=["loc", "scale"], spec=env.action_spec, distribution_class=TanhNormal,
                               return_log_prob=True)
    critic_net = ValueNet(norm, obs_dim, cfg.cells, cfg.activation).to(cfg.device)
    critic = ValueOperator(critic_net, in_keys=["observation"])
    loss = ClipPPOLoss(actor, critic, clip_epsilon=cfg.clip_epsilon, entropy_coeff=cfg.entropy_coeff,
                       critic_coeff=cfg.critic_coeff, loss_critic_type="l2", normalize_advantage=True)
    gae = GAE(gamma=cfg.gamma, lmbda=cfg.gae_lambda, value_network=critic, average_gae=False)
    optimizer = torch.optim.Adam(loss.parameters(), lr=cfg.lr, eps=1e-5)

    run = TrainingRun("ppo", cfg, env, actor_net, {"actor": actor_net, "critic": critic_net},
                      {"optimizer": optimizer})
    counters = run.start(doc)
    for batch in run.batches(actor, cfg.num_envs * cfg.rollout_steps):
        if cfg.anneal_lr:
            optimizer.param_groups[0]["lr"] = annealed_lr(cfg.lr, counters.frames, cfg.frames)
        batch["next", "reward"] = batch["next", "reward"] * cfg.reward_scale
        with torch.no_grad():
            gae(batch)
        flat = batch.exclude("next").reshape(-1)
        for _ in range(cfg.epochs):
            for index in torch.randperm(flat.numel(), device=flat.device).chunk(cfg.minibatches):
                out = loss(flat[index])
                total = out["loss_objective"] + out["loss_critic"] + out["loss_entropy"]
                optimizer.zero_grad(set_to_none=True)
                total.backward()
                torch.nn.utils.clip_grad_norm_(loss.parameters(), cfg.max_grad_norm)
                optimizer.step()
                counters.updates += 1
        norm.update(batch["observation"])
        out = out.detach()
        run.after_batch(batch, {"loss/objective": float(out["loss_objective"]),
                                "loss/critic": float(out["loss_critic"]),
                                "loss/entropy": float(out["entropy"]),
                                "train/action_std": float(actor_net.log_std.detach().exp().mean()),
                                "train/lr": optimizer.param_groups[0]["lr"]})
    return run.finish()


__all__ = ["DEFAULTS", "PPOConfig", "make_config", "train"]
