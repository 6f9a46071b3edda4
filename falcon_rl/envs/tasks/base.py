"""What every flight task shares: the trim cache, the command assembly, the stall and ground
terminations, random draws from the env's generator and the bookkeeping of the previous action.

A task is one folder (``envs/tasks/<name>/``) holding a config dataclass and a :class:`Task` subclass
whose step is written once, as Warp functions (its ``kernels`` module, :meth:`Task.fused_stepper`):
every engine that runs task kernels runs that one body, in float32, whatever the simulator's dtype.
The env calls

    initial = task.sample_initial(mask)      # torch: random draws, before Simulator.reset(initial, mask)
    obs = task.start_episodes(mask, state)   # the episodes' start (buffers of the reset rows), observation
    command = task.command(action)           # [N, A] checked action in [-1, 1] -> [N, 4] command
    obs, reward, reason = task.step(action)  # after the physics steps, on the simulator's state
    obs = task.observe(state)                # [N, D] observation of a given (measured) state

and publishes ``task.info()`` (named [N] / [N, k] tensors) under the ("task", ...) keys.

A task of the user's own may instead write its step in torch (no ``fused_stepper``): :meth:`torch_step`
runs advance (clock, reference) -> update (filters fed by the new state) -> reward -> termination
reason -> remember the action as a_{t-1} -> observe, on ``sim.state``; it warns once that it runs
unfused. A task has one body or the other, never both (checked when it is built).

Termination shared by all tasks (the paper's altitude task, reused by the others):

    terminated = ground_contact  |  |alpha| > 1.5 alpha_stall  |  V_a < V_stall

Each termination has a reason, an index into :data:`TERMINATION_REASONS` that the env publishes as
"termination_reason" (the first that applies, in that order; 0 while flying). A task adds its own
(e.g. "lost": too far from the path) in its step ("lost" by ``warp_common.termination_code``; a torch
task by extending :meth:`Task.termination_checks`); the env adds "non_finite" for a state, reward or
action that is no longer finite.
"""

from __future__ import annotations

import math
import warnings
from abc import ABC, abstractmethod
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING, ClassVar

import torch
from tensordict import TensorDictBase

from ...airframe import Airframe
from ...physics import Simulator, trim_level
from ...physics import state as S
from ...physics.rotations import quaternion_to_euler

if TYPE_CHECKING:
    from ...physics.task_kernels import TaskStep

#: Why an episode terminated: "termination_reason" holds the index (0: not terminated). Checked in
#: this order, the first that applies is published ("water_contact", an env over its sea touching the
#: water, is checked where "ground_contact" is: an env has one surface or the other). The landing task
#: ends on "touchdown" (its wheels on the surface, the goal) or "tip_strike" (a wing tip first).
TERMINATION_REASONS: tuple[str, ...] = ("none", "ground_contact", "alpha_stall", "speed_stall", "lost",
                                        "non_finite", "water_contact", "touchdown", "tip_strike")
#: Index of each reason in :data:`TERMINATION_REASONS`.
TERMINATION_CODE: dict[str, int] = {name: code for code, name in enumerate(TERMINATION_REASONS)}

#: The torch step's methods (:meth:`Task.torch_step` and what it calls): a task with a Warp step
#: defines none of them.
TORCH_STEP_METHODS: tuple[str, ...] = ("torch_step", "advance", "update", "reward", "reward_terms_of",
                                       "observe", "termination_checks", "termination_reason", "after_reset")
#: Torch task classes already warned that they step unfused (:func:`warn_unfused`: once per class).
_WARNED_UNFUSED: set[type] = set()

_TRIM_CACHE: dict[tuple[str, str, float, float, str], tuple[torch.Tensor, torch.Tensor]] = {}


@dataclass(frozen=True)
class TrimPoint:
    """Straight and level trim in the simulator's device and dtype (one row, broadcastable)."""

    quaternion: torch.Tensor  # [4]
    velocity_body: torch.Tensor  # [3] m/s
    surface_position: torch.Tensor  # [3] rad
    throttle: torch.Tensor  # [M]
    command: torch.Tensor  # [4] normalised command that holds the trim
    pitch: float  # rad (= trim alpha in still air)


