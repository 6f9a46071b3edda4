"""The flight-env interface (FixedWingEnv's docstring): its members on FixedWingEnv, and the transforms
and recipe helpers over a minimal base env that implements just that interface."""

from __future__ import annotations

from collections.abc import Iterable

import pytest
import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.data import Bounded, Categorical, Composite, Unbounded
from torchrl.envs import Compose, EnvBase, RewardSum, TransformedEnv
from torchrl.envs.utils import check_env_specs, step_mdp

from falcon_rl import make_env
from falcon_rl.envs.fixed_wing import RANDOMISABLE_PARAMETERS
from falcon_rl.recipes.common import stagger_episodes, trim_action
from falcon_rl.transforms import (
    FLIGHT_ENV_INTERFACE,
    ActionDelay,
    DomainRandomization,
    ObservationDelay,
    RandomizationConfig,
    SensorChannel,
    SensorConfig,
    SensorTransform,
    flight_env,
)

N = 4


# ------------------------------------------------------------------------------ FixedWingEnv
def test_fixed_wing_env_provides_the_interface() -> None:
    env = make_env("altitude", num_envs=N, decimation=2, sensors="mild")
    base = env.base_env
    assert flight_env(env) is base and flight_env(base) is base
    assert all(hasattr(base, name) for name in FLIGHT_ENV_INTERFACE)
    assert base.control_dt == pytest.approx(0.02) and not hasattr(base, "env_" + "dt")
    td = env.reset()
    observation = base.observe(td["measured"])
    assert observation.shape == (N, base.task.observation_dim) and torch.equal(observation, td["observation"])


@pytest.mark.parametrize("task", ["altitude", "attitude"])
def test_trim_action_is_the_trim_command_in_the_action_channels(task: str) -> None:
    env = make_env(task, num_envs=N)
    trim = env.trim_action()
    assert trim.shape == env.action_spec.shape[-1:]
    assert torch.equal(trim, env.task.trim.command[list(env.task.action_channels)])
    assert torch.equal(trim_action(TransformedEnv(env, RewardSum())), trim.float())


def test_set_physical_parameters_writes_only_the_masked_rows() -> None:
    env = make_env("altitude", num_envs=N)
    before = env.physical_parameters()
    assert set(before) == set(RANDOMISABLE_PARAMETERS) - {"turbulence_w20"}
    mask = torch.tensor([True, False, True, False])
    inertia = 2.0 * before["inertia"][0]  # one row for every env
    env.set_physical_parameters(mask, mass=torch.full((N,), 3.0), inertia=inertia,
                                wind_ned=torch.tensor([1.0, -2.0, 0.0]))
    after = env.physical_parameters(["mass", "inertia", "wind_ned", "chord"])
    assert (after["mass"][mask] == 3.0).all() and torch.equal(after["mass"][~mask], before["mass"][~mask])
    assert torch.equal(after["inertia"][mask], inertia.expand(2, 3, 3))
    assert torch.equal(after["inertia"][~mask], before["inertia"][~mask])
    assert torch.equal(after["wind_ned"][mask], torch.tensor([[1.0, -2.0, 0.0]] * 2))
    assert (after["wind_ned"][~mask] == 0).all()
    p = env.sim.params  # the physics API stays the one that is written
    assert torch.allclose(p.inertia_inv[mask] @ p.inertia[mask], torch.eye(3).expand(2, 3, 3), atol=1e-5)
    nominal = env.nominal_physical_parameters(["mass", "chord"])
    assert torch.equal(nominal["mass"], before["mass"]) and torch.equal(nominal["chord"], after["chord"])
    after["mass"].zero_()  # copies: the env is untouched
    assert (env.physical_parameters(["mass"])["mass"][mask] == 3.0).all()


