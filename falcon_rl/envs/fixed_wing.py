"""FixedWingEnv: a batch-locked TorchRL environment over the :class:`Simulator`, one flight task.

    env = FixedWingEnv(FixedWingEnvConfig(task="altitude", airframe="navion", num_envs=1024))
    td = env.reset()                                # batch [N]
    td = env.rand_step(td)                          # td["next", "observation"], ...

Keys (batch [N]):
    observation              [N, D] float, the task's scaled and clipped observation
    action                   [N, A] in [-1, 1]
    ("state", name)          true simulator state (height [N], euler [N, 3], ...): for metrics and
                             privileged critics; sensors and delays act on "observation" only
    ("task", name)           the task's references and tracking errors ([N] or [N, k])
    reward                   [N, 1]
    done, terminated, truncated  [N, 1] bool (terminated: crash or stall; truncated: horizon)

The env only uses the Simulator facade (reset / step / state), so it runs on any backend and device
the Simulator supports. One env step is ``decimation`` physics steps of ``dt`` under the same
command; the state is read once per env step.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.data import Bounded, Categorical, Composite, Unbounded
from torchrl.envs import EnvBase

from ..airframe import Airframe, load_airframe
from ..physics import Simulator
from ..physics.wind import TurbulenceConfig
from ..transforms.presets import nominal_height, resolve_turbulence
from .tasks import TASKS, TaskConfig

#: Fields of ``Simulator.state`` published under ("state", ...).
STATE_KEYS: tuple[str, ...] = (
    "position_ned", "quaternion", "euler", "velocity_body", "velocity_ned", "angular_rate_body",
    "airspeed", "alpha", "beta", "height", "surface_position", "surface_rate", "throttle", "thrust", "time",
    "ground_contact",
)


@dataclass
class FixedWingEnvConfig:
    """Everything that builds a :class:`FixedWingEnv` (Isaac-Lab style config next to its env)."""

    #: Task name, one of ``falcon_rl.envs.tasks.TASKS``.
    task: str = "altitude"
    #: Shipped airframe name or JSON path.
    airframe: str = "navion"
    num_envs: int = 1
    #: Simulator backend: "torch" or "warp" (the scipy reference runs one env; it works too).
    backend: str = "torch"
    device: str = "cpu"
    seed: int = 0
    #: Physics step, s (the paper integrates at 10 ms).
    dt: float = 0.01
    #: Physics steps per env step (control period = decimation x dt).
    decimation: int = 1
    integrator: str = "rk4"
    #: True / "induced", "paper" or False.
    ground_effect: bool | str = True
    #: Steady wind in NED, m/s.
    wind: tuple[float, float, float] | None = None
    #: Dryden turbulence: None (off), a MIL severity ("very_light", "light", "moderate", "severe"),
    #: a robustness-grid name ("mild", "medium"), a float sigma_u / V_a at the task's trim airspeed
    #: and nominal height, or a TurbulenceConfig (see ``falcon_rl.transforms.presets``).
    turbulence: str | float | TurbulenceConfig | None = None
    #: The task's config; None takes the task's defaults.
    task_config: TaskConfig | None = field(default=None)


class FixedWingEnv(EnvBase):
    """Batched fixed-wing flight task as a TorchRL environment (batch-locked, batch [N])."""

    batch_locked = True

    def __init__(self, config: FixedWingEnvConfig | None = None, airframe: Airframe | None = None):
        config = config or FixedWingEnvConfig()
        if config.task not in TASKS:
            raise ValueError(f"unknown task {config.task!r}; choose one of {sorted(TASKS)}")
        if config.decimation < 1:
            raise ValueError(f"decimation must be >= 1, got {config.decimation}")
        device = torch.device(config.device)
        super().__init__(batch_size=torch.Size([config.num_envs]), device=device)
        self.config = config
        self.airframe = airframe or load_airframe(config.airframe)
        task_cls, config_cls = TASKS[config.task]
        task_config = config.task_config if config.task_config is not None else config_cls()
        trim_airspeed = task_config.trim_airspeed or self.airframe.envelope.cruise_speed
        turbulence = resolve_turbulence(config.turbulence, trim_airspeed, nominal_height(task_config))
        self.sim = Simulator(self.airframe, num_envs=config.num_envs, backend=config.backend,
                             device=device, dt=config.dt, integrator=config.integrator,
                             ground_effect=config.ground_effect,
                             wind=None if config.wind is None else list(config.wind),
                             turbulence=turbulence, seed=config.seed)
        self.generator = torch.Generator(device=device)
        self.env_dt = config.dt * config.decimation
        self.task = task_cls(task_config, self.sim, self.generator, self.env_dt, config.ground_effect)
        self.max_episode_steps = max(1, round(self.task.episode_seconds / self.env_dt))
        self.step_count = torch.zeros(config.num_envs, dtype=torch.long, device=device)
        self._set_seed(config.seed)
        self._make_specs()

    # ------------------------------------------------------------------ specs
    def _make_specs(self) -> None:
        n, task, dev = self.config.num_envs, self.task, self.device
        state = self.sim.state
        state_spec = Composite(
            {key: (Categorical(2, shape=state[key].shape, dtype=torch.bool, device=dev)
                   if state[key].dtype == torch.bool
                   else Unbounded(shape=state[key].shape, dtype=state[key].dtype, device=dev))
             for key in STATE_KEYS},
            shape=(n,), device=dev)
        task_spec = Composite(
            {key: Unbounded(shape=(n, *shape), dtype=self.sim.dtype, device=dev)
             for key, shape in task.info_shapes().items()},
            shape=(n,), device=dev)
        clip = task.observation_clip
        self.observation_spec = Composite(
            observation=Bounded(-clip, clip, shape=(n, task.observation_dim), dtype=self.sim.dtype,
                                device=dev),
            state=state_spec, task=task_spec, shape=(n,), device=dev)
        self.action_spec = Bounded(-1.0, 1.0, shape=(n, task.action_dim), dtype=self.sim.dtype, device=dev)
        self.reward_spec = Unbounded(shape=(n, 1), dtype=self.sim.dtype, device=dev)
        self.done_spec = Composite(
            {key: Categorical(2, shape=(n, 1), dtype=torch.bool, device=dev)
             for key in ("done", "terminated", "truncated")},
            shape=(n,), device=dev)

    # ------------------------------------------------------------------ EnvBase API
    def _set_seed(self, seed: int | None) -> None:
        if seed is None:
            seed = int(torch.randint(0, 2**62, (1,)).item())
        seed = int(seed) % (2**62)
        self.generator.manual_seed(seed)
        self.sim.reseed(seed + 1)

    def _reset(self, tensordict: TensorDictBase | None = None, **kwargs) -> TensorDictBase:
        n = self.config.num_envs
        mask = None if tensordict is None else tensordict.get("_reset", None)
        if mask is None:
            mask = torch.ones(n, dtype=torch.bool, device=self.device)
        mask = mask.reshape(n).to(self.device)
        initial = self.task.sample_initial(mask)
        state = self.sim.reset(initial, mask=mask)
        if not isinstance(state, TensorDictBase):
            state = self.sim.state
        self.step_count.masked_fill_(mask, 0)
        self.task.after_reset(state, mask)
        no = torch.zeros(n, 1, dtype=torch.bool, device=self.device)
        return self._output(self.task.observe(state), state, no, no, reward=None)

    def observe(self, state: TensorDictBase) -> torch.Tensor:
        """[N, D] observation the task makes of ``state`` (e.g. a measured one) with its current
        buffers, without side effects (the sensor transform's hook)."""
        return self.task.observe(state)

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        action = tensordict.get("action")
        command = self.task.command(action)
        for _ in range(self.config.decimation):
            self.sim.step(command)
        state = self.sim.state
        observation, reward, terminated = self.task.step(state, action)
        self.step_count += 1
        truncated = self.step_count >= self.max_episode_steps
        return self._output(observation, state, terminated.unsqueeze(-1), truncated.unsqueeze(-1),
                            reward=reward.unsqueeze(-1))

    def _output(self, observation: torch.Tensor, state: TensorDictBase, terminated: torch.Tensor,
                truncated: torch.Tensor, reward: torch.Tensor | None) -> TensorDictBase:
        truncated = truncated & ~terminated
        out = {
            "observation": observation,
            "state": state.select(*STATE_KEYS),
            "task": self.task.info(),
            "terminated": terminated,
            "truncated": truncated,
            "done": terminated | truncated,
        }
        if reward is not None:
            out["reward"] = reward
        return TensorDict(out, batch_size=self.batch_size, device=self.device)