def trim_point(sim: Simulator, airspeed: float, height: float = 100.0,
               ground_effect: bool | str = True) -> TrimPoint:
    """Trim of ``sim.airframe`` at ``airspeed`` and ``height``, solved once per airframe, airspeed,
    height and ground-effect mode and cached for the process."""
    airframe: Airframe = sim.airframe
    key = (airframe.name, str(airframe.path), float(airspeed), float(height), str(ground_effect))
    if key not in _TRIM_CACHE:
        trim = trim_level(airframe, airspeed, height, ground_effect=ground_effect)
        _TRIM_CACHE[key] = (trim.state[0].clone(), trim.commands[0].clone())
    x, command = (t.to(sim.device, sim.dtype) for t in _TRIM_CACHE[key])
    f = S.StateLayout(airframe.num_motors).unpack(x)
    return TrimPoint(
        quaternion=f["quaternion"], velocity_body=f["velocity_body"], surface_position=f["surface_position"],
        throttle=f["throttle"], command=command,
        pitch=float(quaternion_to_euler(f["quaternion"][None])[0, S.PITCH]),
    )


@dataclass
class TaskConfig:
    """Fields every task config has. Times in s, speeds in m/s."""

    #: Episode horizon in s (truncation, not termination).
    episode_seconds: float = 30.0
    #: Airspeed of the initial trim; None means the airframe's cruise speed.
    trim_airspeed: float | None = None
    #: Stall termination: |alpha| beyond this multiple of the airframe's alpha_stall.
    stall_alpha_factor: float = 1.5
    #: Training start off trim: each episode's initial airspeed is ``trim_airspeed`` x U(1 - s, 1 + s)
    #: (attitude and surfaces at trim); 0, the default and the paper's start, draws nothing. In [0, 0.5].
    initial_airspeed_spread: float = 0.0

    #: Number fields that must be > 0 (a None left as None) and >= 0, and (low, high) pairs that must
    #: be ordered; :meth:`check` also requires every number of a ``float`` field to be finite.
    positive: ClassVar[tuple[str, ...]] = ("episode_seconds", "stall_alpha_factor", "trim_airspeed")
    non_negative: ClassVar[tuple[str, ...]] = ()
    ordered: ClassVar[tuple[tuple[str, str], ...]] = ()
    #: Tuple fields that may be empty (every other tuple of numbers needs at least one).
    may_be_empty: ClassVar[tuple[str, ...]] = ()

    def check(self, task: str) -> None:
        """Raise ValueError (one line: task, option, constraint, value) on a value the task cannot run."""
        for f in fields(self):
            value = getattr(self, f.name)
            kind = str(f.type)
            if "float" not in kind or (value is None and "None" in kind):
                continue
            many = kind.startswith("tuple")
            numbers = value if many and isinstance(value, (tuple, list)) else (value,)
            empty_ok = many and f.name in self.may_be_empty
            if (not numbers and not empty_ok) or not all(_is_number(v) and math.isfinite(v) for v in numbers):
                what = "a non-empty tuple of finite numbers" if many else "a finite number"
                raise ValueError(f"{task} option {f.name} must be {what}, got {value!r}")
        if not 0.0 <= self.initial_airspeed_spread <= 0.5:
            raise ValueError(f"{task} option initial_airspeed_spread must be a number in [0, 0.5], "
                             f"got {self.initial_airspeed_spread!r}")
        for names, bound, test in ((self.positive, "> 0", lambda v: v > 0),
                                   (self.non_negative, ">= 0", lambda v: v >= 0)):
            for name in names:
                value = getattr(self, name)
                values = value if isinstance(value, (tuple, list)) else (value,)
                if value is not None and not all(test(v) for v in values):
                    raise ValueError(f"{task} option {name} must be {bound}, got {value!r}")
        for low, high in self.ordered:
            if getattr(self, low) > getattr(self, high):
                raise ValueError(f"{task} options {low} <= {high} required, got {getattr(self, low)!r} > "
                                 f"{getattr(self, high)!r}")