@pytest.mark.parametrize(("values", "message"), [
    ({"wingspan": torch.ones(N)}, "'wingspan' is unknown"),
    ({"gravity": torch.ones(N)}, "'gravity' is not randomisable"),
    ({"mass": torch.ones(N + 1)}, r"mass must have shape \[4\] or \[\], got \[5\]"),
    ({"turbulence_w20": torch.ones(N)}, "needs turbulence on"),
])
def test_set_physical_parameters_rejects_bad_names_and_shapes(values: dict, message: str) -> None:
    env = make_env("altitude", num_envs=N)
    before = env.physical_parameters()
    with pytest.raises(ValueError, match=message):
        env.set_physical_parameters(None, wind_ned=torch.ones(3), **values)
    after = env.physical_parameters()
    assert all(torch.equal(after[k], before[k]) for k in before)  # nothing written
    with pytest.raises(ValueError, match="is unknown"):
        env.physical_parameters(["wingspan"])


def test_episode_step_staggering_is_respected_by_truncation() -> None:
    env = make_env("altitude", num_envs=N, episode_seconds=0.1, decimation=1)  # 10 steps of 10 ms
    assert env.max_episode_steps == 10
    td = env.reset()
    env.set_episode_step(8, mask=torch.tensor([True, False, False, False]))
    env.set_episode_step(torch.tensor([8, 3, 5, 0]), mask=torch.tensor([False, True, False, True]))
    assert torch.equal(env.episode_step, torch.tensor([8, 3, 0, 0]))
    env.episode_step.fill_(7)  # a copy
    assert torch.equal(env.episode_step, torch.tensor([8, 3, 0, 0]))
    td["action"] = env.trim_action().expand(N, -1)
    for expected in ([False] * 4, [True, False, False, False]):
        td = env.step(td)
        assert td["next", "truncated"].squeeze(-1).tolist() == expected
        td = step_mdp(td, keep_other=True)
        td["action"] = env.trim_action().expand(N, -1)
    with pytest.raises(ValueError, match=r"must lie in \[0, 10\)"):
        env.set_episode_step(10)
    with pytest.raises(ValueError, match="must have shape"):
        env.set_episode_step(torch.zeros(N + 1, dtype=torch.long))


def test_stagger_episodes_draws_the_same_offsets_as_before() -> None:
    env = make_env("altitude", num_envs=64, episode_seconds=1.0, decimation=1)
    stagger_episodes(TransformedEnv(env, RewardSum()), seed=5)
    expected = torch.randint(0, 100, (64,), generator=torch.Generator().manual_seed(5))
    assert torch.equal(env.episode_step, expected)


# ------------------------------------------------------------------------------ minimal base env
_MODEL_SHAPES = {"mass": (), "inertia": (3, 3), "aero_coefficients": (4, 6), "aero_rates": (6, 3),
                 "wing_quarter_chord": (3,), "motor_position": (1, 3), "thrust_coefficient": (1,),
                 "actuator_time_constant": (3,), "actuator_natural_frequency": (3,),
                 "throttle_time_constant": (1,), "wind_ned": (3,)}
_STATE_SHAPES = {"position_ned": (3,), "velocity_ned": (3,), "quaternion": (4,), "euler": (3,),
                 "velocity_body": (3,), "angular_rate_body": (3,), "airspeed": (), "height": ()}


