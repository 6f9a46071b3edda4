"""The protocols' rollout (``protocols._rollout``: each step's "action" and "next" entries copied into
storage allocated at the first step, ``step_record.StepRecord``) records what TorchRL's own rollout
records, on the plain env and behind delay lines and sensors, and copies each step (a transform that
hands out the same tensor every step)."""

from __future__ import annotations

import pytest
import torch
from tensordict import TensorDictBase
from torchrl.envs import Transform, TransformedEnv

from falcon_rl import make_env
from falcon_rl.evaluation.protocols import _rollout

STEPS = 40


class HeldActions:
    """A fixed sequence of actions [N, A] (one per call) from a seeded generator."""

    def __init__(self, shape: torch.Size, seed: int):
        generator = torch.Generator().manual_seed(seed)
        self.actions = torch.rand(STEPS, *shape, generator=generator) * 1.6 - 0.8
        self.count = 0

    def __call__(self, td: TensorDictBase) -> TensorDictBase:
        td["action"] = self.actions[self.count % STEPS]
        self.count += 1
        return td


@pytest.mark.parametrize("options", [{}, {"obs_delay_ms": 30.0, "action_delay_ms": 20.0},
                                     {"sensors": "medium"}])
def test_protocol_rollout_records_what_torchrl_records(options):
    envs = [make_env("altitude", "volantex_ranger", num_envs=4, seed=2, decimation=1, **options)
            for _ in range(2)]
    ours, _ = _rollout(envs[0], HeldActions(envs[0].action_spec.shape, 0), STEPS, "test")
    theirs = envs[1].rollout(STEPS, HeldActions(envs[1].action_spec.shape, 0), break_when_any_done=False)
    assert ours.batch_size == theirs.batch_size == torch.Size([4, STEPS])
    assert torch.equal(ours["action"], theirs["action"])
    for key in ("observation", "reward", "done", "termination_reason"):
        assert torch.equal(ours["next", key], theirs["next", key]), key
    assert not torch.equal(ours["next", "observation"][:, 0], ours["next", "observation"][:, -1])


class ReusedObservation(Transform):
    """Hands out the same observation tensor every step (written in place), as an env or transform
    with preallocated outputs may."""

    def __init__(self):
        super().__init__()
        self.buffer: torch.Tensor | None = None

    def _step(self, tensordict: TensorDictBase, next_tensordict: TensorDictBase) -> TensorDictBase:
        observation = next_tensordict["observation"]
        if self.buffer is None:
            self.buffer = observation.clone()
        self.buffer.copy_(observation)
        next_tensordict["observation"] = self.buffer
        return next_tensordict


def test_protocol_rollout_copies_each_step():
    envs = [make_env("altitude", "volantex_ranger", num_envs=4, seed=2, decimation=1) for _ in range(2)]
    reused = TransformedEnv(envs[0], ReusedObservation())
    ours, _ = _rollout(reused, HeldActions(envs[0].action_spec.shape, 0), STEPS, "test")
    plain, _ = _rollout(envs[1], HeldActions(envs[1].action_spec.shape, 0), STEPS, "test")
    assert torch.equal(ours["next", "observation"], plain["next", "observation"])


def test_protocol_rollout_needs_a_step():
    env = make_env("altitude", "volantex_ranger", num_envs=2, seed=0)
    with pytest.raises(ValueError, match="needs at least one step"):
        _rollout(env, HeldActions(env.action_spec.shape, 0), 0, "test")
