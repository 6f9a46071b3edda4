"""The backend contract: an engine owns one batch's buffers and advances them.

    engine = engine_class("warp")(setup)       # backends.py; setup: an EngineSetup (params, dt, ...)
    engine.reset(initial_x, initial_command, mask)      # masked write of [N, S] and [N, 4]
    engine.start(initial_x, initial_command, mask)      # the same from an unprojected state (-> derived)
    engine.step(command, substeps, stop_at_ground)   # command [N, 4] in [-1, 1], held over the sub-steps
    engine.derived()                           # [N, DERIVED_WIDTH], columns of derived.DERIVED_FIELDS

Capabilities (an engine that has them says so; code above the physics asks, never names a backend):

    engine.runs_task_kernels                   # runs a task's Warp kernels over its buffers
    engine.kernel_slices, engine.kernel_device # where: (offset, count) slices of the batch, Warp device
    engine.replayer(launches)                  # a call that replays recorded launches as its own
    engine.fuse(task_step, env)                # the env's whole step as one call (or None)

Buffers (allocated by :class:`Engine`, updated in place, never replaced):

    x                   [N, S]  integrated state (``state.StateLayout``)
    command             [N, 4]  the command held over the current step (clipped to [-1, 1])
    time                [N]     s since each env's reset
    wind_ned            [N, 3]  m/s, steady wind
    gust_velocity_body  [N, 3]  m/s, Dryden gusts acting over the current step
    gust_rate_body      [N, 3]  rad/s
    crashed             [N]     bool, envs stopped at the ground since their reset (``stop_at_ground``)
    surface             [N, W]  the surface under each aircraft at the current state (``surface.py``,
                                columns ``SURFACE_FIELDS``): a sea env's sample, zeros over the ground
    sea                 the envs' wave fields (``sea.SeaSurface``, [N, K] each), or None until a sea
                        is drawn (:meth:`Engine.draw_sea`); envs over the sea are those whose
                        ``params.sea_surface`` is 1 (a calm sea where none was drawn)
    params              ModelParams, per-env tensors [N, ...] (domain randomisation writes them)
    turbulence          the Dryden filter state, or None when turbulence is off
    generator           this engine's torch generator (noise of the torch Dryden filters), a
                        :class:`PicklableGenerator`

Engines pickle (``pickle``, ``copy.deepcopy``, worker processes of ParallelEnv and collectors): the
state above is plain tensors; a backend drops what it binds to them (kernels, launches, compiled
functions) in ``__getstate__`` and binds it again in ``__setstate__``.

A backend is one module with an :class:`Engine` subclass and one line in ``backends.ENGINES``
(``"name": "module:Class"``, imported on first use so that Warp is only loaded when asked for).
Engines import this module only: never the registry, nor the
:class:`~falcon_rl.physics.simulator.Simulator` facade.
"""

from __future__ import annotations

import hashlib
import os
from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar

import torch

from ..airframe import Airframe
from .dynamics import AirInputs, hold_command, project
from .params import ModelParams
from .sea import SeaState, SeaSurface, sample_sea
from .state import ANGULAR_RATE, DOWN_INDEX, NUM_CONTROLS, VELOCITY, StateLayout
from .surface import (
    CLEARANCE,
    ELEVATION,
    OVER_WATER,
    SURFACE_WIDTH,
    TIP_CLEARANCE,
    sample_surface,
    state_rotation,
)
from .wind import Turbulence, TurbulenceConfig


def fresh_seed() -> int:
    """A seed in [0, 2**62) from fresh OS entropy (what an unseeded stream starts from; never the
    process's torch or NumPy state, which spawned or forked workers may share)."""
    return int.from_bytes(os.urandom(8), "little") % (2**62)


def derive_seed(seed: int, *tags: object) -> int:
    """A seed in [0, 2**62) derived from ``seed`` and ``tags`` (e.g. a class name and a position):
    the same inputs give the same seed in every process (a hash, not Python's salted ``hash``), and
    different tags give unrelated streams."""
    text = ":".join(str(part) for part in (int(seed), *tags))
    return int.from_bytes(hashlib.blake2b(text.encode(), digest_size=8).digest(), "little") % (2**62)


class PicklableGenerator(torch.Generator):
    """A ``torch.Generator`` that pickles as (device, state bytes).

    A plain generator pickles its state as a temporary tensor, which a spawned worker process
    (ParallelEnv, multi-process collectors) receives through a file descriptor that is closed by the
    time the worker reads it; bytes travel as they are. Draws are those of ``torch.Generator``.
    """

    def __reduce__(self) -> tuple[object, tuple[str, bytes]]:
        return _restore_generator, (str(self.device), self.get_state().numpy().tobytes())