class PointMassCore(EnvBase):
    """A point mass flying north at 20 m/s, action [N, 2] = (climb, speed) command; no interface."""

    batch_locked = True

    def __init__(self, num_envs: int):
        super().__init__(batch_size=torch.Size([num_envs]))
        n = num_envs
        state = Composite({k: Unbounded(shape=(n, *s)) for k, s in _STATE_SHAPES.items()}, shape=(n,))
        self.observation_spec = Composite(observation=Bounded(-5.0, 5.0, shape=(n, 2)), state=state,
                                          shape=(n,))
        self.action_spec = Bounded(-1.0, 1.0, shape=(n, 2))
        self.reward_spec = Unbounded(shape=(n, 1))
        self.done_spec = Composite({k: Categorical(2, shape=(n, 1), dtype=torch.bool)
                                    for k in ("done", "terminated", "truncated")}, shape=(n,))
        self.state = TensorDict({k: torch.zeros(n, *s) for k, s in _STATE_SHAPES.items()}, batch_size=[n])
        self.steps = torch.zeros(n, dtype=torch.long)
        self.horizon = 50

    @staticmethod
    def _observation(state: TensorDictBase) -> torch.Tensor:
        return torch.stack([state["height"] / 100.0, state["airspeed"] / 20.0], -1).clamp(-5.0, 5.0)

    def _output(self, truncated: torch.Tensor, reward: torch.Tensor | None = None) -> TensorDictBase:
        done = truncated.unsqueeze(-1)
        out = {"observation": self._observation(self.state), "state": self.state.clone(),
               "terminated": torch.zeros_like(done), "truncated": done, "done": done}
        if reward is not None:
            out["reward"] = reward.unsqueeze(-1)
        return TensorDict(out, batch_size=self.batch_size)

    def _reset(self, tensordict: TensorDictBase | None = None, **kwargs) -> TensorDictBase:
        mask = None if tensordict is None else tensordict.get("_reset", None)
        rows = torch.ones(self.batch_size, dtype=torch.bool) if mask is None else mask.reshape(-1)
        fresh = {"position_ned": torch.tensor([0.0, 0.0, -100.0]), "quaternion": torch.tensor([1.0, 0, 0, 0]),
                 "velocity_ned": torch.tensor([20.0, 0, 0]), "velocity_body": torch.tensor([20.0, 0, 0]),
                 "airspeed": torch.tensor(20.0), "height": torch.tensor(100.0)}
        for key, value in fresh.items():
            self.state[key][rows] = value
        self.steps[rows] = 0
        return self._output(torch.zeros(self.batch_size, dtype=torch.bool))

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        action = tensordict["action"].clamp(-1.0, 1.0)
        s = self.state
        s["velocity_ned"] = torch.stack([20.0 + action[:, 1], 0.0 * action[:, 0], -5.0 * action[:, 0]], -1)
        s["position_ned"] = s["position_ned"] + 0.02 * s["velocity_ned"]
        s["height"], s["airspeed"] = -s["position_ned"][:, 2], 20.0 + action[:, 1]
        self.steps += 1
        return self._output(self.steps >= self.horizon, reward=-(s["height"] - 100.0).abs())

    def _set_seed(self, seed: int | None) -> None:
        return None


class PointMassFlightEnv(PointMassCore):
    """:class:`PointMassCore` with the flight-env interface and no FixedWingEnv attributes."""

    def __init__(self, num_envs: int):
        super().__init__(num_envs)
        self.nominal = {k: torch.ones(num_envs, *s) for k, s in _MODEL_SHAPES.items()}
        self.nominal["wind_ned"].zero_()
        self.values = {k: v.clone() for k, v in self.nominal.items()}
        self.reference = {"chord": torch.full((num_envs,), 1.5), "span": torch.full((num_envs,), 10.0)}
        self.max_episode_steps = self.horizon

    control_dt = 0.02

    def observe(self, state: TensorDictBase) -> torch.Tensor:
        return self._observation(state)

    def trim_action(self) -> torch.Tensor:
        return torch.tensor([0.1, 0.5])

    def physical_parameters(self, names: Iterable[str] | None = None) -> dict[str, torch.Tensor]:
        every = {**self.values, **self.reference}
        return {k: every[k].clone() for k in (self.values if names is None else names)}

    def nominal_physical_parameters(self, names: Iterable[str] | None = None) -> dict[str, torch.Tensor]:
        every = {**self.nominal, **self.reference}
        return {k: every[k].clone() for k in (self.nominal if names is None else names)}

    def set_physical_parameters(self, mask: torch.Tensor | None = None, **values: torch.Tensor) -> None:
        rows = torch.ones(self.batch_size, dtype=torch.bool) if mask is None else mask
        for name, value in values.items():
            self.values[name][rows] = value.expand_as(self.values[name])[rows]

    @property
    def episode_step(self) -> torch.Tensor:
        return self.steps.clone()

    def set_episode_step(self, values: torch.Tensor | int, mask: torch.Tensor | None = None) -> None:
        rows = torch.ones(self.batch_size, dtype=torch.bool) if mask is None else mask
        self.steps[rows] = torch.as_tensor(values).expand(self.batch_size)[rows]

    def stagger_episodes(self, generator: torch.Generator) -> None:
        self.set_episode_step(torch.randint(0, self.horizon, self.batch_size, generator=generator))

    def random_state(self) -> dict[str, torch.Tensor]:
        return {}  # deterministic: nothing to save

    def set_random_state(self, states: dict[str, torch.Tensor]) -> None:
        return None


