"""The altitude task's off-policy training episodes reach the hold on every reference airframe: the
longest ramp (offset_max / climb-rate limit) plus ``hold_seconds`` fits in one episode. On the Airship
V7 (0.83 m/s) 20 s episodes ended on the ramp and SAC never learned to hold (RMSE 1.39 m)."""

from __future__ import annotations

import pytest

import falcon_rl  # noqa: F401  (registers the shipped tasks)
from falcon_rl.airframe import load_airframe
from falcon_rl.envs.tasks import task_spec


@pytest.mark.parametrize("algorithm", ["sac", "td3"])
@pytest.mark.parametrize("airframe", ["airship_v7", "volantex_ranger"])
def test_off_policy_episodes_cover_the_longest_ramp_and_the_hold(algorithm: str, airframe: str) -> None:
    spec = task_spec("altitude")
    config = spec.default_config()
    training = spec.training_defaults(algorithm, airframe)
    ramp = config.offset_max / load_airframe(airframe).envelope.climb_rate_limit
    assert training["episode_seconds"] >= ramp + config.hold_seconds, (airframe, ramp, training)


def test_v7_off_policy_defaults_differ_from_the_rangers_only_in_episodes_frames_and_airspeed_weight() -> None:
    spec = task_spec("altitude")
    for algorithm in ("sac", "td3"):
        v7 = spec.training_defaults(algorithm, "airship_v7")
        ranger = spec.training_defaults(algorithm, "volantex_ranger")
        differing = {k for k in v7.keys() | ranger.keys() if v7.get(k) != ranger.get(k)}
        assert differing <= {"episode_seconds", "frames", "env_options"}, (algorithm, differing)
        assert v7["episode_seconds"] > ranger["episode_seconds"]
    heavier = {"w_airspeed": 2.0}
    assert heavier["w_airspeed"] > spec.default_config().w_airspeed
    assert spec.training_defaults("td3", "airship_v7")["env_options"] == heavier
    assert spec.training_defaults("sac", "volantex_ranger")["env_options"] == heavier
    # SAC on the V7 keeps the airspeed weight 0.5 and adds the energy-rate penalty
    assert spec.training_defaults("sac", "airship_v7")["env_options"] == {"w_energy_rate": 0.5}
    assert spec.default_config().w_energy_rate == 0.0  # the paper's reward
    assert "env_options" not in spec.training_defaults("td3", "volantex_ranger")


def test_v7_td3_env_options_build_the_training_env() -> None:
    from falcon_rl.recipes.common import make_train_env
    from falcon_rl.recipes.td3 import make_config

    cfg = make_config("altitude", airframe="airship_v7", num_envs=2, out=None)
    env = make_train_env(cfg)
    assert env.base_env.task.config.w_airspeed == 2.0
    assert env.base_env.task.config.survival_bonus == 1.0  # the task's training defaults stay underneath


def test_v7_sac_trains_with_the_energy_rate_penalty_and_scores_without() -> None:
    from falcon_rl.envs import make_env
    from falcon_rl.recipes.common import make_train_env
    from falcon_rl.recipes.sac import make_config

    cfg = make_config("altitude", airframe="airship_v7", num_envs=2, out=None)
    config = make_train_env(cfg).base_env.task.config
    assert (config.w_energy_rate, config.w_airspeed, config.episode_seconds) == (0.5, 0.5, 40.0)
    assert make_env("altitude", "airship_v7", num_envs=1).task.config.w_energy_rate == 0.0


def test_env_options_given_merge_into_the_recipes() -> None:
    from falcon_rl.recipes.td3 import make_config

    cfg = make_config("altitude", airframe="airship_v7", env_options={"decimation": 4})
    assert cfg.env_options == {"w_airspeed": 2.0, "decimation": 4}
    cfg = make_config("altitude", airframe="airship_v7", env_options={"w_airspeed": 0.5})
    assert cfg.env_options == {"w_airspeed": 0.5}


def test_v7_ppo_trains_on_near_target_starts_and_covers_the_longest_ramp() -> None:
    spec = task_spec("altitude")
    config = spec.default_config()
    training = spec.training_defaults("ppo", "airship_v7")
    ramp = config.offset_max / load_airframe("airship_v7").envelope.climb_rate_limit
    assert training["episode_seconds"] >= ramp + config.hold_seconds
    assert training["env_options"] == {"offset_min": 0.0}
    assert "env_options" not in spec.training_defaults("ppo", "volantex_ranger")


def test_v7_ppo_training_starts_span_the_target_while_the_protocol_keeps_the_papers_offsets(
        monkeypatch: pytest.MonkeyPatch) -> None:
    from falcon_rl.envs import make_env
    from falcon_rl.evaluation import protocols
    from falcon_rl.recipes.common import make_actor_net, make_train_env
    from falcon_rl.recipes.evaluate import evaluate
    from falcon_rl.recipes.ppo import make_config

    cfg = make_config("altitude", airframe="airship_v7", num_envs=512, out=None)
    env = make_train_env(cfg)
    env.reset()
    task = env.base_env.task
    offsets = (task.initial_altitude - task.target).abs()
    assert float(offsets.min()) < 3.0 and float(offsets.max()) <= 18.0
    protocol = make_env("altitude", "airship_v7", num_envs=512, seed=0)
    td = protocol.reset()
    paper = (td["task", "initial_altitude"] - td["task", "target_altitude"]).abs()
    assert float(paper.min()) >= 12.0 and float(paper.max()) <= 18.0

    # The validation and the test fly the protocol's env: none of the training env options reach it.
    built: dict = {}

    class BuiltError(Exception):
        pass

    def record(*args, **kwargs):
        built.update(kwargs)
        raise BuiltError

    monkeypatch.setattr(protocols, "make_env", record)
    with pytest.raises(BuiltError):
        evaluate(make_actor_net(cfg, env, scale="param"), cfg, "ppo", episodes=2)
    assert "offset_min" not in built and built["num_envs"] == 2
