"""The whole env step in one Warp launch (per CPU slice): the warp engine's ``fuse`` (the engine
contract's ``Engine.fuse``), for an env (``FixedWingEnv``) whose task has a fused Warp step
(``Task.fused_stepper``).

For env i, :func:`env_step_kernel`'s kernels do in order what the env's torch glue around the two launches
of the engine and the task did, with the same float32 arithmetic:

1. the action contract's values (``transforms.action_check.check_action``): a row with a NaN flies the
   centre command (0) and is flagged; the others are clamped to [-1, 1]; the result is the task's
   action buffer;
2. ``Task.command`` (the action into its channels of the task's command buffer, trim in the others) and
   ``Engine.step``'s clamp into the engine's command;
3. the physics sub-steps and the crash state (``warp_kernels.advance_env``, the engine's own step);
4. the task's step (its ``@wp.func``: reference, observation, reward, termination);
5. the non-finite guard of ``FixedWingEnv.step_tensors``: a row whose state, gusts, clock, observation
   or reward is not finite, or whose action had a NaN, ends with reason "non_finite" and its non-finite
   outputs zeroed;
6. the episode step count and the done flags: terminated (a reason), truncated (at
   ``max_episode_steps``, not when terminated) and done (either).

The kernel of a task's step is made on its first use (:func:`env_step_kernel_for`), in a Warp module of
its own (the physics and the task's step inlined), so that a launch compiles only the kernel of the task
it steps: a cold CUDA compile of one takes minutes (NVRTC, sm_90: 301 s for altitude's on a 2-core AMD
EPYC host). :class:`FusedEnvStep` binds the views (the engine's buffers, the task's, the env's counters),
records the launches and replays them; per step it copies the action into its buffer (a cast for other
float dtypes), draws the task's random numbers, bumps the turbulence stream counter when on, and
launches: nothing else runs in Python or torch. On CUDA, :meth:`FusedEnvStep.cuda_graph` captures those
(draws, counter, launch) in a CUDA graph for loops that replay it.

No ``from __future__ import annotations`` here: Warp reads the kernel factory's annotations, which name
the task's struct types through the closure.
"""

from collections.abc import Callable
from typing import Any, Protocol

import numpy as np
import torch
import warp as wp

from ._warp import KERNEL_OPTIONS
from .params import WarpParams
from .task_kernels import SimulatorViews, TaskStep
from .warp_kernels import (
    EngineViews,
    StepSettings,
    advance_env,
    flush_denormals_begin,
    flush_denormals_end,
)


class SteppedEnv(Protocol):
    """What :class:`FusedEnvStep` reads of the env it steps (``FixedWingEnv``): its config (num_envs,
    decimation), device, simulator (its engine and crash state), task (action channels, command buffer),
    episode step counter [N] long, horizon and the termination code of a non-finite step."""

    config: Any
    device: torch.device
    sim: Any
    task: Any
    step_count: torch.Tensor
    max_episode_steps: int
    non_finite_reason: int


@wp.struct
class EnvViews:
    """The env's side of a step: the action as given and as checked, the command, the counters and the
    flags it writes."""

    raw_action: wp.array2d(dtype=wp.float32)  # [N, A] the step's action (cast to float32)
    action: wp.array2d(dtype=wp.float32)  # [N, A] the checked action the task reads
    channels: wp.array(dtype=wp.int32)  # [A] the command channel of each action entry
    command_buffer: wp.array(dtype=wp.vec4)  # [N] the task's command (trim in undriven channels)
    step_count: wp.array(dtype=wp.int64)  # [N] env steps since the reset
    terminated: wp.array(dtype=wp.bool)  # [N] out: a termination reason (reason > 0)
    truncated: wp.array(dtype=wp.bool)  # [N] out: the horizon reached, not terminated
    done: wp.array(dtype=wp.bool)  # [N] out: terminated or truncated
    non_finite: wp.array(dtype=wp.bool)  # [N] out: terminated with reason "non_finite"
    max_episode_steps: wp.int64
    non_finite_reason: wp.int64  # the termination code of a non-finite step


