"""What the PPO, SAC and TD3 recipes share: the config fields, the networks, the training env and
the bookkeeping of a run.

Networks (all read the env's "observation" [N, D] through one :class:`RunningNorm`):

    PolicyNet   obs [N, D] -> loc [N, A] (pre-tanh), and a scale [N, A] for stochastic actors:
                a learned state-independent log-std (PPO) or a second head (SAC)
    ValueNet    obs [N, D] -> V(s) [N, 1]                                   (PPO critic)
    QNet        obs [N, D], action [N, A] -> Q(s, a) [N, 1]               (SAC / TD3 critics)

The deployed action of every algorithm is ``tanh(loc)`` (TanhNormal's deterministic sample), which
is what :mod:`falcon_rl.policies.format` bakes into a policy file.
"""

from __future__ import annotations

import copy
import itertools
import math
import random
import time
from dataclasses import asdict, dataclass, field, fields

import numpy as np
import torch
from torch import nn
from torchrl.envs import ExcludeTransform, RewardSum, TransformedEnv

from ..defaults import DEFAULT_AIRFRAME, DEFAULT_BACKEND
from ..envs import make_env, task_spec
from ..envs.tasks import TERMINATION_CODE
from ..policies.format import ACTIVATIONS
from ..transforms import flight_env

#: The "termination_reason" of an episode that ended on a state, reward or action that was not finite.
NON_FINITE = TERMINATION_CODE["non_finite"]


@dataclass
class TrainConfig:
    """Fields every recipe has. Frames are env steps summed over the batch of envs."""

    #: A registered task; its ``TaskSpec.training[<algorithm>]`` holds the task's defaults of these fields.
    task: str = "altitude"
    #: Shipped airframe name or JSON path.
    airframe: str = DEFAULT_AIRFRAME
    #: Parallel envs in the training batch.
    num_envs: int = 512
    #: Simulator backend (``defaults.BATCH_BACKENDS``; the default is the fastest at these batch sizes).
    backend: str = DEFAULT_BACKEND
    device: str = "cpu"
    seed: int = 0
    #: Total env steps to train for.
    frames: int = 10_000_000
    #: Training episode length, s (None: the task's default). Shorter episodes show the policy more
    #: acquisition transients per frame; the evaluation protocol still flies its own length.
    episode_seconds: float | None = None
    #: Multiplies the env reward before learning (returns of 3000-step episodes are large).
    reward_scale: float = 1.0
    #: Hidden layer widths and activation of every network.
    cells: tuple[int, ...] = (64, 64)
    activation: str = "tanh"
    #: Normalise observations with running statistics (saved with the policy); the std used is at
    #: least ``norm_min_std`` (the task observations are already scaled to O(1), and a nearly constant
    #: channel early in training must not be blown up).
    normalize_observations: bool = True
    norm_min_std: float = 0.1
    #: Start the actor's mean action at the task's trim command (else at 0, mid-range).
    init_at_trim: bool = True
    #: Extra options of the training env (task config fields such as reward weights), see make_env.
    env_options: dict = field(default_factory=dict)
    #: Output folder (checkpoint.pt, policy.pt, policy.ts, logs); None: no files.
    out: str | None = "runs/train"
    #: Continue from ``out``/checkpoint.pt: True needs it (a missing one is an error), "auto" resumes
    #: when it exists and starts a new run otherwise, False starts a new run.
    resume: bool | str = False
    #: "csv", "tensorboard", "wandb" (offline unless WANDB_MODE says otherwise) or "none".
    logger: str = "csv"
    #: Write the checkpoint every this many frames (and at the end). A checkpoint closes a segment of
    #: collection: the envs restart (reset, episodes staggered) after it, whether the run goes on or is
    #: resumed from it, so that a resumed run equals an uninterrupted one bit for bit.
    checkpoint_every: int = 2_000_000
    #: Evaluate on a short protocol every this many frames (0: only at the end).
    eval_every: int = 0
    #: Ship the best of the periodic evaluations' snapshots and the last weights, scored on validation
    #: episodes (:mod:`falcon_rl.recipes.selection`), instead of the last weights; needs ``eval_every``.
    keep_best: bool = False
    #: Stop training at the first validation that meets every condition, e.g.
    #: ``"survival>=1,acquisition>=0.95,rmse_m<=0.5"`` (metrics of the task's protocol, each averaged
    #: over its cases; :func:`falcon_rl.recipes.selection.parse_stop_when`); needs ``eval_every``.
    #: "" trains all ``frames``.
    stop_when: str = ""
    #: Episodes (per case) that confirm a validation meeting ``stop_when`` before the run stops, on
    #: their own seeds (``seed + CONFIRMATION_SEED``: neither the validation's nor the test's); when
    #: they miss a condition the run trains on. 0 stops on the validation alone.
    confirm_episodes: int = 100
    #: Episodes of the periodic evaluation and of the final one (on the task's protocol: per maneuver on
    #: the attitude protocol), and their length, s (None: the protocol's own, 30 s on altitude).
    eval_episodes: int = 16
    final_eval_episodes: int = 100
    eval_seconds: float | None = None
    #: Torch intra-op threads; 1 is fastest for these small tensors on a shared CPU.
    threads: int = 1
    #: Show a tqdm progress bar.
    progress: bool = True

    def to_dict(self) -> dict:
        return {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(self).items()}