def test_transforms_work_over_a_minimal_flight_env() -> None:
    base = PointMassFlightEnv(N)
    randomize = DomainRandomization(RandomizationConfig(wind_speed=(2.0, 6.0)), seed=1)
    sensors = SensorTransform(SensorConfig(gps_position=SensorChannel(noise_std=1.0)), seed=2)
    env = TransformedEnv(base, Compose(randomize, sensors, ObservationDelay(40.0), ActionDelay(40.0)))
    check_env_specs(env, seed=0)
    td = env.reset()
    assert torch.equal(td["applied_action"], base.trim_action().expand(N, -1))
    assert torch.equal(td["observation"], base.observe(td["measured"]))
    assert not torch.equal(td["measured", "position_ned"], td["state", "position_ned"])
    ratio = base.values["mass"] / base.nominal["mass"]
    assert ratio.min() >= 0.9 and ratio.max() <= 1.1 and ratio.std() > 0
    assert torch.equal(randomize.sampled()["mass"], base.values["mass"])
    speed = torch.linalg.vector_norm(base.values["wind_ned"], dim=-1)
    assert speed.min() >= 2.0 and speed.max() <= 6.0
    assert env.transform[3].delays.tolist() == [2] * N  # 40 ms / control_dt 20 ms
    actions = [torch.full((N, 2), 0.1 * t) for t in range(5)]
    for t, action in enumerate(actions):
        td["action"] = action
        full = env.step(td)
        expected = actions[t - 2] if t >= 2 else base.trim_action().expand(N, -1)
        assert torch.equal(full["next", "applied_action"], expected)
        td = step_mdp(full)
    stagger_episodes(TransformedEnv(base, RewardSum()), seed=3)
    assert base.episode_step.max() < base.max_episode_steps
    assert torch.equal(trim_action(env), base.trim_action())


def test_a_missing_interface_member_raises_a_clear_type_error() -> None:
    with pytest.raises(TypeError, match="PointMassCore lacks flight-env interface member"):
        flight_env(PointMassCore(N))
    env = TransformedEnv(PointMassCore(N), ActionDelay(40.0))
    with pytest.raises(TypeError, match=r"member\(s\) control_dt \(documented on falcon_rl"):
        env.reset()
    with pytest.raises(TypeError, match="trim_action"):
        trim_action(env)
    with pytest.raises(RuntimeError, match="must be appended to a TransformedEnv"):
        flight_env(ActionDelay(40.0))


@pytest.mark.parametrize("backend", ["torch", "warp"])
def test_random_state_restores_the_same_draws(backend: str) -> None:
    """Saving random_state(), flying on and restoring it replays the same episodes and gusts (what a
    resumed training run relies on)."""
    env = make_env("altitude", "volantex_ranger", num_envs=3, backend=backend, seed=5, turbulence="moderate")
    env.reset()
    saved = env.random_state()
    assert set(saved) == {"env", "sim", "turbulence"}

    def hold_trim(td: TensorDictBase) -> TensorDictBase:
        return td.set("action", env.trim_action().expand(3, -1).clone())

    first = env.rollout(40, hold_trim, break_when_any_done=False)
    env.set_random_state(saved)
    second = env.rollout(40, hold_trim, break_when_any_done=False)
    assert torch.equal(first["next", "task", "target_altitude"], second["next", "task", "target_altitude"])
    assert torch.equal(first["next", "state", "height"], second["next", "state", "height"])
    env.set_random_state(saved)
    env.reset()
    env.rollout(7, hold_trim, break_when_any_done=False)  # the draws move on without a restore
    third = env.rollout(40, hold_trim, break_when_any_done=False)
    assert not torch.equal(first["next", "state", "height"], third["next", "state", "height"])
