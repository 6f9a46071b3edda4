"""The attitude task's off-policy training defaults: on the Volantex Ranger SAC and TD3 share one recipe
(the sharper bank Gaussian and the best of the validations every 50 k frames), with which every seed of
both met the controller issue's 3.0 deg; on the Airship V7 they keep the task's own term and the last
weights, which is what reproduces the V7's shipped files."""

from __future__ import annotations

import falcon_rl  # noqa: F401  (registers the shipped tasks)
from falcon_rl.envs.tasks import task_spec


def test_ranger_sac_and_td3_attitude_share_the_sharper_bank_term_and_the_choice_of_snapshot() -> None:
    spec = task_spec("attitude")
    sac, td3 = (spec.training_defaults(algorithm, "volantex_ranger") for algorithm in ("sac", "td3"))
    assert sac == td3
    assert sac["env_options"]["sigma_bank"] < spec.default_config().sigma_bank
    assert sac["keep_best"] is True and sac["eval_every"] == 50_000
    sac["env_options"]["sigma_bank"] = 1.0  # a fresh copy: a run's config never shares the recipe's dict
    assert spec.training_defaults("td3", "volantex_ranger")["env_options"]["sigma_bank"] < 1.0


def test_v7_off_policy_attitude_keeps_the_tasks_term_and_the_last_weights() -> None:
    spec = task_spec("attitude")
    for algorithm in ("sac", "td3"):
        v7 = spec.training_defaults(algorithm, "airship_v7")
        assert "env_options" not in v7 and not v7.get("keep_best"), (algorithm, v7)


def test_ranger_ppo_attitude_trains_in_medium_turbulence_with_the_sharper_bank_term() -> None:
    spec = task_spec("attitude")
    ppo = spec.training_defaults("ppo", "volantex_ranger")
    assert ppo["env_options"] == {"sigma_bank": 0.075, "turbulence": "medium"}
    assert spec.training_defaults("sac", "volantex_ranger")["env_options"] == {"sigma_bank": 0.075}
    from falcon_rl.recipes.common import make_train_env
    from falcon_rl.recipes.ppo import make_config

    env = make_train_env(make_config("attitude", airframe="volantex_ranger", num_envs=2, out=None))
    assert env.base_env.config.turbulence == "medium" and env.base_env.task.config.sigma_bank == 0.075
