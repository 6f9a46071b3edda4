"""The task registry: one TaskSpec per task, found from its name by make_env, Gymnasium, the controller
lookup, the evaluation harness, the report, the recipes and ``falcon-rl eval``; a task defined here,
outside the package, registers all of it."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass

import gymnasium as gym
import pytest
import torch
from tensordict import TensorDictBase
from torchrl.envs.utils import check_env_specs

import falcon_rl  # noqa: F401  (registers the shipped tasks and their gym ids)
from falcon_rl.cli import main
from falcon_rl.envs import make_env, register_gym_envs
from falcon_rl.envs.tasks import (
    TASK_SPECS,
    TRIM_HOLD,
    Metric,
    Task,
    TaskConfig,
    TaskSpec,
    register_task,
    resolve,
    task_names,
    task_spec,
    unregister_task,
)
from falcon_rl.evaluation.controllers import make_controller
from falcon_rl.evaluation.metrics import first_episode_mask, rmse, survival
from falcon_rl.evaluation.protocols import ProtocolResult, tracking_protocol
from falcon_rl.evaluation.report import write_report
from falcon_rl.recipes import algorithm

SHIPPED = ("altitude", "attitude", "climb_descend", "path_following", "trajectory", "sea_skimming", "landing")
TOY = "toy_hold"
TOY_GYM_ID = "falcon_rl_test/ToyHold-v0"


# ------------------------------------------------------------------------------------------ toy task
@dataclass
class ToyConfig(TaskConfig):
    """Hold ``height`` with the throttle alone (elevator, aileron, rudder at trim)."""

    episode_seconds: float = 0.5
    height: float = 50.0


class ToyTask(Task):
    """Observation [e_h / 10, V_a / cruise - 1]; action [throttle]; reward -e_h^2."""

    name = TOY
    observation_dim = 2
    action_dim = 1
    observation_clip = 5.0
    action_channels = (3,)
    config: ToyConfig

    def __init__(self, config, sim, generator, control_dt, ground_effect=True):
        super().__init__(config, sim, generator, control_dt, ground_effect)
        self.height_error = torch.zeros(self.num_envs, device=self.device, dtype=self.dtype)

    def sample_initial(self, mask: torch.Tensor) -> dict[str, torch.Tensor]:
        height = torch.full((self.num_envs,), self.config.height, device=self.device, dtype=self.dtype)
        return {**self.trim_initial(), "height": height}

    def after_reset(self, state: TensorDictBase, mask: torch.Tensor) -> None:
        super().after_reset(state, mask)
        self.update(state)

    def update(self, state: TensorDictBase) -> None:
        self.height_error.copy_(state["height"] - self.config.height)

    def observe(self, state: TensorDictBase) -> torch.Tensor:
        obs = torch.stack([(state["height"] - self.config.height) / 10.0,
                           state["airspeed"] / self.trim_airspeed - 1.0], dim=-1)
        return obs.clamp(-self.observation_clip, self.observation_clip)

    def reward(self, state: TensorDictBase, action: torch.Tensor) -> torch.Tensor:
        return -self.height_error**2

    def info(self) -> dict[str, torch.Tensor]:
        return {"height_error": self.height_error.clone()}


def toy_metrics(rollout: TensorDictBase) -> dict[str, torch.Tensor]:
    nxt = rollout["next"]
    valid = first_episode_mask(nxt["done"])
    return {"survival": survival(nxt["terminated"], valid),
            "height_rmse_m": rmse(nxt["state", "height"] - ToyConfig.height, valid)}


def toy_protocol(airframe, controller, factory, episodes=2, seed=0, backend="torch", device="cpu",
                 episode_seconds=None, **env_options) -> ProtocolResult:
    return tracking_protocol(TOY, toy_metrics, (("next", "state", "height"),), airframe, controller, factory,
                             episodes, seed, backend, device, episode_seconds, **env_options)


def toy_figure(result: ProtocolResult, path):
    path.write_text(f"{result.task}: {result.summary}")
    return path


TOY_SPEC = TaskSpec(
    name=TOY, task=ToyTask, config=ToyConfig, gym_id=TOY_GYM_ID, title="Toy height hold",
    protocol=f"{__name__}:toy_protocol",  # a lazy reference, resolved at use
    metrics=(Metric("survival", "Surv."), Metric("height_rmse_m", "h RMSE", "m")),
    controllers={"trim": TRIM_HOLD}, figure=toy_figure,
    training={"ppo": {"num_envs": 4, "env_options": {"decimation": 2}}},
    airframe_training={"airship_v7": {"ppo": {"num_envs": 8}}},
)


@pytest.fixture
def toy_task():
    spec = register_task(TOY_SPEC)
    register_gym_envs()
    yield spec
    unregister_task(TOY)
    gym.registry.pop(TOY_GYM_ID, None)


# ------------------------------------------------------------------------------------------ tests
def test_shipped_tasks_are_registered_with_everything() -> None:
    assert set(SHIPPED) <= set(task_names())
    for name in SHIPPED:
        spec = task_spec(name)
        assert spec.task.name == name
        assert spec.gym_id in gym.registry and spec.title and spec.metrics
        assert "trim" in spec.controllers and callable(spec.protocol_function())
        assert callable(spec.figure_function())
        for controller in spec.controllers:
            assert callable(spec.controller(controller))
    assert set(task_spec("climb_descend").controllers) == {"lqr", "mppi", "trim"}
    guided = {"guided-lqr", "guided-l1-lqr", "guided-ppo", "guided-l1-ppo"}
    for name in ("path_following", "trajectory"):
        assert set(task_spec(name).controllers) == {"trim", *guided}


def test_toy_task_is_reached_from_its_name(toy_task, tmp_path, capsys) -> None:
    assert TASK_SPECS[TOY] is toy_task and (toy_task.task, toy_task.config) == (ToyTask, ToyConfig)
    env = make_env(TOY, "volantex_ranger", num_envs=2, seed=1, height=40.0)
    check_env_specs(env)
    assert env.task.config.height == 40.0 and env.action_spec.shape == (2, 1)

    gym_env = gym.make(TOY_GYM_ID, airframe="volantex_ranger")
    obs, info = gym_env.reset(seed=0)
    assert obs.shape == (2,) and info["height_error"] == pytest.approx(0.0, abs=1e-3)
    obs, reward, terminated, _, info = gym_env.step(gym_env.action_space.sample())
    assert isinstance(reward, float) and not terminated

    result = toy_task.protocol_function()("volantex_ranger", "trim", lambda e: make_controller("trim", e),
                                          episodes=2, backend="warp")
    assert result.task == TOY and result.summary["survival"] == 1.0
    assert result.summary["height_rmse_m"] < 0.5  # trim holds the height for half a second
    report = write_report([result], tmp_path, [], "toy").read_text()
    assert "## Toy height hold" in report and "h RMSE (m)" in report

    code = main(["eval", "--task", TOY, "--controller", "trim", "--episodes", "2", "--seconds", "0.2",
                 "--backend", "warp", "--out", str(tmp_path / "cli"), "--json"])
    out, _ = capsys.readouterr()
    doc = json.loads(out)
    assert code == 0 and doc["task"] == TOY and doc["survival"] == 1.0
    assert (tmp_path / "cli" / f"{TOY}_volantex_ranger_trim.png").read_text().startswith(TOY)

    with pytest.raises(ValueError, match=r"controller 'lqr' does not apply to task 'toy_hold'.*\['trim'\]"):
        make_controller("lqr", env)
    cfg = algorithm("ppo").make_config(TOY, frames=1000)
    assert (cfg.num_envs, cfg.env_options, cfg.frames) == (4, {"decimation": 2}, 1000)
    # an airframe's own training defaults go on top of the task's; the flags go on top of both
    cfg = algorithm("ppo").make_config(TOY, airframe="airship_v7")
    assert (cfg.num_envs, cfg.env_options) == (8, {"decimation": 2})
    assert algorithm("ppo").make_config(TOY, airframe="airship_v7", num_envs=2).num_envs == 2
    assert toy_task.training_defaults("ppo", "navion") == {"num_envs": 4, "env_options": {"decimation": 2}}


def test_toy_task_is_gone_after_unregistering(toy_task) -> None:
    unregister_task(TOY)
    assert TOY not in TASK_SPECS and TOY not in task_names()
    with pytest.raises(ValueError, match="unknown task 'toy_hold'"):
        make_env(TOY, "volantex_ranger")
    register_task(TOY_SPEC)  # the fixture's teardown unregisters it again


def test_registry_errors() -> None:
    with pytest.raises(ValueError) as info:
        task_spec("nope")
    message = str(info.value)
    assert "unknown task 'nope'" in message and "altitude" in message and "\n" not in message
    with pytest.raises(ValueError, match="already registered"):
        register_task(task_spec("altitude"))
    clash = TaskSpec(name="other", task=ToyTask, config=ToyConfig, gym_id=task_spec("altitude").gym_id,
                     title="clash")
    with pytest.raises(ValueError, match="is taken by 'altitude'"):
        register_task(clash)
    with pytest.raises(ValueError, match="unknown recipes"):
        TaskSpec(name="bad", task=ToyTask, config=ToyConfig, gym_id="x/Bad-v0", title="bad",
                 training={"dqn": {}})
    with pytest.raises(ValueError, match=r"unknown recipes \['dqn'\]"):
        TaskSpec(name="bad", task=ToyTask, config=ToyConfig, gym_id="x/Bad-v0", title="bad",
                 airframe_training={"navion": {"dqn": {}}})
    with pytest.raises(ValueError, match=r"package\.module:attribute"):
        resolve("falcon_rl.evaluation.protocols")
    assert resolve("falcon_rl.baselines.lqr:AltitudeLQR.from_env").__name__ == "from_env"
    with pytest.raises(ValueError, match="no evaluation protocol"):
        bare = TaskSpec(name="bare", task=ToyTask, config=ToyConfig, gym_id="x/Bare-v0", title="bare")
        bare.protocol_function()
    with pytest.raises(TypeError):
        task_spec("altitude").controllers["lqr"] = "x:y"  # read-only


@pytest.mark.parametrize("task", SHIPPED)
def test_every_protocol_runs_with_trim(task: str) -> None:
    """Two short episodes of each task's protocol with "trim" (10 Hz control keeps it fast): every
    metric the spec lists is in the summary, survival is a fraction and the errors are finite."""
    spec = task_spec(task)
    seconds = 2.0 if task == "attitude" else 16.0  # past the intercept windows of path and trajectory
    result = spec.protocol_function()("volantex_ranger", "trim", lambda env: make_controller("trim", env),
                                      episodes=2, seed=0, backend="warp", episode_seconds=seconds,
                                      decimation=10)
    assert result.task == task and result.settings["episodes"] == 2
    keys = {key.split("/")[-1] for key in result.summary}
    assert {m.key for m in spec.metrics} <= keys
    assert all(0.0 <= v <= 1.0 for k, v in result.summary.items() if k.endswith("survival"))
    if task in ("sea_skimming", "landing"):  # trim meets the water or the runway: tests/test_<task>.py fly
        return                                # their baselines through the protocols
    errors = [v for k, v in result.summary.items() if "rmse" in k]
    assert errors and any(math.isfinite(v) for v in errors)


def test_controllers_that_do_not_apply_name_the_ones_that_do() -> None:
    env = make_env("path_following", "volantex_ranger", num_envs=1)
    for name in ("lqr", "mppi"):
        with pytest.raises(ValueError, match=r"does not apply to task 'path_following'.*\['guided-l1-lqr', "
                                             r"'guided-l1-ppo', 'guided-lqr', 'guided-ppo', 'trim'\]"):
            make_controller(name, env)
    from falcon_rl.baselines.lqr import AltitudeLQR
    from falcon_rl.baselines.mppi import MPPI, MPPIConfig

    assert task_spec("climb_descend").controller("lqr") == AltitudeLQR.from_env
    with pytest.raises(ValueError, match="MPPI tracks one of"):
        MPPI(env, MPPIConfig(samples=2))
    climb = make_env("climb_descend", "volantex_ranger", num_envs=1)
    assert MPPI(climb, MPPIConfig(samples=2, horizon_seconds=0.5)).tracks == "altitude"


def test_policies_fly_their_own_task_or_a_derived_one(tmp_path) -> None:
    from falcon_rl.policies import shipped_policy
    from falcon_rl.policies.format import seal

    altitude_policy = shipped_policy("altitude", "volantex_ranger")
    climb = make_env("climb_descend", "volantex_ranger", num_envs=1)
    assert make_controller(str(altitude_policy), climb).meta["task"] == "altitude"  # the same MDP
    document = torch.load(altitude_policy, map_location="cpu", weights_only=True)
    document["meta"]["task"] = "climb_descend"  # same sizes, but altitude does not derive from it
    torch.save(seal(document), tmp_path / "climb.pt")  # re-sealed: the edit alone fails the checksum
    altitude = make_env("altitude", "volantex_ranger", num_envs=1)
    with pytest.raises(ValueError, match="a policy of task 'climb_descend' does not fly task 'altitude'"):
        make_controller(str(tmp_path / "climb.pt"), altitude)
