"""The published layout works with TorchRL's standard pieces as it is: CatTensors, ExcludeTransform,
replay buffers, ObservationNorm; the lean env; the task record's defaults."""

from __future__ import annotations

import pytest
import torch
from torchrl.data import LazyTensorStorage, ReplayBuffer
from torchrl.envs import CatTensors, Compose, ExcludeTransform, TransformedEnv
from torchrl.envs.utils import check_env_specs

from falcon_rl.envs import make_env
from falcon_rl.envs.layout import flat_scalars
from falcon_rl.envs.tasks import TERMINATION_REASONS, task_names, task_spec


@pytest.mark.parametrize("task", task_names())
def test_every_entry_has_a_feature_dim(task: str) -> None:
    env = make_env(task, "volantex_ranger", num_envs=3, seed=0)
    td = env.reset()
    for key in td.keys(True, True):
        assert td[key].dim() >= 2, key  # [N, ...]: scalars are [N, 1]
    assert td["state", "height"].shape == (3, 1)
    assert td["termination_reason"].shape == (3, 1) and td["termination_reason"].dtype == torch.long
    assert env.observation_spec["termination_reason"].n == len(TERMINATION_REASONS)


def test_cat_tensors_and_exclude_transform_work_on_the_env() -> None:
    """TorchRL 0.14's ExcludeTransform checks its keys against the spec's leaves, so a group is
    excluded by its leaves (a group name such as "state" is refused by TorchRL itself)."""
    base = make_env("altitude", "volantex_ranger", num_envs=4, seed=1)
    groups = [key for key in base.observation_spec.keys(True, True) if key[0] in ("state", "task")]
    env = TransformedEnv(base, Compose(
        CatTensors(in_keys=["observation", ("state", "height"), ("state", "airspeed")], out_key="features",
                   del_keys=False),
        ExcludeTransform(*groups)))
    check_env_specs(env)
    td = env.rollout(5, break_when_any_done=False)
    assert td["next", "features"].shape == (4, 5, base.task.observation_dim + 2)
    assert not [key for key in td["next"].keys(True, True) if key[0] in ("state", "task")]
    height = td["next", "features"][..., -2]
    assert torch.all(height > 0)


def test_a_lean_env_fills_a_small_replay_buffer() -> None:
    full = make_env("altitude", "volantex_ranger", num_envs=8, seed=2)
    lean = make_env("altitude", "volantex_ranger", num_envs=8, seed=2, lean=True)
    def hold(td):
        return td.set("action", torch.zeros(8, 2))

    a = full.rollout(10, hold, break_when_any_done=False)
    b = lean.rollout(10, hold, break_when_any_done=False)
    assert set(b["next"].keys()) == {"observation", "termination_reason", "reward", "done", "terminated",
                                     "truncated"}
    assert torch.equal(a["next", "observation"], b["next", "observation"])  # the same flight
    buffer = ReplayBuffer(storage=LazyTensorStorage(1000))
    buffer.extend(b.reshape(-1))
    assert len(buffer) == 80
    check_env_specs(lean)
    per_step = sum(v.element_size() * v[0].numel() for v in b.reshape(-1).values(True, True))
    full_step = sum(v.element_size() * v[0].numel() for v in a.reshape(-1).values(True, True))
    assert per_step < full_step / 3


def test_flat_scalars_gives_the_series_the_metrics_read() -> None:
    env = make_env("altitude", "volantex_ranger", num_envs=2, seed=3)
    td = env.rollout(4, break_when_any_done=False)
    flat = flat_scalars(td)
    assert flat["next", "state", "height"].shape == (2, 4)
    assert flat["next", "state", "throttle"].shape == (2, 4, 1)  # per-motor entries keep their dim
    assert flat["next", "task", "target_altitude"].shape == (2, 4)
    assert td["next", "state", "height"].shape == (2, 4, 1)  # a copy: the rollout is untouched


def test_normalize_sets_up_observation_norm_on_the_env() -> None:
    env = make_env("altitude", "volantex_ranger", num_envs=16, seed=4, normalize=True)
    check_env_specs(env)
    norm = env.transform[-1]
    assert norm.loc.shape == norm.scale.shape == (env.observation_spec["observation"].shape[-1],)
    assert (norm.scale >= 1e-2).all()


@pytest.mark.parametrize("task", task_names())
def test_the_env_defaults_are_the_task_records(task: str) -> None:
    spec = task_spec(task)
    env = make_env(task, "volantex_ranger", num_envs=1, seed=0)
    assert env.config.decimation == spec.env_default("decimation", 1)
    for name, value in spec.defaults.items():
        if hasattr(env.task.config, name):
            assert getattr(env.task.config, name) == value, name
    overridden = make_env(task, "volantex_ranger", num_envs=1, seed=0, decimation=1)
    assert overridden.control_dt == pytest.approx(0.01)


def test_the_training_env_of_the_altitude_task_is_the_default_env() -> None:
    env = make_env("altitude", "volantex_ranger", num_envs=1, seed=0)
    config = env.task.config
    assert env.config.decimation == 5 and config.survival_bonus == 1.0 and config.w_overshoot == 0.0
    assert config.sigma_altitude == 6.0