@wp.func
def take_action(v: EnvViews, e: EngineViews, i: int) -> bool:
    """Env i's checked action, task command and engine command (steps 1-2 of the module docstring);
    returns whether the action had a NaN."""
    width = v.raw_action.shape[1]
    nan = bool(False)  # noqa: UP018 (a mutable Warp local)
    for k in range(width):
        if wp.isnan(v.raw_action[i, k]):
            nan = True
    u = v.command_buffer[i]
    for k in range(width):
        a = wp.float32(0.0)
        if not nan:
            a = wp.clamp(v.raw_action[i, k], -1.0, 1.0)
        v.action[i, k] = a
        u[v.channels[k]] = a
    v.command_buffer[i] = u
    e.command[i] = wp.vec4(wp.clamp(u[0], -1.0, 1.0), wp.clamp(u[1], -1.0, 1.0), wp.clamp(u[2], -1.0, 1.0),
                           wp.clamp(u[3], -1.0, 1.0))
    return nan


@wp.func
def vec3_finite(a: wp.vec3) -> bool:
    """Every component of ``a`` is finite."""
    return wp.isfinite(a[0]) and wp.isfinite(a[1]) and wp.isfinite(a[2])


@wp.func
def finish_step(v: EnvViews, e: EngineViews, observation: wp.array2d(dtype=wp.float32),
                reward: wp.array(dtype=wp.float32), reason: wp.array(dtype=wp.int64), nan_action: bool,
                i: int):
    """The non-finite guard, the step count and the done flags of env i (steps 5-6)."""
    finite = bool(wp.isfinite(e.time[i]) and wp.isfinite(reward[i]))
    finite = finite and vec3_finite(e.gust_velocity_body[i]) and vec3_finite(e.gust_rate_body[i])
    for k in range(e.x.shape[1]):
        if not wp.isfinite(e.x[i, k]):
            finite = False
    for k in range(observation.shape[1]):
        if not wp.isfinite(observation[i, k]):
            finite = False
    bad = nan_action or not finite
    if bad:
        reason[i] = v.non_finite_reason
        for k in range(observation.shape[1]):
            if not wp.isfinite(observation[i, k]):
                observation[i, k] = 0.0
        if not wp.isfinite(reward[i]):
            reward[i] = 0.0
    v.non_finite[i] = bad
    count = v.step_count[i] + wp.int64(1)
    v.step_count[i] = count
    terminated = reason[i] > wp.int64(0)
    truncated = count >= v.max_episode_steps and not terminated
    v.terminated[i] = terminated
    v.truncated[i] = truncated
    v.done[i] = terminated or truncated


def env_step_kernel(task_step: Any, buffers: type, constants: type) -> Any:
    """A Warp kernel of the whole env step (the module docstring) around ``task_step``, a task's
    ``@wp.func (sim, buf: buffers, c: constants, observation [N, D], reward [N], reason [N] int64, i)``,
    for env i = offset + tid, in a Warp module of its own (forward only): a launch compiles it alone."""

    def env_step(e: EngineViews, p: WarpParams, g: StepSettings, substeps: int, stop_at_ground: int,
                 v: EnvViews, sim: SimulatorViews, buf: buffers, c: constants,  # type: ignore[valid-type]
                 observation: wp.array2d(dtype=wp.float32), reward: wp.array(dtype=wp.float32),
                 reason: wp.array(dtype=wp.int64), offset: int):
        i = wp.tid() + offset
        saved = flush_denormals_begin()
        nan_action = take_action(v, e, i)
        advance_env(e, p, g, substeps, stop_at_ground, i)
        task_step(sim, buf, c, observation, reward, reason, i)
        finish_step(v, e, observation, reward, reason, nan_action, i)
        flush_denormals_end(saved)

    # A module of its own: a launch compiles this task's kernel only (a cold CUDA compile of the four
    # tasks' steps, each with the physics inlined, took minutes), and options follow this module's.
    return wp.kernel(env_step, module="unique", module_options=dict(KERNEL_OPTIONS))


#: Env-step kernels made so far, by the task step's ``@wp.func`` (each made on its first use).
_ENV_STEP_KERNELS: dict[Any, Any] = {}


def env_step_kernel_for(task_step: TaskStep) -> Any:
    """The env-step kernel around ``task_step``'s function (:func:`env_step_kernel`, made once per
    function): a built-in task's and a user's alike."""
    func = task_step.kernel_func
    if func not in _ENV_STEP_KERNELS:
        _ENV_STEP_KERNELS[func] = env_step_kernel(func, task_step.buffers, task_step.constants)
    return _ENV_STEP_KERNELS[func]