@dataclass
class OffPolicyConfig(TrainConfig):
    """Replay-based hyper-parameters shared by SAC and TD3 (on top of :class:`TrainConfig`)."""

    #: Steps per env per iteration; a batch holds num_envs x rollout_steps frames.
    rollout_steps: int = 8
    #: Gradient steps per collected batch (update-to-data ratio = this / batch frames).
    updates_per_batch: int = 16
    batch_size: int = 512
    buffer_size: int = 1_000_000
    #: Uniform random actions before the policy acts (and before the first update).
    init_random_frames: int = 20_000
    actor_lr: float = 3e-4
    critic_lr: float = 3e-4
    gamma: float = 0.99
    #: Polyak factor of the target critics (target <- (1 - tau) target + tau online).
    tau: float = 0.005
    #: Hidden layers and activation of the critics (the actor uses ``cells`` / ``activation``).
    critic_cells: tuple[int, ...] = (256, 256)
    critic_activation: str = "relu"
    #: Layer norm after every hidden layer of the critics (keeps the Q features' scale steady while the
    #: targets move; the actor and the policy file are unchanged).
    critic_layer_norm: bool = False
    #: Anneal the actor's and critics' learning rates linearly to 5 % over ``frames`` (as PPO's
    #: ``anneal_lr``; SAC's temperature keeps its own): the last frames refine the policy instead of
    #: moving it.
    anneal_lr: bool = False
    #: Rewards summed before the critic's target bootstraps (TorchRL's MultiStep over each collected
    #: batch, cut at episode ends and at the batch's end; 1: the one-step target). At most rollout_steps.
    n_step: int = 1


#: Task-independent defaults of the off-policy recipes (each task's ``TaskSpec.training["sac"/"td3"]``
#: goes on top, e.g. the altitude task's training env). On a CPU the gradient steps, not the
#: simulator, bound the wall clock (one SAC step on a 256 batch costs 10-30 ms on one core), so: small
#: networks (actor 64x64, critics 128x128), few envs and 16 envs x 16 steps = 256 frames feeding 64
#: updates (update-to-data ratio 0.25). Measured on the Ranger altitude task (seed 1, one free core,
#: docs/notes/policies-training-log.md): SAC and TD3 both reach survival 1, acquisition 1 and RMSE
#: 0.37 / 0.35 m on the 100-episode protocol after 400 k frames (1,414 s / 1,127 s wall); at 100 k
#: frames neither acquires reliably yet.
OFF_POLICY_DEFAULTS: dict = {
    "num_envs": 16, "frames": 400_000, "reward_scale": 0.1, "rollout_steps": 16, "updates_per_batch": 64,
    "batch_size": 256, "init_random_frames": 10_240, "cells": (64, 64), "activation": "relu",
    "critic_cells": (128, 128), "checkpoint_every": 50_000,
}