def _restore_generator(device: str, state: bytes) -> PicklableGenerator:
    generator = PicklableGenerator(device=device)
    generator.set_state(torch.frombuffer(bytearray(state), dtype=torch.uint8))
    return generator


def make_generator(device: torch.device | str, seed: int | None) -> PicklableGenerator:
    """A :class:`PicklableGenerator` on ``device`` seeded with ``seed`` (None: fresh entropy)."""
    generator = PicklableGenerator(device=device)
    generator.manual_seed(fresh_seed() if seed is None else int(seed))
    return generator


@dataclass(frozen=True)
class EngineSetup:
    """Everything an engine is built from (the facade resolves names and defaults first)."""

    airframe: Airframe
    params: ModelParams
    num_envs: int
    device: torch.device
    dtype: torch.dtype
    dt: float
    integrator: str
    turbulence: TurbulenceConfig | None = None
    #: Seed of the generator and of the turbulence streams (None: fresh entropy).
    seed: int | None = 0
    #: Backend-specific options (e.g. ``compile`` for torch, ``cpu_threads`` for warp); an engine
    #: raises on any name outside its ``OPTIONS``.
    options: Mapping[str, Any] = field(default_factory=dict)
    #: Airy components of each env's wave field (``sea.sample_sea``), when a sea is drawn.
    sea_components: int = 64


