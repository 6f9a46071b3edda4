"""FixedWingEnv: a batch-locked TorchRL environment over the :class:`Simulator`, one flight task.

    env = FixedWingEnv(FixedWingEnvConfig(task="altitude", airframe="navion", num_envs=1024))
    td = env.reset()                                # batch [N]
    td = env.rand_step(td)                          # td["next", "observation"], ...

Keys (batch [N]; every entry has a trailing feature dim, scalars are [N, 1], as TorchRL's reward
and done, so that ``CatTensors``, ``ExcludeTransform`` and replay buffers take them as they are):
    observation              [N, D] float, the task's scaled and clipped observation
    action                   [N, A] float in [-1, 1] (see "Actions" below)
    ("state", name)          true simulator state (height [N, 1], euler [N, 3], ...): for metrics and
                             privileged critics; sensors and delays act on "observation" only
    ("task", name)           the task's references and tracking errors ([N, 1] or [N, k])
    ("reward_terms", name)   [N, 1] each named term of the reward (``Task.reward_terms``: weighted and
                             signed, they sum to "reward"); zero in a reset's output
    termination_reason       [N, 1] long, index in ``TERMINATION_REASONS`` ("none", "ground_contact",
                             "alpha_stall", "speed_stall", "lost", "non_finite") of why the env
                             terminated this step, 0 while flying
    reward                   [N, 1]
    done, terminated, truncated  [N, 1] bool (terminated: a termination reason; truncated: horizon)

``lean=True`` publishes only what a policy needs (observation, termination_reason, reward and the
done flags): 100-odd bytes per env-step in a replay buffer instead of the ~500 of the full state.

Actions: an [N, A] real floating tensor (cast to the spec's dtype); any other shape or dtype (bool,
integer, complex) or a missing "action" is refused with a one-line ValueError before anything moves
(``transforms.action_check``). +-inf and huge values are clamped to [-1, 1], and the clamped action
is what the physics, the reward's action-rate term and ``previous_action`` see. A row with a NaN is
flown at the centre command and terminated that step with reason "non_finite". Any env whose state,
derived state, observation or reward leaves the finite numbers is terminated the same way, its
outputs zeroed; the other envs are untouched, and no NaN or Inf leaves the env.

The env only uses the Simulator facade (reset / step / state), so it runs on any backend and device
the Simulator supports. One env step is ``decimation`` physics steps of ``dt`` under the same
command; the state is read once per env step.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any, ClassVar, NamedTuple

import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.data import Bounded, Categorical, Composite, Unbounded
from torchrl.envs import EnvBase

from ..airframe import Airframe, load_airframe
from ..defaults import DEFAULT_AIRFRAME, DEFAULT_BACKEND
from ..physics import Simulator
from ..physics.engine import fresh_seed, make_generator
from ..physics.params import RANDOMIZABLE_PARAMETERS
from ..physics.switches import ModelSwitches
from ..physics.wind import TurbulenceConfig
from ..transforms.action_check import refuse_bad_action
from ..transforms.presets import nominal_height, resolve_turbulence
from .layout import column, simulator_layout
from .staged_step import StagedEnvStep, finite_rows
from .tasks import TERMINATION_CODE, TERMINATION_REASONS, Task, TaskConfig, task_spec

#: Fields of ``Simulator.state`` published under ("state", ...).
STATE_KEYS: tuple[str, ...] = (
    "position_ned", "quaternion", "euler", "velocity_body", "velocity_ned", "angular_rate_body",
    "airspeed", "alpha", "beta", "height", "surface_position", "surface_rate", "throttle", "thrust", "time",
    "ground_contact",
)
#: Keys of a lean env (``lean=True``): what a policy and a replay buffer need.
LEAN_KEYS: tuple[str, ...] = ("observation", "termination_reason")
NON_FINITE = TERMINATION_CODE["non_finite"]

if TYPE_CHECKING:
    from ..physics.fused_env_step import FusedEnvStep

#: Per-env ``ModelParams`` fields that ``set_physical_parameters`` may write: the rows the physics
#: parameter table flags randomisable (``physics.params.RANDOMIZABLE_PARAMETERS``), written through
#: ``Simulator.params.assign``, which refreshes the rows derived from them.
RANDOMISABLE_MODEL_PARAMETERS: tuple[str, ...] = RANDOMIZABLE_PARAMETERS
#: Per-env atmosphere parameters that ``set_physical_parameters`` may write: steady wind [N, 3] m/s
#: NED, and Dryden W20 [N] m/s (only with turbulence on).
RANDOMISABLE_ATMOSPHERE_PARAMETERS: tuple[str, ...] = ("wind_ned", "turbulence_w20")
RANDOMISABLE_PARAMETERS: tuple[str, ...] = RANDOMISABLE_MODEL_PARAMETERS + RANDOMISABLE_ATMOSPHERE_PARAMETERS


@dataclass
class FixedWingEnvConfig:
    """Everything that builds a :class:`FixedWingEnv` (Isaac-Lab style config next to its env)."""

    #: Task name, a registered task (``falcon_rl.envs.tasks.task_spec``).
    task: str = "altitude"
    #: Shipped airframe name or JSON path.
    airframe: str = DEFAULT_AIRFRAME
    num_envs: int = 1
    #: Simulator backend: "warp" (fused kernels, the fastest on CPU and GPU) or "torch" (the
    #: differentiable reference); the scipy reference runs one env, it works too.
    backend: str = DEFAULT_BACKEND
    device: str = "cpu"
    #: Seed of every random draw of the env (episodes, turbulence); None: fresh entropy.
    seed: int | None = None
    #: Physics step, s (the paper integrates at 10 ms).
    dt: float = 0.01
    #: Physics steps per env step (control period = decimation x dt); None: the task's default
    #: (``TaskSpec.defaults``: 5, i.e. 20 Hz control, the rate the recipes train at).
    decimation: int | None = None
    integrator: str = "rk4"
    #: True / "induced", "paper" or False.
    ground_effect: bool | str = True
    #: Floating dtype of the simulation and of every float entry (torch.float32 or torch.float64; a
    #: float64 env's task step reads float32 copies of the state and its outputs are cast to float64).
    dtype: torch.dtype = torch.float32
    #: Torch backend: step through torch.compile (see ``Simulator``).
    compile: bool = False
    #: Warp backend on the CPU: threads (None: one per core, at most one per 512 envs).
    warp_cpu_threads: int | None = None
    #: Publish only observation, termination_reason, reward and done flags (lean replay buffers).
    lean: bool = False
    #: Run the task's Warp step inside the engine's one-call env step where the engine has one (the
    #: warp engine: one launch, ``Engine.fuse``); False: the engine's step, then the task's as its own
    #: launch (the same body and outputs, the staged step).
    fused: bool = True
    #: Steady wind in NED, m/s.
    wind: tuple[float, float, float] | None = None
    #: Dryden turbulence: None (off), a MIL severity ("very_light", "light", "moderate", "severe"),
    #: a robustness-grid name ("mild", "medium"), a float sigma_u / V_a at the task's trim airspeed
    #: and nominal height, or a TurbulenceConfig (see ``falcon_rl.transforms.presets``).
    turbulence: str | float | TurbulenceConfig | None = None
    #: Model switches for ablations: None (the full model), a ``ModelSwitches`` or a mapping of its
    #: fields, e.g. {"actuators": "ideal", "throttle_lag": False} (see ``falcon_rl.physics.switches``).
    model: ModelSwitches | Mapping[str, Any] | None = None
    #: The task's config; None takes the task's defaults (``TaskSpec.default_config()``).
    task_config: TaskConfig | None = field(default=None)


class StepTensors(NamedTuple):
    """One env step's outputs as tensors (``FixedWingEnv.step_tensors``)."""

    observation: torch.Tensor  # [N, D], finite
    reward: torch.Tensor  # [N], finite
    reason: torch.Tensor  # [N] long, index in TERMINATION_REASONS (0: not terminated)
    truncated: torch.Tensor  # [N] bool, horizon reached and not terminated
    non_finite: torch.Tensor  # [N] bool, rows terminated as "non_finite"
    state: TensorDictBase | None  # the simulator's state after the step ([N] scalars); None when lean
    # and the task's fused step computed the outputs without it