#: Entries of a transition kept in the replay buffer.
TRANSITION = ("observation", "action", ("next", "observation"), ("next", "reward"), ("next", "done"),
              ("next", "terminated"))
#: The extra entry of an n-step transition: the steps from "observation" to ("next", "observation").
STEPS_TO_NEXT = "steps_to_next_obs"


def transition_keys(n_step: int = 1) -> tuple:
    """The replay buffer's entries for ``n_step``-step transitions (:data:`TRANSITION`, plus
    :data:`STEPS_TO_NEXT` when ``n_step`` > 1)."""
    return TRANSITION + ((STEPS_TO_NEXT,) if n_step > 1 else ())


def transition_shapes(env: TransformedEnv, n_step: int = 1) -> dict[tuple[str, ...], tuple[int, ...]]:
    """{key: shape of one transition's entry} of :func:`transition_keys` for ``env`` (D, A: its
    sizes; the step count is a scalar)."""
    obs_dim, act_dim = observation_dims(env)
    shapes = {"observation": (obs_dim,), "action": (act_dim,), STEPS_TO_NEXT: ()}
    return {(k,) if isinstance(k, str) else k: shapes.get(k if isinstance(k, str) else k[1], (1,))
            for k in transition_keys(n_step)}


def config_from(cls: type, task: str, algorithm: str, defaults: dict | None = None,
                **overrides) -> TrainConfig:
    """``cls`` with the recipe's task-independent ``defaults``, then the task's defaults for
    ``algorithm`` (``task_spec(task).training``, with the airframe's ``airframe_training`` on top), then
    ``overrides`` (None values are ignored). ``env_options`` merge key by key instead: an override adds
    to (or replaces single entries of) the task's, so ``--set 'env_options={"turbulence": "medium"}'``
    keeps the recipe's reward weights."""
    names = {f.name for f in fields(cls)}
    unknown = set(overrides) - names
    if unknown:
        raise TypeError(f"unknown {cls.__name__} fields {sorted(unknown)}")
    given = {k: v for k, v in overrides.items() if v is not None}
    airframe = given.get("airframe", (defaults or {}).get("airframe", cls.airframe))
    task_defaults = task_spec(task).training_defaults(algorithm, airframe)
    values = {**copy.deepcopy(defaults or {}), **task_defaults, **given}
    if isinstance(given.get("env_options"), dict):  # anything else fails the config checks
        values["env_options"] = {**(defaults or {}).get("env_options", {}),
                                 **task_defaults.get("env_options", {}), **given["env_options"]}
    return cls(task=task, **values)