class Engine(ABC):
    """Base of the backends: owns the buffers listed in the module docstring."""

    #: Backend-specific option names this engine accepts in ``EngineSetup.options``.
    OPTIONS: ClassVar[tuple[str, ...]] = ()
    #: Whether this engine runs a task's Warp kernels over its buffers (``kernel_slices``,
    #: ``kernel_device``, ``replayer``): a task's fused step (``Task.fused_stepper``) binds to it.
    RUNS_TASK_KERNELS: ClassVar[bool] = False

    @classmethod
    def placement(cls, num_envs: int, device: torch.device, dtype: torch.dtype
                  ) -> tuple[torch.device, torch.dtype]:
        """(device, dtype) this backend runs a batch of ``num_envs`` on, given the requested ones;
        raises ValueError when it cannot."""
        return device, dtype

    def __init__(self, setup: EngineSetup):
        unknown = set(setup.options) - set(self.OPTIONS)
        if unknown:
            raise ValueError(f"options {sorted(unknown)} do not apply to the {type(self).__name__} "
                             f"(it takes {list(self.OPTIONS) or 'none'})")
        n, kw = setup.num_envs, {"device": setup.device, "dtype": setup.dtype}
        self.setup = setup
        self.num_envs = n
        self.dt = float(setup.dt)
        self.integrator = setup.integrator
        self.layout = StateLayout(setup.airframe.num_motors)
        self.params = setup.params
        self.x = torch.zeros(n, self.layout.size, **kw)
        self.command = torch.zeros(n, NUM_CONTROLS, **kw)
        self.time = torch.zeros(n, **kw)
        self.wind_ned = torch.zeros(n, 3, **kw)
        self.gust_velocity_body = torch.zeros(n, 3, **kw)
        self.gust_rate_body = torch.zeros(n, 3, **kw)
        self.crashed = torch.zeros(n, dtype=torch.bool, device=setup.device)
        self.surface = torch.zeros(n, SURFACE_WIDTH, **kw)
        self.sea: SeaSurface | None = None
        #: [N, S] the state before a step that applies the crash state (allocated on first use).
        self._before: torch.Tensor | None = None
        self._surface_before: torch.Tensor | None = None
        seed = fresh_seed() if setup.seed is None else int(setup.seed)
        self.generator = make_generator(setup.device, seed)
        self.turbulence: Turbulence | None = (
            None if setup.turbulence is None
            else Turbulence(setup.turbulence, n, setup.device, setup.dtype, seed))

    @property
    def air(self) -> AirInputs:
        """The air-mass motion the dynamics sees (views of the wind and gust buffers) and, once a sea is
        drawn, the surface under each aircraft (``surface``)."""
        return AirInputs(self.wind_ned, self.gust_velocity_body, self.gust_rate_body,
                         None if self.sea is None else self.surface)

    # ------------------------------------------------------------------ the sea
    def draw_sea(self, sea: SeaState, generator: torch.Generator, mask: torch.Tensor | None = None) -> None:
        """Draw a wave field of ``sea`` (``sea.sample_sea``, :attr:`EngineSetup.sea_components` components,
        from ``generator``: the same draws whatever the mask) into the rows of ``mask`` [N] bool (all when
        None) and sample their surface; the other rows keep theirs. The rows' ``sea_surface`` switch is
        the caller's (``Simulator.set_sea``)."""
        self.copy_sea(sample_sea(sea, self.num_envs, generator, self.setup.sea_components, self.setup.device,
                                 self.setup.dtype), mask)

    def copy_sea(self, field: SeaSurface, mask: torch.Tensor | None = None) -> None:
        """Copy the wave fields ``field`` ([N, K] each, K = :attr:`EngineSetup.sea_components`) into the rows
        of ``mask`` [N] bool (all when None) and sample their surface; the other rows keep theirs."""
        target_field = self.ensure_sea()
        for name, tensor in vars(field).items():
            target = getattr(target_field, name)
            if tuple(tensor.shape) != tuple(target.shape):
                raise ValueError(f"a sea field's {name} must be {list(target.shape)}, got "
                                 f"{list(tensor.shape)}")
            tensor = tensor.to(target)
            if mask is None:
                target.copy_(tensor)
            else:
                target.copy_(torch.where(mask[:, None], tensor, target))
        self.sample_surface(mask)

    def ensure_sea(self) -> SeaSurface:
        """The envs' wave fields, allocated calm (zero amplitudes) on first use; the tensors stay in place."""
        if self.sea is None:
            shape = (self.num_envs, self.setup.sea_components)
            kw = {"device": self.setup.device, "dtype": self.setup.dtype}
            self.sea = SeaSurface(*(torch.zeros(shape, **kw) for _ in range(6)))
            self.sea.direction_cos.fill_(1.0)
            self.sea.wavenumber.fill_(1.0)
        return self.sea

    def sample_surface(self, mask: torch.Tensor | None = None) -> None:
        """Sample the surface under the rows of ``mask`` (all when None) at the current state and clock into
        :attr:`surface` (torch): a sea env's sample, zeros for an env over the ground. Nothing without a
        sea drawn and no env over the sea."""
        flags = self.params.sea_surface != 0
        if self.sea is None:
            if not bool(flags.any()):
                return
            self.ensure_sea()
        assert self.sea is not None
        x = self.x
        sample = sample_surface(x, state_rotation(x), self.params.span, self.params.wing_quarter_chord,
                                self.sea,
                                self.time)
        sample = sample.masked_fill(~flags[:, None], 0.0)
        if mask is None:
            self.surface.copy_(sample)
        else:
            self.surface.copy_(torch.where(mask[:, None], sample, self.surface))

    # ------------------------------------------------------------------ the contract
    def step(self, command: torch.Tensor, substeps: int = 1, stop_at_ground: bool = False) -> None:
        """Advance every env by ``substeps`` steps of dt under ``command`` [N, 4] (clipped to
        [-1, 1], detached: the step is not differentiable), state and clock in place.

        ``stop_at_ground`` (the crash state): envs already ``crashed`` keep their state (clock, gusts
        and Dryden filters advance); an env whose CG is below the ground after the sub-steps stops on
        it (height 0, zero velocity and body rates, attitude and actuators as integrated) and is
        flagged in ``crashed`` until its reset."""
        torch.clamp(command.detach(), -1.0, 1.0, out=self.command)
        if not stop_at_ground:
            self.advance(int(substeps))
            return
        if self._before is None:
            self._before = torch.empty_like(self.x)
        self._before.copy_(self.x)
        surface_before = None
        if self.sea is not None:
            if self._surface_before is None:
                self._surface_before = torch.empty_like(self.surface)
            surface_before = self._surface_before
            surface_before.copy_(self.surface)
        self.advance(int(substeps))
        self.stop_crashed(self._before, surface_before)

    @abstractmethod
    def advance(self, substeps: int) -> None:
        """``substeps`` steps of dt under ``self.command``: Dryden gusts (when on), integration,
        projection and the clock, in place."""

    def stop_crashed(self, before: torch.Tensor, surface_before: torch.Tensor | None = None) -> None:
        """The crash state in torch, after the sub-steps: envs already ``crashed`` get ``before`` [N, S]
        (the state before the step) and ``surface_before`` [N, SURFACE_WIDTH] (their surface rows before
        the step; None without a sea) back; envs whose CG went below the ground (over the sea: the water
        under it) stop on it and are flagged. A stopped env's surface row is the step's sample moved to
        the stop: CG clearance 0 and the lower tip's clearance shifted by the height change (the
        stations' horizontal positions are unchanged; the air's flow is kept as sampled). No host sync,
        no [N, S] allocation over the ground (``before`` is overwritten)."""
        x = self.x
        crashed = self.crashed
        below = (x[:, DOWN_INDEX] > 0.0) & ~crashed
        if surface_before is None:
            x[:, DOWN_INDEX].masked_fill_(below, 0.0)
        else:
            surface = self.surface
            water = surface[:, OVER_WATER] != 0
            below = torch.where(water, surface[:, CLEARANCE] < 0.0, below) & ~crashed
            stop_down = torch.where(water, -surface[:, ELEVATION], 0.0)
            stopped = torch.where(below, stop_down, x[:, DOWN_INDEX])
            landed = below & water
            surface[:, TIP_CLEARANCE] += torch.where(landed, x[:, DOWN_INDEX] - stopped, 0.0)
            surface[:, CLEARANCE].masked_fill_(landed, 0.0)
            surface.copy_(torch.where(crashed[:, None], surface_before, surface))
            x[:, DOWN_INDEX].copy_(stopped)
        x.copy_(torch.where(crashed[:, None], before, x, out=before))
        x[:, VELOCITY.start:ANGULAR_RATE.stop].masked_fill_(below[:, None], 0.0)
        crashed |= below

    def reset(self, initial_x: torch.Tensor, initial_command: torch.Tensor,
              mask: torch.Tensor | None = None) -> None:
        """Write ``initial_x`` [N, S] and ``initial_command`` [N, 4] into the rows of ``mask`` [N]
        bool (all when None); zero their clocks, gusts and Dryden filters. Other rows untouched."""
        if mask is None:
            self.x.copy_(initial_x)
            self.command.copy_(initial_command)
            self.time.zero_()
            self.gust_velocity_body.zero_()
            self.gust_rate_body.zero_()
            self.crashed.zero_()
        else:
            self.x[mask] = initial_x[mask]
            self.command[mask] = initial_command[mask]
            self.time.masked_fill_(mask, 0.0)
            self.gust_velocity_body.masked_fill_(mask[:, None], 0.0)
            self.gust_rate_body.masked_fill_(mask[:, None], 0.0)
            self.crashed.masked_fill_(mask, False)
        if self.turbulence is not None:
            self.turbulence.reset(mask)
        self.sample_surface(mask)
        self.after_reset()

    def start(self, initial_x: torch.Tensor, initial_command: torch.Tensor,
              mask: torch.Tensor | None = None, check: Callable[[], None] | None = None,
              derive: bool = True) -> torch.Tensor | None:
        """:meth:`reset` the rows of ``mask`` [N] bool (all when None) from an unprojected
        ``initial_x`` [N, S] under ``initial_command`` [N, 4]: the ideal actuators put on the command
        and the step's projection applied first (``hold_command``, ``project``). ``check``: the
        caller's check of those rows (it raises, naming them), run before anything is written; a
        backend that screens the rows against the reset ranges (``state.MAX_RESET_*``) on the device
        runs it only when its screen finds a bad row. Returns the batch's [N, DERIVED_WIDTH] derived
        state when the backend evaluated it on the way (the engine's buffer, overwritten by the next
        evaluation), else None; ``derive=False`` tells a backend that the caller will not read it."""
        if check is not None:
            check()
        self.reset(project(hold_command(initial_x, initial_command, self.params), self.params),
                   initial_command, mask)
        return None

    def after_reset(self) -> None:
        """Hook: a backend that binds views of the buffers re-checks them here."""
        return None

    @abstractmethod
    def derived(self) -> torch.Tensor:
        """[N, DERIVED_WIDTH] derived state of the current x (``derived.DERIVED_FIELDS``)."""

    # ------------------------------------------------------------------ capabilities
    @property
    def runs_task_kernels(self) -> bool:
        """Whether a task's Warp kernels run over this engine's buffers: the capability
        (:attr:`RUNS_TASK_KERNELS`), with buffers on a CPU or CUDA device (a task step reads float64
        buffers through float32 copies)."""
        return self.RUNS_TASK_KERNELS and self.setup.device.type in ("cpu", "cuda")

    @property
    def kernel_slices(self) -> list[tuple[int, int]]:
        """(offset, count) slices of the batch that a kernel over it is launched in (one per CPU thread
        of an engine that splits its batch; the whole batch by default)."""
        return [(0, self.num_envs)]

    @property
    def kernel_device(self) -> str:
        """The Warp device of this engine's buffers (engines that run task kernels)."""
        raise NotImplementedError(f"the {type(self).__name__} runs no task kernels")

    def replayer(self, launches: list[Any], threads: int | None = None) -> Callable[[], None]:
        """A call that replays recorded Warp ``launches`` (one per :attr:`kernel_slices`) as the engine
        replays its own (engines that run task kernels)."""
        raise NotImplementedError(f"the {type(self).__name__} runs no task kernels")

    def fuse(self, task_step: Any, env: Any) -> Any | None:
        """The whole step of ``env`` (``FixedWingEnv``: the action check, the task's command, the physics
        sub-steps, the task's fused step ``task_step``, the non-finite guard, the counters and the done
        flags) as one call of this engine (``fused_env_step.FusedEnvStep``), or None where the engine
        has no such step: the env then runs those stages one after the other."""
        return None

    def reseed(self, seed: int) -> None:
        """Reseed this engine's generator and the turbulence noise streams."""
        self.generator.manual_seed(int(seed))
        if self.turbulence is not None:
            self.turbulence.reseed(int(seed))
