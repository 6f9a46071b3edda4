"""The altitude task inside a TorchRL data pipeline: transforms, a small policy and a Collector.

    python examples/torchrl_pipeline.py

Builds 64 Volantex Ranger altitude envs, normalises observations with ObservationNorm (statistics
from a short random rollout), counts steps and sums rewards, and collects a few batches with a
Gaussian MLP policy, printing what a training loop would log. Runs in well under a minute on CPU.
"""

from __future__ import annotations

import torch
from tensordict.nn import NormalParamExtractor, TensorDictModule
from torch import nn
from torchrl.collectors import Collector
from torchrl.envs import Compose, ObservationNorm, RewardSum, StepCounter, TransformedEnv
from torchrl.envs.utils import check_env_specs
from torchrl.modules import MLP, ProbabilisticActor, TanhNormal

import falcon_rl

NUM_ENVS = 64
FRAMES_PER_BATCH = NUM_ENVS * 50


def make_env() -> TransformedEnv:
    base = falcon_rl.make_env("altitude", "volantex_ranger", num_envs=NUM_ENVS, seed=0)
    env = TransformedEnv(base, Compose(
        ObservationNorm(in_keys=["observation"], standard_normal=True),
        StepCounter(),
        RewardSum(),
    ))
    env.transform[0].init_stats(num_iter=100, reduce_dim=(0, 1), cat_dim=1)
    return env


def make_policy(env: TransformedEnv) -> ProbabilisticActor:
    n_obs = env.observation_spec["observation"].shape[-1]
    n_act = env.action_spec.shape[-1]
    net = nn.Sequential(MLP(in_features=n_obs, out_features=2 * n_act, num_cells=[64, 64]),
                        NormalParamExtractor())
    module = TensorDictModule(net, in_keys=["observation"], out_keys=["loc", "scale"])
    return ProbabilisticActor(module, spec=env.action_spec, in_keys=["loc", "scale"],
                              distribution_class=TanhNormal, return_log_prob=True)


def main() -> None:
    torch.manual_seed(0)
    env = make_env()
    check_env_specs(env)
    policy = make_policy(env)
    collector = Collector(env, policy, frames_per_batch=FRAMES_PER_BATCH, total_frames=4 * FRAMES_PER_BATCH,
                          auto_register_policy_transforms=False)
    for i, batch in enumerate(collector):
        finished = batch["next", "done"]
        returns = batch["next", "episode_reward"][finished]
        print(f"batch {i}: {batch.numel()} frames, mean reward {batch['next', 'reward'].mean():.3f}, "
              f"episodes ended {int(finished.sum())}, "
              f"mean return {returns.mean() if returns.numel() else float('nan'):.2f}, "
              f"max steps {int(batch['next', 'step_count'].max())}, "
              f"|altitude error| {batch['next', 'task', 'altitude_error'].abs().mean():.2f} m")
    collector.shutdown()


if __name__ == "__main__":
    main()