# ---------------------------------------------------------------------------------------- networks
class RunningNorm(nn.Module):
    """obs [N, D] -> clip((obs - mean) / max(sqrt(var), min_std), +-clip), statistics merged batch
    by batch.

    The statistics are plain tensor attributes, not buffers: TorchRL losses copy the parameters and
    buffers of their networks (target and vmapped critics), and every copy must read the same,
    updated statistics. :meth:`stats` / :meth:`load_stats` save and restore them.
    """

    def __init__(self, dim: int, device: torch.device | str = "cpu", clip: float = 10.0,
                 enabled: bool = True, min_std: float = 0.1):
        super().__init__()
        self.enabled, self.clip, self.min_std = enabled, clip, min_std
        self.mean = torch.zeros(dim, device=device)
        self.var = torch.ones(dim, device=device)
        self.count = torch.zeros((), device=device, dtype=torch.float64)

    @torch.no_grad()
    def update(self, obs: torch.Tensor) -> None:
        """Merge the mean and variance of ``obs`` [..., D] (Chan's parallel algorithm)."""
        if not self.enabled:
            return
        x = obs.reshape(-1, obs.shape[-1]).to(self.mean.dtype)
        n, batch_mean, batch_var = x.shape[0], x.mean(0), x.var(0, unbiased=False)
        total = self.count + n
        delta = batch_mean - self.mean
        self.mean.add_(delta * (n / total).to(self.mean.dtype))
        m2 = self.var * self.count + batch_var * n + delta.square() * (self.count * n / total)
        self.var.copy_(m2 / total)
        self.count.copy_(total)

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        if not self.enabled:
            return obs
        return ((obs - self.mean) / self.std()).clamp(-self.clip, self.clip)

    def std(self) -> torch.Tensor:
        return self.var.sqrt().clamp_min(self.min_std)

    def stats(self) -> dict[str, torch.Tensor]:
        return {"mean": self.mean.clone(), "var": self.var.clone(), "count": self.count.clone(),
                "enabled": torch.tensor(self.enabled), "clip": torch.tensor(self.clip),
                "min_std": torch.tensor(self.min_std)}

    def load_stats(self, stats: dict[str, torch.Tensor]) -> None:
        self.mean.copy_(stats["mean"])
        self.var.copy_(stats["var"])
        self.count.copy_(stats["count"])
        self.enabled, self.clip = bool(stats["enabled"]), float(stats["clip"])
        self.min_std = float(stats["min_std"])


def annealed_lr(lr: float, frames: int, total: int, floor: float = 0.05) -> float:
    """``lr`` annealed linearly over ``total`` frames, to ``floor`` x ``lr`` from then on."""
    return lr * max(1.0 - frames / total, floor)


def mlp(n_in: int, n_out: int, cells: tuple[int, ...], activation: str, out_gain: float = 1.0,
        layer_norm: bool = False) -> nn.Sequential:
    """Linear-activation stack, orthogonal init (gain sqrt 2), last layer gain ``out_gain``; with
    ``layer_norm`` a LayerNorm between each hidden Linear and its activation."""
    layers: list[nn.Module] = []
    sizes = (n_in, *cells)
    for a, b in itertools.pairwise(sizes):
        layers += [nn.Linear(a, b), *([nn.LayerNorm(b)] if layer_norm else []), ACTIVATIONS[activation]()]
    layers.append(nn.Linear(sizes[-1], n_out))
    for i, layer in enumerate(m for m in layers if isinstance(m, nn.Linear)):
        gain = out_gain if i == len(cells) else math.sqrt(2.0)
        nn.init.orthogonal_(layer.weight, gain)
        nn.init.zeros_(layer.bias)
    return nn.Sequential(*layers)


class PolicyNet(nn.Module):
    """obs [N, D] -> loc [N, A] (``scale=None``), or (loc, scale) [N, A] each.

    ``scale="param"``: a learned log-std vector (PPO); ``scale="head"``: the MLP outputs 2A values,
    the second half a log-std clamped to [-5, 2] (SAC). ``mlp`` holds everything that acts.
    """

    def __init__(self, norm: RunningNorm, obs_dim: int, act_dim: int, cells: tuple[int, ...],
                 activation: str = "tanh", scale: str | None = None, init_log_std: float = -0.5):
        super().__init__()
        self.norm, self.act_dim, self.scale = norm, act_dim, scale
        self.mlp = mlp(obs_dim, act_dim * (2 if scale == "head" else 1), cells, activation, out_gain=0.01)
        if scale == "param":
            self.log_std = nn.Parameter(torch.full((act_dim,), float(init_log_std)))

    def forward(self, obs: torch.Tensor):
        out = self.mlp(self.norm(obs))
        loc = out[..., : self.act_dim]
        if self.scale is None:
            return loc
        log_std = self.log_std.expand_as(loc) if self.scale == "param" else out[..., self.act_dim:]
        return loc, log_std.clamp(-5.0, 2.0).exp()

    @torch.no_grad()
    def start_at(self, action: torch.Tensor) -> None:
        """Bias the mean action to ``action`` [A] in (-1, 1): tanh(loc) = action at initialisation."""
        self.mlp[-1].bias[: self.act_dim] = torch.atanh(action.clamp(-0.95, 0.95)).to(self.mlp[-1].bias)

    def arch(self) -> dict:
        """Plain description of the acting network (the policy file's ``arch`` entry)."""
        linear = [m for m in self.mlp if isinstance(m, nn.Linear)]
        activation = next(k for k, v in ACTIVATIONS.items() if isinstance(self.mlp[1], v))
        return {"obs_dim": linear[0].in_features, "act_dim": self.act_dim,
                "out_dim": linear[-1].out_features, "cells": [m.out_features for m in linear[:-1]],
                "activation": activation}