class FusedEnvStep:
    """The recorded launches of an env's whole step (one per CPU slice of the engine) with its buffers:
    the action [N, A] as given, the done flags (``flags`` [3, N, 1] bool: terminated, truncated, done;
    ``truncated`` [N] is a view of its middle row) and ``non_finite`` [N] bool; the observation, reward
    and reason buffers are the task's fused step's (:class:`TaskStep`). Every buffer is
    overwritten by the next call. It binds again when the engine binds again or a tensor it reads moved.

    ``numpy_views()`` gives NumPy views of the action and output buffers on the CPU, for callers that
    step with NumPy (write the action into the view, :meth:`launch`, read the outputs)."""

    def __init__(self, env: SteppedEnv, task_step: TaskStep):
        self.env, self.task_step = env, task_step
        self.kernel = env_step_kernel_for(task_step)
        n, device = env.config.num_envs, env.device
        task = env.task
        self.raw_action = torch.zeros(n, task.action_dim, device=device, dtype=torch.float32)
        self.flags = torch.zeros(3, n, 1, device=device, dtype=torch.bool)
        #: [N, 1] views of the three flags (a TorchRL step's columns, each cloned on its own).
        self.flag_columns: tuple[torch.Tensor, ...] = tuple(self.flags.unbind(0))
        self.truncated = self.flags[1].view(n)
        self.non_finite = torch.zeros(n, device=device, dtype=torch.bool)
        #: [N, 1] views of the task step's reward and reason (a TorchRL step's columns, cloned as they are).
        self.reward_column, self.reason_column = task_step.reward.view(n, 1), task_step.reason.view(n, 1)
        self.channels = torch.as_tensor(task.action_channels, device=device, dtype=torch.int32)
        self._launches: list[Any] = []
        self._replay: Callable[[], None] = lambda: None
        self._threads = 1
        self._key: tuple[Any, ...] = ()

    def _binding_key(self) -> tuple[Any, ...]:
        """What the launches depend on beyond buffers written in place: the engine's binding (its
        parameters object, dt, integrator, turbulence; a replaced parameter tensor is seen at the next
        reset, as by the engine), the horizon, the decimation and the crash state."""
        env, engine = self.env, self.env.sim.engine
        engine.check_binding()
        return engine.generation, env.max_episode_steps, env.config.decimation, env.sim.stop_at_ground

    def bind(self) -> None:
        """Bind the views and record the launches (binding the engine and the task step first)."""
        env, engine = self.env, self.env.sim.engine
        engine.check_binding()
        self.task_step.ensure_bound()
        views, params, settings = engine.bind_views()
        v = EnvViews()
        v.raw_action = wp.from_torch(self.raw_action)
        v.action = wp.from_torch(self.task_step.action)
        v.channels = wp.from_torch(self.channels)
        v.command_buffer = wp.from_torch(env.task.command_buffer, dtype=wp.vec4)
        v.step_count = wp.from_torch(env.step_count, dtype=wp.int64)
        n = env.config.num_envs
        v.terminated = wp.from_torch(self.flags[0].view(n), dtype=wp.bool)
        v.truncated = wp.from_torch(self.truncated, dtype=wp.bool)
        v.done = wp.from_torch(self.flags[2].view(n), dtype=wp.bool)
        v.non_finite = wp.from_torch(self.non_finite, dtype=wp.bool)
        v.max_episode_steps = int(env.max_episode_steps)
        v.non_finite_reason = int(env.non_finite_reason)
        inputs = [views, params, settings, int(env.config.decimation), int(env.sim.stop_at_ground), v,
                  *self.task_step.kernel_inputs()]
        self._threads, slices = engine.split(int(env.config.decimation))  # the sub-steps are work too
        self._launches = [wp.launch(self.kernel, dim=count, inputs=[*inputs, offset],
                                    device=engine.device, record_cmd=True)
                          for offset, count in slices]
        self._replay = engine.replayer(self._launches, self._threads)
        self._key = self._binding_key()

    def launch(self) -> None:
        """One env step of the action in :attr:`raw_action`: the task's draws, the turbulence counter and
        the launches (binding again first when needed)."""
        if not self._launches or self._binding_key() != self._key:
            self.bind()
        self.task_step.draw()
        self.env.sim.engine.bump_turbulence_counter(self.env.config.decimation)
        self._replay()

    def cuda_graph(self) -> Callable[[], None]:
        """This step captured in a CUDA graph, as a call that replays it (CUDA only; ValueError elsewhere):
        one env step of the action in :attr:`raw_action`, with the task's draws (their generators
        registered with the graph, so each replay draws fresh numbers), the turbulence counter and the
        launch, and no host work but the replay. The outputs land in the buffers :meth:`launch` writes.
        Capturing runs nothing; capture after a first step (torch and Warp load their CUDA kernels at
        their first launch, which a capture only records). A replay after the step bound again (a
        replaced parameter set, a new horizon, decimation or crash setting) raises RuntimeError:
        capture again. Resets are not in the graph (``FixedWingEnv.reset_tensors``, between
        replays)."""
        device = self.env.device
        if device.type != "cuda":
            raise ValueError(f"a CUDA graph needs a CUDA device; this env is on {device}")
        if not self._launches or self._binding_key() != self._key:
            self.bind()
        key, engine = self._key, self.env.sim.engine
        graph = torch.cuda.CUDAGraph()
        for generator in self.task_step.generators():
            graph.register_generator_state(generator)
        stream = torch.cuda.Stream(device)
        stream.wait_stream(torch.cuda.current_stream(device))
        with torch.cuda.stream(stream):
            engine.follow_torch_stream()  # the Warp view of the capture stream, made before the capture
        with torch.cuda.graph(graph, stream=stream):
            self.launch()
        torch.cuda.current_stream(device).wait_stream(stream)

        def replay() -> None:
            if self._binding_key() != key:
                raise RuntimeError("the env's step bound again since its CUDA graph was captured: capture "
                                   "a new one (FusedEnvStep.cuda_graph)")
            graph.replay()

        return replay

    #: The state of the last step as a TensorDict: None, the kernel builds none (the env's staged step,
    #: ``envs.staged_step.StagedEnvStep``, is called alike and may have one).
    state = None
    #: Its outputs are its buffers, overwritten by the next call (a caller that keeps them copies them).
    reuses_buffers = True

    def __call__(self, action: torch.Tensor, with_state: bool = True) -> tuple[torch.Tensor, ...]:
        """(observation [N, D], reward [N], reason [N] long, truncated [N], non_finite [N]) of the step
        with ``action`` [N, A] (a real float tensor of that shape, checked by the caller);
        ``with_state`` is the staged step's and ignored here (no state is built)."""
        self.raw_action.copy_(action)
        self.launch()
        t = self.task_step
        return t.observation, t.reward, t.reason, self.truncated, self.non_finite

    def torchrl_outputs(self, action: torch.Tensor) -> dict[str, torch.Tensor]:
        """A lean TorchRL step's outputs for ``action`` [N, A] (checked by the caller) as new tensors (the
        caller may keep them): ``observation`` [N, D], ``reward`` [N, 1], ``termination_reason`` [N, 1]
        long, ``terminated``, ``truncated``, ``done`` [N, 1] bool; six copies and no other operation. Each
        output owns its memory: views of one copy of the three flags (``unbind``) cost TorchRL's step
        ~15 us more at 1 env than separate copies (``benchmarks/env_step.py``)."""
        self(action)
        terminated, truncated, done = self.flag_columns
        terminated, truncated, done = terminated.clone(), truncated.clone(), done.clone()
        return {"observation": self.task_step.observation.clone(),
                "termination_reason": self.reason_column.clone(),
                "terminated": terminated, "truncated": truncated, "done": done,
                "reward": self.reward_column.clone()}

    def numpy_views(self) -> dict[str, np.ndarray]:
        """NumPy views (CPU only) of ``action`` [N, A] (write the step's action here), ``observation``
        [N, D], ``reward`` [N], ``reason`` [N], ``truncated`` [N] and ``non_finite`` [N]."""
        t = self.task_step
        tensors = {"action": self.raw_action, "observation": t.observation, "reward": t.reward,
                   "reason": t.reason, "truncated": self.truncated, "non_finite": self.non_finite}
        return {name: tensor.numpy() for name, tensor in tensors.items()}


__all__ = ["EnvViews", "FusedEnvStep", "SteppedEnv", "env_step_kernel", "env_step_kernel_for"]
