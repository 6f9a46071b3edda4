"""What every flight task shares: the trim cache, the command assembly, the stall and ground
terminations, random draws from the env's generator and the bookkeeping of the previous action.

A task is one small module holding a config dataclass and a :class:`Task` subclass. The env calls

    initial = task.sample_initial(mask)      # before Simulator.reset(initial, mask)
    obs = task.start_episodes(state, mask)   # after_reset (buffers of the reset rows), then observe
    command = task.command(action)           # [N, A] checked action in [-1, 1] -> [N, 4] command
    obs, reward, reason = task.step(state, action)           # after the physics steps
    obs = task.observe(state)                # [N, D] scaled and clipped observation (after reset)

``step`` runs advance (clock, reference) -> update (filters fed by the new state) -> reward ->
termination reason -> remember the action as a_{t-1} -> observe.

and publishes ``task.info()`` (named [N] / [N, k] tensors) under the ("task", ...) keys.

Termination shared by all tasks (the paper's altitude task, reused by the others):

    terminated = ground_contact  |  |alpha| > 1.5 alpha_stall  |  V_a < V_stall

Each termination has a reason, an index into :data:`TERMINATION_REASONS` that the env publishes as
"termination_reason" (the first that applies, in that order; 0 while flying). A task adds its own
(e.g. "lost": too far from the path) by extending :meth:`Task.termination_checks`; the env adds
"non_finite" for a state, reward or action that is no longer finite.
"""

from __future__ import annotations

import math
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
#: this order, the first that applies is published.
TERMINATION_REASONS: tuple[str, ...] = ("none", "ground_contact", "alpha_stall", "speed_stall", "lost",
                                        "non_finite")