class ValueNet(nn.Module):
    """obs [N, D] -> V(s) [N, 1]."""

    def __init__(self, norm: RunningNorm, obs_dim: int, cells: tuple[int, ...], activation: str = "tanh"):
        super().__init__()
        self.norm, self.mlp = norm, mlp(obs_dim, 1, cells, activation, out_gain=1.0)

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        return self.mlp(self.norm(obs))


class QNet(nn.Module):
    """obs [N, D], action [N, A] -> Q(s, a) [N, 1] (``layer_norm``: see :func:`mlp`)."""

    def __init__(self, norm: RunningNorm, obs_dim: int, act_dim: int, cells: tuple[int, ...],
                 activation: str = "relu", layer_norm: bool = False):
        super().__init__()
        self.norm = norm
        self.mlp = mlp(obs_dim + act_dim, 1, cells, activation, out_gain=1.0, layer_norm=layer_norm)

    def forward(self, obs: torch.Tensor, action: torch.Tensor) -> torch.Tensor:
        return self.mlp(torch.cat([self.norm(obs), action], dim=-1))


# ---------------------------------------------------------------------------------------- env
#: ``make_env`` options that put a robustness transform over the env (some read the published state).
ROBUSTNESS_OPTIONS: tuple[str, ...] = ("sensors", "obs_delay_ms", "action_delay_ms", "randomize")


def make_train_env(cfg: TrainConfig, num_envs: int | None = None, seed_offset: int = 0) -> TransformedEnv:
    """The task env with a RewardSum transform ("episode_reward" for the logs), without the
    ("state", ...) and ("task", ...) entries (learning reads "observation" only): built ``lean`` (it
    publishes none) unless a robustness transform over it reads the state."""
    options = dict(cfg.env_options)
    if cfg.episode_seconds is not None:
        options["episode_seconds"] = cfg.episode_seconds
    if not any(options.get(name) is not None for name in ROBUSTNESS_OPTIONS):
        options.setdefault("lean", True)
    try:
        base = make_env(cfg.task, cfg.airframe, num_envs=num_envs or cfg.num_envs, backend=cfg.backend,
                        device=cfg.device, seed=cfg.seed + seed_offset, **options)
    except TypeError as exc:  # an unknown env option
        raise ValueError(f"env_options: {exc}") from None
    unused = [key for key in base.observation_spec.keys(True, True) if key[0] in ("state", "task")]
    if not isinstance(base, TransformedEnv):
        base = TransformedEnv(base)  # robustness transforms come as one; append instead of nesting
    if unused:
        base.append_transform(ExcludeTransform(*unused))
    base.append_transform(RewardSum())
    return base


def stagger_episodes(env: TransformedEnv, seed: int) -> None:
    """Spread the first truncations over the horizon: start each env's step counter at a random
    step, so that later batches hold every phase of the episode rather than all envs in lockstep."""
    flight_env(env, "stagger_episodes").stagger_episodes(torch.Generator().manual_seed(seed))