def _is_number(value: object) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


class Task(ABC):
    """Base of the flight tasks. N envs; A action channels; D observation entries."""

    name: ClassVar[str]
    observation_dim: ClassVar[int]
    action_dim: ClassVar[int]
    observation_clip: ClassVar[float]
    #: Simulator command channels the action drives, in action order (0 elevator .. 3 throttle).
    action_channels: ClassVar[tuple[int, ...]] = (S.ELEVATOR, S.AILERON, S.RUDDER, S.THROTTLE)
    #: Names of the reward's terms (weighted and signed: the reward is their sum, in this order), as
    #: :meth:`reward_terms_of` returns them; empty for a task whose :meth:`reward` is one expression.
    reward_terms: ClassVar[tuple[str, ...]] = ()

    def __init__(self, config: TaskConfig, sim: Simulator, generator: torch.Generator,
                 control_dt: float, ground_effect: bool | str = True):
        config.check(self.name)
        self.config = config
        #: Length of one env step (decimation x physics dt), s.
        self.control_dt = float(control_dt)
        self.sim = sim
        self.airframe: Airframe = sim.airframe
        self.generator = generator
        self.num_envs = sim.num_envs
        self.device = sim.device
        self.dtype = sim.dtype
        warp_step = self.has_warp_step()
        if warp_step:
            self._check_one_body()
            if not sim.engine.runs_task_kernels:
                raise ValueError(f"the {self.name} task steps in Warp kernels, which run on CPU or CUDA "
                                 f"buffers; the {type(sim.engine).__name__} on {sim.device} runs none")
        #: dtype of the task's own buffers: float32 for a task with a Warp step (its kernels read and write
        #: them in place), else the simulator's.
        self.buffer_dtype = torch.float32 if warp_step else self.dtype
        env = self.airframe.envelope
        self.trim_airspeed = float(config.trim_airspeed or env.cruise_speed)
        self.trim = trim_point(sim, self.trim_airspeed, ground_effect=ground_effect)
        self.stall_speed = float(env.stall_speed)
        self.stall_alpha = float(config.stall_alpha_factor * self.airframe.aero.alpha_stall)
        n = self.num_envs
        #: Full simulator command, trim in the channels the action does not drive. [N, 4]
        self.command_buffer = self.trim.command.expand(n, 4).clone()
        self.channels = torch.tensor(self.action_channels, device=self.device)
        #: Action of the previous env step (zero after a reset). [N, A]
        self.previous_action = torch.zeros(n, self.action_dim, device=self.device, dtype=self.buffer_dtype)
        self.time = torch.zeros(n, device=self.device, dtype=self.buffer_dtype)
        k = len(self.reward_terms)
        #: [N, K] each reward term of the last step (K = len(reward_terms)), and [N, K] their sums over
        #: the steps since the env's last ``reward_term_means`` (the fused step writes both too).
        self.reward_term_values = torch.zeros(n, k, device=self.device, dtype=self.buffer_dtype)
        self.reward_term_sums = torch.zeros(n, k, device=self.device, dtype=self.buffer_dtype)
        #: Env steps since the sums started (the env counts them and starts them over).
        self.reward_term_steps = 0

    @property
    def episode_seconds(self) -> float:
        """Episode horizon, s (the env truncates after this many seconds)."""
        return self.config.episode_seconds

    # ------------------------------------------------------------------ randomness
    def uniform(self, low: float | torch.Tensor, high: float | torch.Tensor, *shape: int) -> torch.Tensor:
        """U(low, high) of shape [N, *shape] from the env's generator."""
        u = torch.rand(self.num_envs, *shape, generator=self.generator, device=self.device,
                       dtype=self.dtype)
        return low + (high - low) * u

    def random_sign(self, *shape: int) -> torch.Tensor:
        """+-1 with equal probability, [N, *shape]."""
        return torch.where(self.uniform(0.0, 1.0, *shape) < 0.5, -1.0, 1.0).to(self.dtype)

    def choice(self, values: tuple[float, ...]) -> torch.Tensor:
        """One of ``values`` per env, uniformly. [N]"""
        table = torch.tensor(values, device=self.device, dtype=self.dtype)
        index = torch.randint(len(values), (self.num_envs,), generator=self.generator, device=self.device)
        return table[index]

    # ------------------------------------------------------------------ hooks
    def trim_initial(self, yaw: torch.Tensor | None = None) -> dict[str, torch.Tensor]:
        """Initial fields of straight and level trim at ``trim_airspeed``, heading ``yaw`` [N] rad
        (north when None); position and height are left to the task. With ``initial_airspeed_spread`` s
        > 0 the body velocity is scaled per env by U(1 - s, 1 + s) ([N, 3]; drawn from the env's
        generator, so seeds without the option keep their streams)."""
        t = self.trim
        velocity, spread = t.velocity_body, self.config.initial_airspeed_spread
        if spread > 0.0:
            velocity = velocity * self.uniform(1.0 - spread, 1.0 + spread, 1)
        initial = {"velocity_body": velocity, "surface_position": t.surface_position,
                   "throttle": t.throttle, "command": t.command,
                   "angular_rate_body": torch.zeros(3, device=self.device, dtype=self.dtype)}
        if yaw is None:
            initial["quaternion"] = t.quaternion
        else:
            zeros = torch.zeros_like(yaw)
            initial["euler"] = torch.stack([zeros, zeros + t.pitch, yaw], dim=-1)
        return initial

    @abstractmethod
    def sample_initial(self, mask: torch.Tensor) -> dict[str, torch.Tensor]:
        """Draw the initial conditions and episode parameters of all envs; keep those of the rows
        where ``mask`` [N] is True. Returns the ``initial`` mapping for ``Simulator.reset``."""

    def after_reset(self, state: TensorDictBase, mask: torch.Tensor) -> None:
        """Torch step: reset per-episode buffers of the rows in ``mask`` [N] from the fresh ``state``."""
        self.previous_action[mask] = 0.0
        self.time[mask] = 0.0

    def start_episodes(self, mask: torch.Tensor, state: TensorDictBase | None = None) -> torch.Tensor:
        """[N, D] observation (a new tensor, the simulator's dtype) after the rows in ``mask`` [N] bool were
        reset: the Warp step's start kernel, which reads the simulator's buffers, or, for a torch task,
        :meth:`after_reset` then :meth:`observe` of ``state``, the simulator's (built when None)."""
        stepper = self.warp_step()
        if stepper is not None:
            return stepper.start(mask).to(self.dtype, copy=True)
        state = self.sim.state if state is None else state
        self.after_reset(state, mask)
        return self.observe(state)

    def command(self, action: torch.Tensor) -> torch.Tensor:
        """[N, A] action in [-1, 1] -> [N, 4] simulator command (trim in undriven channels)."""
        self.command_buffer[:, self.channels] = action.to(self.dtype).clamp(-1.0, 1.0)
        return self.command_buffer

    def advance(self) -> None:
        """Torch step: move the task clock (and any reference) forward by one env step."""
        self.time += self.control_dt

    def observe(self, state: TensorDictBase) -> torch.Tensor:
        """[N, D] observation of ``state`` (e.g. a measured one: [N, 1] scalars or the simulator's [N]),
        scaled and clipped to +-observation_clip, with the current buffers and no side effect: the Warp
        step's observe kernel (the same function as its step's observation), in the simulator's dtype.
        A torch task defines it."""
        stepper = self.warp_step()
        if stepper is None or stepper.observe_kernel is None:
            raise NotImplementedError(f"{type(self).__name__} has neither a Warp step with an observe kernel "
                                      f"nor an observe method")
        return stepper.observe(state).to(self.dtype)

    def reward(self, state: TensorDictBase, action: torch.Tensor) -> torch.Tensor:
        """Torch step: [N] reward of the transition that ended in ``state`` under ``action`` [N, A]: the
        sum of :meth:`reward_terms_of` in the order of :attr:`reward_terms` (each kept in
        :attr:`reward_term_values` and added to :attr:`reward_term_sums`). A task may override this
        with one expression instead (then it has no named terms)."""
        terms = self.reward_terms_of(state, action)
        if len(terms) != len(self.reward_terms):
            raise ValueError(f"{type(self).__name__}.reward_terms_of gave {len(terms)} terms for the "
                             f"{len(self.reward_terms)} names of reward_terms")
        total = terms[0]
        for term in terms[1:]:
            total = total + term
        torch.stack(terms, dim=-1, out=self.reward_term_values)
        self.reward_term_sums += self.reward_term_values
        return total

    def reward_terms_of(self, state: TensorDictBase, action: torch.Tensor) -> tuple[torch.Tensor, ...]:
        """Torch step: the reward's terms, each [N], weighted and signed, in the order of
        :attr:`reward_terms`."""
        raise NotImplementedError(f"{type(self).__name__} defines neither reward nor reward_terms_of")

    def termination_checks(self, state: TensorDictBase) -> dict[str, torch.Tensor]:
        """Torch step: {reason: [N] bool} of the terminations it checks (names of TERMINATION_REASONS):
        ground or water contact, alpha stall (|alpha| > k alpha_stall) and speed stall (V_a < V_stall)."""
        return {"ground_contact": state["ground_contact"], "water_contact": state["water_contact"],
                "alpha_stall": state["alpha"].abs() > self.stall_alpha,
                "speed_stall": state["airspeed"] < self.stall_speed}

    def termination_reason(self, state: TensorDictBase) -> torch.Tensor:
        """[N] long: the index in TERMINATION_REASONS of the first termination that applies, 0 none."""
        reason = torch.zeros(self.num_envs, dtype=torch.long, device=self.device)
        for name, hit in reversed(list(self.termination_checks(state).items())):
            reason = torch.where(hit, TERMINATION_CODE[name], reason)
        return reason

    def terminated(self, state: TensorDictBase) -> torch.Tensor:
        """[N] bool: any of :meth:`termination_checks`."""
        return self.termination_reason(state) > 0

    def update(self, state: TensorDictBase) -> None:
        """Torch step: per-step filters fed by the new state (integrals, rates, target release); optional."""
        return None

    def step(self, action: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(observation [N, D], reward [N], termination reason [N] long, 0 while flying) after the physics
        sub-steps of ``action`` [N, A] (checked: finite, in [-1, 1]), on the simulator's state: the Warp
        step (buffers the next call overwrites, float32) or, for a torch task, :meth:`torch_step` of
        ``sim.state``."""
        stepper = self.warp_step()
        if stepper is not None:
            return stepper(action)
        return self.torch_step(self.sim.state, action)

    def torch_step(self, state: TensorDictBase, action: torch.Tensor
                   ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """A torch task's step (the module docstring's order) after an env step that applied ``action``
        [N, A] and ended in ``state``; a task with a Warp step has none."""
        if self.has_warp_step():
            raise TypeError(f"{type(self).__name__} steps in its Warp kernels (fused_stepper): "
                            f"call step(action)")
        warn_unfused(type(self), self.sim.engine.runs_task_kernels)
        self.advance()
        self.update(state)
        reward = self.reward(state, action)
        reason = self.termination_reason(state)
        self.previous_action.copy_(action)
        return self.observe(state), reward, reason

    def fused_stepper(self) -> TaskStep | None:
        """This task's Warp step (``warp_common.FusedStep``, bound on first use and kept in ``_fused``;
        ``warp_common.fused_stepper``), or None for a torch task (the default).

        Called right after the physics sub-steps with the checked action [N, A], it reads the simulator's
        buffers (float32 copies of a float64 simulator's) and the task's, updates the task's buffers in
        place and returns (observation [N, D], reward [N], termination reason [N] long), buffers that the
        next call overwrites. Its start kernel starts episodes (:meth:`start_episodes`) and its observe
        kernel observes a given state (:meth:`observe`). On the warp engine the env runs it inside the
        engine's one-call step (``Engine.fuse``)."""
        return None

    def warp_step(self) -> TaskStep | None:
        """:meth:`fused_stepper`, read from ``_fused`` once it is bound (a task's ``fused_stepper`` runs
        its imports and checks on every call: ~2 us, paid here once)."""
        return self.__dict__.get("_fused") or self.fused_stepper()

    @classmethod
    def has_warp_step(cls) -> bool:
        """Whether the task's step is written as Warp functions (:meth:`fused_stepper`)."""
        return cls.fused_stepper is not Task.fused_stepper

    def _check_one_body(self) -> None:
        """A task with a Warp step defines none of the torch step's methods (they would never run):
        TypeError naming them otherwise."""
        cls = type(self)
        defined = [name for name in TORCH_STEP_METHODS if getattr(cls, name) is not getattr(Task, name)]
        if defined:
            raise TypeError(
                f"{cls.__name__} defines {', '.join(defined)}, but its step is its Warp functions "
                f"(fused_stepper), so they would never run: a task's step, reward and observation are "
                f"written once. Change the Warp functions (its kernels module, with a FusedStep of its own), "
                f"or write the whole step in torch (set fused_stepper = Task.fused_stepper)")

    def __getstate__(self) -> dict:
        """The plain state: a fused step's backend binding (``_fused``) is made again after unpickling."""
        return {**self.__dict__, "_fused": None}

    def info(self) -> dict[str, torch.Tensor]:
        """Task quantities published under ("task", name): references and tracking errors, copies in the
        simulator's dtype (by default of :meth:`info_views`)."""
        views = self.info_views()
        if views is None:
            raise NotImplementedError(f"{type(self).__name__} defines neither info nor info_views")
        return {key: value.to(self.dtype, copy=True) for key, value in views.items()}

    def info_views(self) -> dict[str, torch.Tensor] | None:
        """:meth:`info`'s entries as live views of the task's buffers (no copies: they change with the next
        step or reset), in the same order, for hosts that read them every step; None (the default) when
        an entry is computed rather than stored."""
        return None

    def info_shapes(self) -> dict[str, tuple[int, ...]]:
        """Trailing shapes of :meth:`info` entries (after the batch dim)."""
        return {k: tuple(v.shape[1:]) for k, v in self.info().items()}


def warn_unfused(cls: type, engine_runs_kernels: bool) -> None:
    """Warn once per class (RuntimeWarning) that a torch task steps unfused on an engine that runs task
    kernels (a separate torch pass over the state instead of one Warp launch)."""
    if engine_runs_kernels and cls not in _WARNED_UNFUSED:
        _WARNED_UNFUSED.add(cls)
        warnings.warn(f"{cls.__name__} steps in torch, unfused (slower): write its step as Warp functions "
                      f"(Task.fused_stepper; CONTRIBUTING, 'Add a task') to run it in the engine's step",
                      RuntimeWarning, stacklevel=3)


def gaussian(error: torch.Tensor, sigma: float) -> torch.Tensor:
    """exp(-e^2 / (2 sigma^2)), elementwise."""
    return torch.exp(-0.5 * (error / sigma) ** 2)


def taper(error: torch.Tensor, band: float) -> torch.Tensor:
    """Linear taper max(0, 1 - |e| / band): 1 on the reference, 0 outside the band."""
    return (1.0 - error.abs() / band).clamp_min(0.0)


def normalised_surfaces(state: TensorDictBase, sim: Simulator) -> torch.Tensor:
    """Surface positions [N, 3] mapped onto [-1, 1] by the actuator limits (the command's scale)."""
    lo, hi = sim.params.surface_min, sim.params.surface_max
    return 2.0 * (state["surface_position"] - lo) / (hi - lo) - 1.0


def wrap_angle(angle: torch.Tensor) -> torch.Tensor:
    """Wrap to (-pi, pi]."""
    return torch.remainder(angle + math.pi, 2.0 * math.pi) - math.pi


def airspeed_margin_penalty(airspeed: torch.Tensor, safe_airspeed: float) -> torch.Tensor:
    """((V_safe - V_a) / V_safe)^2 below V_safe, 0 above. [N]"""
    return ((safe_airspeed - airspeed).clamp_min(0.0) / safe_airspeed) ** 2