#: Index of each reason in :data:`TERMINATION_REASONS`.
TERMINATION_CODE: dict[str, int] = {name: code for code, name in enumerate(TERMINATION_REASONS)}

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

    def check(self, task: str) -> None:
        """Raise ValueError (one line: task, option, constraint, value) on a value the task cannot run."""
        for f in fields(self):
            value = getattr(self, f.name)
            kind = str(f.type)
            if "float" not in kind or (value is None and "None" in kind):
                continue
            many = kind.startswith("tuple")
            numbers = value if many and isinstance(value, (tuple, list)) else (value,)
            if not numbers or not all(_is_number(v) and math.isfinite(v) for v in numbers):
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
        self.previous_action = torch.zeros(n, self.action_dim, device=self.device, dtype=self.dtype)
        self.time = torch.zeros(n, device=self.device, dtype=self.dtype)
        k = len(self.reward_terms)
        #: [N, K] each reward term of the last step (K = len(reward_terms)), and [N, K] their sums over
        #: the steps since the env's last ``reward_term_means`` (the fused step writes both too).
        self.reward_term_values = torch.zeros(n, k, device=self.device, dtype=self.dtype)
        self.reward_term_sums = torch.zeros(n, k, device=self.device, dtype=self.dtype)
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
        """Reset per-episode buffers of the rows in ``mask`` [N] from the fresh ``state``."""
        self.previous_action[mask] = 0.0
        self.time[mask] = 0.0

    def start_episodes(self, state: TensorDictBase | None, mask: torch.Tensor,
                       starter: TaskStep | None = None) -> torch.Tensor:
        """[N, D] observation (a new tensor) after the rows in ``mask`` [N] bool were reset to ``state``,
        the simulator's: :meth:`after_reset` then :meth:`observe`, or, given ``starter`` (this task's
        :meth:`fused_starter`, which the caller asked for once before the reset), the same in one
        backend launch (parity tested), which reads the simulator's buffers (``state`` may then be
        None)."""
        if starter is not None:
            return starter.start(mask).clone()
        if state is None:
            raise ValueError(f"the {self.name} task needs the reset state to start episodes")
        self.after_reset(state, mask)
        return self.observe(state)

    def fused_starter(self) -> TaskStep | None:
        """The fused step (:meth:`fused_stepper`) when it has a start kernel, the twin of
        :meth:`after_reset` and :meth:`observe` of the class it twins (``TaskStep.owner``), and this
        task's class does not override ``after_reset`` (``observe`` and the methods ``after_reset`` calls
        are the step's, checked by :meth:`fused_stepper`); else None: the task starts episodes in torch."""
        stepper = self.fused_stepper()
        if stepper is None or stepper.start_kernel is None or self.overrides(stepper.owner, ("after_reset",)):
            return None
        return stepper

    def command(self, action: torch.Tensor) -> torch.Tensor:
        """[N, A] action in [-1, 1] -> [N, 4] simulator command (trim in undriven channels)."""
        self.command_buffer[:, self.channels] = action.to(self.dtype).clamp(-1.0, 1.0)
        return self.command_buffer

    def advance(self) -> None:
        """Move the task clock (and any reference) forward by one env step."""
        self.time += self.control_dt

    @abstractmethod
    def observe(self, state: TensorDictBase) -> torch.Tensor:
        """[N, D] observation, scaled and clipped to +-observation_clip."""

    def observation_of(self, state: TensorDictBase, fused: bool = True) -> torch.Tensor:
        """[N, D] the observation of ``state`` (e.g. a measured one: [N, 1] scalars or the simulator's
        [N]) with the current buffers, without side effects: the fused step's observe kernel where the
        task has one (the same code as its step's observation; ``fused=False``: never), else
        :meth:`observe`."""
        stepper = self.fused_stepper() if fused else None
        if stepper is not None and stepper.observe_kernel is not None:
            return stepper.observe(state).to(self.dtype)
        return self.observe(state)

    def reward(self, state: TensorDictBase, action: torch.Tensor) -> torch.Tensor:
        """[N] reward of the transition that ended in ``state`` under ``action`` [N, A]: the sum of
        :meth:`reward_terms_of` in the order of :attr:`reward_terms` (each kept in
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
        """The reward's terms, each [N], weighted and signed, in the order of :attr:`reward_terms`."""
        raise NotImplementedError(f"{type(self).__name__} defines neither reward nor reward_terms_of")

    def termination_checks(self, state: TensorDictBase) -> dict[str, torch.Tensor]:
        """{reason: [N] bool} of the terminations this task checks (names of TERMINATION_REASONS):
        ground contact, alpha stall (|alpha| > k alpha_stall) and speed stall (V_a < V_stall)."""
        return {"ground_contact": state["ground_contact"],
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
        """Per-step filters fed by the new state (integrals, rates, target release); optional."""
        return None

    def step(self, state: TensorDictBase, action: torch.Tensor
             ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """(observation [N, D], reward [N], termination reason [N] long, 0 while flying) after an env
        step that applied ``action`` [N, A] (checked: finite, in [-1, 1]) and ended in ``state``."""
        self.advance()
        self.update(state)
        reward = self.reward(state, action)
        reason = self.termination_reason(state)
        self.previous_action.copy_(action)
        return self.observe(state), reward, reason

    def fused_stepper(self) -> TaskStep | None:
        """This task's backend-fused step (bound on first use, kept in ``_fused``), or None when it has
        none for the simulator's backend (the default) or a subclass overrides a method it fuses.

        Called right after the physics sub-steps with the same checked action [N, A], it reads the
        simulator's buffers instead of a state TensorDict, updates every buffer :meth:`step` updates,
        exactly as :meth:`step` would (parity tested), and returns (observation [N, D], reward [N],
        termination reason [N] long), buffers that the next call overwrites. On the warp backend the env
        runs it inside the engine's one-call step (``Engine.fuse``) when nothing else overrides it."""
        return None

    def overrides(self, owner: type, methods: tuple[str, ...]) -> bool:
        """Whether this task's class overrides one of ``methods`` of ``owner`` (a fused twin of them then
        does not apply)."""
        cls = type(self)
        return any(getattr(cls, name) is not getattr(owner, name) for name in methods)

    def fused_step(self, action: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor] | None:
        """The backend-fused twin of :meth:`step` (:meth:`fused_stepper`), or None when there is none:
        the env then builds ``sim.state`` and calls :meth:`step`."""
        stepper = self.fused_stepper()
        return None if stepper is None else stepper(action)

    def __getstate__(self) -> dict:
        """The plain state: a fused step's backend binding (``_fused``) is made again after unpickling."""
        return {**self.__dict__, "_fused": None}

    @abstractmethod
    def info(self) -> dict[str, torch.Tensor]:
        """Task quantities published under ("task", name): references and tracking errors."""

    def info_views(self) -> dict[str, torch.Tensor] | None:
        """:meth:`info`'s entries as live views of the task's buffers (no copies: they change with the next
        step or reset), in the same order, for hosts that read them every step; None (the default) when
        an entry is computed rather than stored."""
        return None

    def info_shapes(self) -> dict[str, tuple[int, ...]]:
        """Trailing shapes of :meth:`info` entries (after the batch dim)."""
        return {k: tuple(v.shape[1:]) for k, v in self.info().items()}


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