def trim_action(env: TransformedEnv) -> torch.Tensor:
    """The task's trim command in its action channels [A], float32 on the CPU."""
    return flight_env(env, "trim_action").trim_action().float().cpu()


def make_actor_net(cfg: TrainConfig, env: TransformedEnv, scale: str | None, **kwargs) -> PolicyNet:
    """The actor network of ``cfg`` for ``env`` with its normaliser (started at trim when asked)."""
    obs_dim, act_dim = observation_dims(env)
    norm = RunningNorm(obs_dim, cfg.device, enabled=cfg.normalize_observations, min_std=cfg.norm_min_std)
    net = PolicyNet(norm, obs_dim, act_dim, cfg.cells, cfg.activation, scale=scale, **kwargs)
    trim = trim_action(env) if cfg.init_at_trim else None
    if trim is not None:
        net.start_at(trim)
    return net.to(cfg.device)


def observation_dims(env: TransformedEnv) -> tuple[int, int]:
    return env.observation_spec["observation"].shape[-1], env.action_spec.shape[-1]


# ---------------------------------------------------------------------------------------- run state
@dataclass
class Counters:
    """What a resumed run continues from (plain numbers only, for weights_only loading)."""

    frames: int = 0
    iterations: int = 0
    updates: int = 0
    episodes: int = 0
    wall_seconds: float = 0.0
    last_checkpoint_frames: int = 0
    last_eval_frames: int = 0


@dataclass
class EpisodeStats:
    """Running return, survival and throughput of the most recent batches (progress bar, logs)."""

    mean_return: float = math.nan
    survival: float = math.nan
    start: float = field(default_factory=time.perf_counter)
    frames_at_start: int = 0
    #: Episodes that ended in the batches seen so far, and those of them that ended "non_finite" (a
    #: state, reward or action that was not finite; counted where the batch holds "termination_reason").
    episodes_ended: int = 0
    non_finite_ended: int = 0

    def update(self, batch, reward_key=("next", "episode_reward")) -> dict[str, float]:
        """Scalars of one collected batch [N, T] (episodes that ended in it); counts its ended episodes."""
        done = batch["next", "done"].squeeze(-1)
        self.episodes_ended += int(done.sum())
        reason = batch.get(("next", "termination_reason"), None)
        if reason is not None:
            self.non_finite_ended += int((reason.squeeze(-1)[done] == NON_FINITE).sum())
        if done.any():
            self.mean_return = float(batch.get(reward_key).squeeze(-1)[done].mean())
            terminated = batch["next", "terminated"].squeeze(-1)[done]
            self.survival = float(1.0 - terminated.float().mean())
        return {"train/return": self.mean_return, "train/survival": self.survival,
                "train/episodes_ended": float(done.sum()),
                "train/reward": float(batch["next", "reward"].mean())}

    def rate(self, frames: int) -> float:
        return (frames - self.frames_at_start) / max(time.perf_counter() - self.start, 1e-9)


def set_threads(cfg: TrainConfig) -> None:
    if cfg.threads > 0 and torch.device(cfg.device).type == "cpu":
        torch.set_num_threads(cfg.threads)


def seed_everything(seed: int) -> None:
    """Seed torch (CPU and CUDA), numpy and Python's ``random`` with ``seed``: done before a recipe
    builds anything, so that the networks' initial weights follow the seed."""
    torch.manual_seed(seed)
    np.random.seed(seed % 2**32)
    random.seed(seed)


__all__ = ["ACTIVATIONS", "OFF_POLICY_DEFAULTS", "STEPS_TO_NEXT", "TRANSITION", "Counters",
           "EpisodeStats", "OffPolicyConfig", "PolicyNet", "QNet", "RunningNorm", "TrainConfig", "ValueNet",
           "annealed_lr", "config_from", "make_actor_net", "make_train_env", "mlp", "observation_dims",
           "seed_everything", "set_threads", "stagger_episodes", "transition_keys", "transition_shapes",
           "trim_action"]