class FixedWingEnv(EnvBase):
    """Batched fixed-wing flight task as a TorchRL environment (batch-locked, batch [N]).

    Flight-env interface: the transforms, recipes and evaluation helpers use only these members
    (and TorchRL's ``batch_size``, ``device`` and specs), found through
    ``falcon_rl.transforms.flight_env``; any base env that provides them works under the transforms.
    N envs, D observation entries, A action channels.

    =================================  ==========  ==================================================
    member                             shape       meaning; used by
    =================================  ==========  ==================================================
    control_dt                         float       s per env step (decimation x dt); sensors, delays
    observe(state)                     [N, D]      the task's observation of a (measured) state,
                                                   without side effects; SensorTransform
    trim_action()                      [A]         trim command in the action channels; ActionDelay,
                                                   recipes' trim_action, TrimHold, examples
    physical_parameters(names=None)    {[N, ...]}  current per-env values (copies); None: the
                                                   randomisable ones; DomainRandomization.sampled
    nominal_physical_parameters(...)   {[N, ...]}  the values the env was built with; randomisation
    set_physical_parameters(mask, **)  mask [N]    masked write of RANDOMISABLE_PARAMETERS, each
                                                   [N, ...] or one row [...]; DomainRandomization
    episode_step                       [N] long    env steps since each env's reset (a copy)
    max_episode_steps                  int         truncation once episode_step reaches it; recipes
    set_episode_step(values, mask)     [N] or int  start counters mid-episode; stagger_episodes
    stagger_episodes(generator)        -           counters uniform in {0, ..., max - 1}; recipes
    reward_term_means()                {float}     mean of each named reward term per env-step since the
                                                   last call (optional member); the recipes' logs
    random_state()                     {tensors}   the env's and the simulator's generator states and
                                                   the turbulence stream counter; checkpoints
    seed_record                        (int, int)  (times seeded, last seed); the random transforms
                                                   derive their streams from it
    set_random_state(states)           -           restore them (resume continues the same draws)
    =================================  ==========  ==================================================

    Parameter names: any per-env ``ModelParams`` field may be read (e.g. ``chord``, ``span``); only
    ``RANDOMISABLE_PARAMETERS`` may be written; ``turbulence_w20`` exists with turbulence on. A
    ValueError (one line) reports an unknown or non-randomisable name, a shape mismatch or a step
    count outside [0, max_episode_steps). (``parameters`` is ``nn.Module``'s, hence the prefix.)
    """

    #: Names of the ``termination_reason`` codes (index -> name), for readers of recordings and logs.
    termination_reasons: tuple[str, ...] = TERMINATION_REASONS

    batch_locked = True
    #: The termination code of a step that left the finite numbers (``TERMINATION_REASONS``).
    non_finite_reason: ClassVar[int] = NON_FINITE

    def __init__(self, config: FixedWingEnvConfig | None = None, airframe: Airframe | None = None):
        config = config or FixedWingEnvConfig()
        spec = task_spec(config.task)
        decimation = config.decimation if config.decimation is not None else spec.env_default("decimation", 1)
        if not (isinstance(decimation, int) and decimation >= 1):
            raise ValueError(f"decimation must be an int >= 1, got {decimation!r}")
        if config.seed is None:
            config = replace(config, seed=fresh_seed())  # fresh entropy, recorded in the config
        config = replace(config, decimation=decimation)
        device = torch.device(config.device)
        super().__init__(batch_size=torch.Size([config.num_envs]), device=device)
        self.config = config
        self.airframe = airframe or load_airframe(config.airframe)
        task_config = config.task_config if config.task_config is not None else spec.default_config()
        trim_airspeed = task_config.trim_airspeed or self.airframe.envelope.cruise_speed
        turbulence = resolve_turbulence(config.turbulence, trim_airspeed, nominal_height(task_config))
        self.sim = Simulator(self.airframe, num_envs=config.num_envs, backend=config.backend,
                             device=device, dt=config.dt, integrator=config.integrator,
                             ground_effect=config.ground_effect,
                             wind=config.wind,
                             turbulence=turbulence, seed=config.seed, model=config.model, dtype=config.dtype,
                             compile=config.compile, warp_cpu_threads=config.warp_cpu_threads,
                             check_inputs=False)  # actions are checked by the env: no second check, no sync
        self.generator = make_generator(device, config.seed)
        self.control_dt = config.dt * decimation
        self.task = spec.task(task_config, self.sim, self.generator, self.control_dt, config.ground_effect)
        self.max_episode_steps = max(1, round(self.task.episode_seconds / self.control_dt))
        self.step_count = torch.zeros(config.num_envs, dtype=torch.long, device=device)
        self._nominal_parameters = self.physical_parameters()
        self._seed_record: tuple[int, int] = (0, 0)
        self._set_seed(config.seed)
        self._make_specs()

    # ------------------------------------------------------------------ specs
    def _make_specs(self) -> None:
        n, dev = self.config.num_envs, self.device
        sample = self._output(self.task.observe(self.sim.state), self.sim.state,
                              torch.zeros(n, dtype=torch.long, device=dev),
                              torch.zeros(n, 1, dtype=torch.bool, device=dev), reward=None)

        def leaf(value: torch.Tensor) -> Bounded | Categorical | Unbounded:
            if value.dtype == torch.bool:
                return Categorical(2, shape=value.shape, dtype=torch.bool, device=dev)
            return Unbounded(shape=value.shape, dtype=value.dtype, device=dev)

        clip = self.task.observation_clip
        spec = Composite(
            observation=Bounded(-clip, clip, shape=(n, self.task.observation_dim), dtype=self.sim.dtype,
                                device=dev),
            termination_reason=Categorical(len(TERMINATION_REASONS), shape=(n, 1), dtype=torch.long,
                                           device=dev),
            shape=(n,), device=dev)
        if not self.config.lean:
            for group in ("state", "task", "reward_terms"):
                if group not in sample.keys():  # noqa: SIM118 (a TensorDict iterates its rows)
                    continue
                spec[group] = Composite({key: leaf(value) for key, value in sample[group].items()},
                                        shape=(n,), device=dev)
        self.observation_spec = spec
        self.action_spec = Bounded(-1.0, 1.0, shape=(n, self.task.action_dim), dtype=self.sim.dtype,
                                   device=dev)
        self.reward_spec = Unbounded(shape=(n, 1), dtype=self.sim.dtype, device=dev)
        self.done_spec = Composite(
            {key: Categorical(2, shape=(n, 1), dtype=torch.bool, device=dev)
             for key in ("done", "terminated", "truncated")},
            shape=(n,), device=dev)

    # ------------------------------------------------------------------ EnvBase API
    def _set_seed(self, seed: int | None) -> None:
        if seed is None:
            seed = fresh_seed()  # fresh entropy, never a shared default
        seed = int(seed) % (2**62)
        self.generator.manual_seed(seed)
        self.sim.reseed(seed + 1)
        self._seed_record = (self._seed_record[0] + 1, seed)

    @property
    def seed_record(self) -> tuple[int, int]:
        """(times seeded, construction included; the seed last used): the robustness transforms
        reseed themselves from it when it changes."""
        return self._seed_record

    def _reset(self, tensordict: TensorDictBase | None = None, seed: int | None = None,
               **kwargs) -> TensorDictBase:
        if seed is not None:
            self._set_seed(seed)
        n = self.config.num_envs
        mask = None if tensordict is None else tensordict.get("_reset", None)
        observation, state = self.reset_tensors(mask, with_state=not self.config.lean)
        reason = torch.zeros(n, dtype=torch.long, device=self.device)
        no = torch.zeros(n, 1, dtype=torch.bool, device=self.device)
        return self._output(observation, state, reason, no, reward=None)

    def reset_tensors(self, mask: torch.Tensor | None = None, with_state: bool = True
                      ) -> tuple[torch.Tensor, TensorDictBase | None]:
        """Reset the rows of ``mask`` ([N] or [N, 1] bool; all when None) without TensorDicts in or out
        (the core of ``reset``, for the Gymnasium paths): (observation [N, D], simulator state). With
        ``with_state=False`` the state is None when the task starts episodes with its Warp step's start
        kernel, which reads the simulator's buffers: the state is then not built."""
        n = self.config.num_envs
        mask = (torch.ones(n, dtype=torch.bool, device=self.device) if mask is None
                else mask.reshape(n).to(self.device, torch.bool))
        initial = self.task.sample_initial(mask)
        publish = with_state or not self.task.has_warp_step()
        state = self.sim.reset(initial, mask=mask, publish=publish)
        if publish and not isinstance(state, TensorDictBase):  # a facade whose reset returns nothing
            state = self.sim.state
        self.step_count.masked_fill_(mask, 0)
        return self.task.start_episodes(mask, state), state

    def observe(self, state: TensorDictBase) -> torch.Tensor:
        """[N, D] observation the task makes of ``state`` (fields as under ("state", ...), e.g. a
        measured one; [N, 1] scalars or the simulator's [N]) with its current buffers, without side
        effects (the sensor transform's hook)."""
        return self.task.observe(simulator_layout(state, self.config.num_envs))

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        action = tensordict.get("action", None)
        if self.config.lean:  # the step wrote every output, finite and flagged
            refuse_bad_action(action, self.config.num_envs, self.task.action_dim)
            self.task.reward_term_steps += 1  # on the task: EnvBase's __setattr__ costs ~2 us a step
            # The entries are new tensors of the batch's shape and device, as the checked constructor
            # would make sure of: TorchRL's own Gym-like envs build their outputs the same way.
            return TensorDict._new_unsafe(self.stepper().torchrl_outputs(action), batch_size=self.batch_size,
                                          device=self.device)
        step = self.step_tensors(action)
        out = self._output(step.observation, step.state, step.reason, step.truncated.unsqueeze(-1),
                           reward=step.reward.unsqueeze(-1))
        if not self.config.lean and bool(step.non_finite.any()):  # lean: the outputs are clean already
            out = self._zero_non_finite(out, step.non_finite)
        return out

    def step_tensors(self, action: object, with_state: bool = True, copy: bool = True) -> StepTensors:
        """One env step without TensorDicts in or out (the core of ``step``, for the Gymnasium paths):
        ``action`` [N, A] checked (see "Actions" in the module docstring); the observation and reward
        it returns are finite (zeroed in "non_finite" rows), the state is the simulator's as it is.
        ``with_state=False`` lets a task with a fused step skip building the state (``state`` is then
        None, and the finiteness check reads the simulator's buffers instead). On the warp backend
        with a fused task step the whole step is one engine call (``Engine.fuse``); ``copy=False``
        then returns its buffers, which the next step overwrites."""
        stepper = self.stepper()
        refuse_bad_action(action, self.config.num_envs, self.task.action_dim)
        self.task.reward_term_steps += 1
        observation, reward, reason, truncated, non_finite = stepper(action, with_state)
        state = stepper.state
        if stepper.reuses_buffers and (copy or (with_state and not self.config.lean)):
            observation, reward, reason = observation.clone(), reward.clone(), reason.clone()
            truncated, non_finite = truncated.clone(), non_finite.clone()
        if with_state and not self.config.lean and state is None:  # the derived state is checked too
            state, derived = self.sim.state_and_derived()
            extra = ~finite_rows(derived)  # the kernel checked the rest
            non_finite |= extra
            reason.masked_fill_(extra, NON_FINITE)
            truncated &= ~extra
            observation.masked_fill_(extra[:, None] & ~torch.isfinite(observation), 0.0)
            reward.masked_fill_(extra & ~torch.isfinite(reward), 0.0)
        return StepTensors(observation, reward, reason, truncated, non_finite, state)

    def stepper(self) -> FusedEnvStep | StagedEnvStep:
        """The env's step: the engine's one-call step (:meth:`env_stepper`) where it applies, else the
        same step as stages (``staged_step.StagedEnvStep``); both are called alike and give the same
        outputs."""
        if "_stepper" not in self.__dict__:
            self.__dict__["_stepper"] = self.env_stepper() or StagedEnvStep(self)
        return self.__dict__["_stepper"]

    def env_stepper(self) -> FusedEnvStep | None:
        """The engine's one-call env step (``Engine.fuse``) when it applies: ``fused`` on, a task with a
        fused step (``Task.fused_stepper``) whose ``command`` is the base one, and an engine that fuses
        (the warp engine: one launch); None otherwise (the step then runs the engine, the task and the
        checks one after the other)."""
        if "_env_step" not in self.__dict__:
            task = self.task
            fused = self.config.fused and type(task).command is Task.command
            task_step = task.fused_stepper() if fused else None
            self.__dict__["_env_step"] = None if task_step is None else self.sim.engine.fuse(task_step, self)
        return self.__dict__["_env_step"]

    def __getstate__(self) -> dict[str, Any]:
        """The plain state: the one-launch step's binding is made again after unpickling."""
        state = self.__dict__.copy()
        state.pop("_env_step", None)
        state.pop("_stepper", None)
        return state

    @staticmethod
    def _zero_non_finite(out: TensorDictBase, rows: torch.Tensor) -> TensorDictBase:
        """Replace every non-finite number of the ``rows`` [N] bool by 0 (those envs are terminated):
        no NaN or Inf leaves the env, and the other envs are untouched."""
        def clean(value: torch.Tensor) -> torch.Tensor:
            if not value.is_floating_point():
                return value
            mask = rows.reshape(-1, *([1] * (value.dim() - 1))) & ~torch.isfinite(value)
            return value.masked_fill(mask, 0.0)

        return out.apply(clean)

    def _output(self, observation: torch.Tensor, state: TensorDictBase | None, reason: torch.Tensor,
                truncated: torch.Tensor, reward: torch.Tensor | None) -> TensorDictBase:
        """The step or reset output; ``reason`` [N] long (0: not terminated), ``truncated`` [N, 1]."""
        terminated = (reason > 0).unsqueeze(-1)
        truncated = truncated & ~terminated
        out = {
            "observation": observation,
            "termination_reason": reason.unsqueeze(-1),
            "terminated": terminated,
            "truncated": truncated,
            "done": terminated | truncated,
        }
        batch, device = self.batch_size, self.device
        if not self.config.lean:
            out["state"] = TensorDict._new_unsafe({key: column(state[key]) for key in STATE_KEYS},
                                                  batch_size=batch, device=device)
            task = {key: column(value) for key, value in self.task.info().items()}
            out["task"] = TensorDict._new_unsafe(task, batch_size=batch, device=device)
            if self.task.reward_terms:  # the transition's terms; zero in a reset's output
                values = self.task.reward_term_values
                dtype = self.sim.dtype  # a float64 env's terms come from its float32 task step
                values = (values.to(dtype, copy=True) if reward is not None
                          else torch.zeros_like(values, dtype=dtype))
                terms = dict(zip(self.task.reward_terms, values.unsqueeze(-1).unbind(1), strict=True))
                out["reward_terms"] = TensorDict._new_unsafe(terms, batch_size=batch, device=device)
        if reward is not None:
            out["reward"] = reward
        # Every entry is an [N, ...] tensor of the env's device by construction (the simulator's state,
        # the task's buffers and outputs): the unchecked constructor skips TensorDict's per-entry
        # validation, as the lean step and Simulator.state do.
        return TensorDict._new_unsafe(out, batch_size=batch, device=device)

    # ------------------------------------------------------------------ flight-env interface
    def reward_term_means(self) -> dict[str, float]:
        """{term: mean per env-step} of the task's named reward terms (``Task.reward_terms``; weighted and
        signed, they sum to the reward) over the env steps since the last call, which starts them over;
        empty for a task without named terms or before a step. The recipes log them as
        ``reward/<term>``."""
        task, steps = self.task, self.task.reward_term_steps
        task.reward_term_steps = 0
        sums = task.reward_term_sums.sum(0) / max(steps * self.config.num_envs, 1)
        task.reward_term_sums.zero_()
        return dict(zip(task.reward_terms, sums.tolist(), strict=True)) if steps else {}

    def trim_action(self) -> torch.Tensor:
        """[A] the task's straight-and-level trim command in its action channels (a copy)."""
        return self.task.trim.command[self.task.channels].clone()

    def physical_parameters(self, names: Iterable[str] | None = None) -> dict[str, torch.Tensor]:
        """Current per-env parameters {name: [N, ...]} (copies). None: the randomisable ones this env
        has (``turbulence_w20`` only with turbulence on); any per-env ModelParams field may be named."""
        names = self._randomisable_names() if names is None else tuple(names)
        return {name: self._parameter_tensor(name).clone() for name in names}

    def nominal_physical_parameters(self, names: Iterable[str] | None = None) -> dict[str, torch.Tensor]:
        """As :meth:`physical_parameters`, the values the env was built with (a parameter that is not
        randomisable cannot change, so its current value is its nominal one)."""
        names = self._randomisable_names() if names is None else tuple(names)
        return {name: (self._nominal_parameters[name] if name in self._nominal_parameters
                       else self._parameter_tensor(name)).clone() for name in names}

    def set_physical_parameters(self, mask: torch.Tensor | None = None, **values: torch.Tensor) -> None:
        """Write randomisable parameters on the rows where ``mask`` [N] bool is True (all when None).
        Each value is [N, ...] or one row [...] for every env; all are checked before any is written."""
        rows = self._rows(mask)
        checked = {}
        for name, value in values.items():
            if name not in RANDOMISABLE_PARAMETERS:
                kind = "is not randomisable" if name in self.sim.params.per_env_fields() else "is unknown"
                raise ValueError(f"physical parameter {name!r} {kind}; randomisable: "
                                 f"{', '.join(RANDOMISABLE_PARAMETERS)}")
            target = self._parameter_tensor(name)
            value = torch.as_tensor(value, device=self.device)
            if value.shape not in (target.shape, target.shape[1:]):
                raise ValueError(f"{name} must have shape {list(target.shape)} or {list(target.shape[1:])}, "
                                 f"got {list(value.shape)}")
            checked[name] = value.to(target.dtype).expand_as(target)
        model = {name: value for name, value in checked.items() if name in RANDOMISABLE_MODEL_PARAMETERS}
        if model:
            self.sim.params.assign(rows, **model)
        for name in RANDOMISABLE_ATMOSPHERE_PARAMETERS:
            if name in checked:
                self._parameter_tensor(name)[rows] = checked[name][rows]

    @property
    def episode_step(self) -> torch.Tensor:
        """[N] long env steps since each env's last reset (a copy); truncation at max_episode_steps."""
        return self.step_count.clone()

    def set_episode_step(self, values: torch.Tensor | int, mask: torch.Tensor | None = None) -> None:
        """Set the step counters of the rows in ``mask`` [N] (all when None) to ``values`` ([N] or one
        int), each in [0, max_episode_steps)."""
        n = self.config.num_envs
        rows = self._rows(mask)
        values = torch.as_tensor(values, dtype=torch.long, device=self.device)
        if values.shape not in ((n,), ()):
            raise ValueError(f"episode steps must have shape [{n}] or [], got {list(values.shape)}")
        if bool(((values < 0) | (values >= self.max_episode_steps)).any()):
            raise ValueError(f"episode steps must lie in [0, {self.max_episode_steps}), got "
                             f"[{int(values.min())}, {int(values.max())}]")
        self.step_count[rows] = values.expand(n)[rows]

    def random_state(self) -> dict[str, torch.Tensor]:
        """{"env", "sim"[, "turbulence"]}: the env's generator state (episode draws), the simulator's
        (torch Dryden noise) and the Warp turbulence stream's (seed, step) [2] int32 (copies)."""
        states = {"env": self.generator.get_state(), "sim": self.sim.generator.get_state()}
        if self.sim.turbulence is not None:
            states["turbulence"] = self.sim.turbulence.rng.clone()
        return states

    def set_random_state(self, states: dict[str, torch.Tensor]) -> None:
        """Restore what :meth:`random_state` returned (entries it lacks are left as they are)."""
        if "env" in states:
            self.generator.set_state(states["env"])
        if "sim" in states:
            self.sim.generator.set_state(states["sim"])
        if "turbulence" in states and self.sim.turbulence is not None:
            self.sim.turbulence.rng.copy_(states["turbulence"])

    def stagger_episodes(self, generator: torch.Generator) -> None:
        """Start each env's step counter at a step drawn uniformly in [0, max_episode_steps) with
        ``generator``, so that truncations spread over the horizon instead of all envs in lockstep."""
        offsets = torch.randint(0, self.max_episode_steps, self.step_count.shape, generator=generator,
                                device=generator.device)
        self.set_episode_step(offsets.to(self.device))

    def _randomisable_names(self) -> tuple[str, ...]:
        return tuple(name for name in RANDOMISABLE_PARAMETERS
                     if name != "turbulence_w20" or self.sim.turbulence is not None)

    def _parameter_tensor(self, name: str) -> torch.Tensor:
        """The live per-env tensor [N, ...] behind parameter ``name`` (ValueError when unknown)."""
        if name == "wind_ned":
            return self.sim.wind_ned
        if name == "turbulence_w20":
            if self.sim.turbulence is None:
                raise ValueError("turbulence_w20 needs turbulence on in the env "
                                 "(make_env(..., turbulence=...))")
            return self.sim.turbulence.w20
        if name not in self.sim.params.per_env_fields():
            raise ValueError(f"physical parameter {name!r} is unknown; randomisable: "
                             f"{', '.join(RANDOMISABLE_PARAMETERS)}")
        return getattr(self.sim.params, name)

    def _rows(self, mask: torch.Tensor | None) -> torch.Tensor:
        """[N] bool rows of ``mask`` ([N] or [N, 1]; all rows when None)."""
        n = self.config.num_envs
        if mask is None:
            return torch.ones(n, dtype=torch.bool, device=self.device)
        if mask.numel() != n:
            raise ValueError(f"mask must have {n} entries, got shape {list(mask.shape)}")
        return mask.reshape(n).to(self.device, torch.bool)
