"""The tensor core of the Gymnasium and Stable-Baselines3 envs: it steps a :class:`FixedWingEnv` that has
no TorchRL transform over it through ``step_tensors`` / ``reset_tensors`` (no TensorDict, no
``step_mdp``, no spec checks), with NumPy out: views of the tensors on the CPU, one packed
device-to-host copy per call on another device.

It gives what TorchRL's ``step``, ``step_and_maybe_reset`` and ``reset`` give for the same env, number
for number (tests/test_gym.py, test_gym_vector.py and test_sb3.py step both side by side):
observations, rewards, flags, the ("task", ...) entries and ``termination_reason``, the non-finite
numbers of "non_finite" rows zeroed, and the SAME_STEP autoreset (a done row's observation and
entries are those of its reset, the other rows keep the step's). N envs, D observation entries, A
action channels; ``info`` arrays are [N] for a scalar entry and [N, ...] otherwise, as
``falcon_rl.envs.gym.task_arrays`` makes them.
"""

from __future__ import annotations

import functools
import math
from typing import Any, NamedTuple

import numpy as np
import torch
from torchrl.envs import EnvBase

from ..fixed_wing import FixedWingEnv


class Transition(NamedTuple):
    """One step of the batch as host arrays (N envs, D observation entries)."""

    #: [N, D] float32 after the autoreset: the next episode's first observation where ``done``.
    observation: np.ndarray
    #: [N, D] float32 before the autoreset (the same array as ``observation`` when no env was reset).
    final_observation: np.ndarray
    #: [N] in the simulation's float dtype (float32 unless the env was built with float64).
    reward: np.ndarray
    #: [N] bool each.
    terminated: np.ndarray
    truncated: np.ndarray
    #: {entry: [N, ...]}: the ("task", ...) entries and ``termination_reason`` after the autoreset
    #: (None when a step of the TorchRL path was asked for none: ``step_transition(infos=False)``).
    info: dict[str, np.ndarray] | None
    #: The same entries of the last transition, before the autoreset (None likewise).
    final_info: dict[str, np.ndarray] | None

    @property
    def done(self) -> np.ndarray:
        """[N] bool: terminated or truncated (the rows that were reset)."""
        return self.terminated | self.truncated


def tensor_core_env(env: EnvBase) -> FixedWingEnv | None:
    """``env`` when it is a :class:`FixedWingEnv` with its own ``_step`` and ``_reset`` (the tensor core
    reproduces them); None for anything else, e.g. a ``TransformedEnv`` (whose transforms run in
    TorchRL's step)."""
    kind = type(env)
    own = isinstance(env, FixedWingEnv) and kind._step is FixedWingEnv._step
    return env if own and kind._reset is FixedWingEnv._reset else None


class TensorCore:
    """Steps and resets a transform-free :class:`FixedWingEnv` with host arrays out (see the module
    docstring); ``step`` takes an [N, A] real floating tensor (the env's action contract)."""

    def __init__(self, env: FixedWingEnv):
        self.env = env
        self.num_envs = env.config.num_envs
        self.dtype = env.sim.dtype
        #: False (on the CPU): host arrays are views of the tensors; True (elsewhere): one packed copy.
        self.pack = env.device.type != "cpu"
        sample = {} if env.config.lean else env.task.info()
        #: Task entries in the order of ``task.info()`` and their trailing shapes.
        self.keys: tuple[str, ...] = tuple(sample)
        self.shapes = {key: tuple(value.shape[1:]) for key, value in sample.items()}
        #: [N, D] observation (sim dtype) and task entries after the last step or reset (own copies);
        #: None and [] before the first reset.
        self.current: np.ndarray | None = None
        self.current_entries: list[np.ndarray] = []
        #: The single env's NumPy step (:class:`NumpyStep`) where it runs, else None.
        self.numpy_step = NumpyStep.build(env) if self.num_envs == 1 and not self.pack else None

    # ------------------------------------------------------------------ API
    def reset(self, mask: np.ndarray | None = None) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """Reset every env, or the rows of ``mask`` [N] bool (the others keep their observation and
        entries); returns (observation [N, D] float32, info arrays, ``termination_reason`` 0)."""
        if mask is not None and self.current is None:
            raise RuntimeError("a partial reset needs a full reset first")
        rows = None if mask is None else torch.as_tensor(mask, device=self.env.device)
        fresh, _ = self.env.reset_tensors(rows, with_state=False)
        observation, *entries = self._host([fresh, *self._entries()])
        if mask is not None:
            observation = np.where(mask[:, None], observation, self.current)
            entries = [_select(mask, new, old)
                       for new, old in zip(entries, self.current_entries, strict=True)]
        self._keep(observation, entries)
        return observation.astype(np.float32), self._arrays(entries, np.zeros(self.num_envs, dtype=np.int64))

    def step(self, action: torch.Tensor, autoreset: bool = False) -> Transition:
        """Step every env with ``action`` [N, A]; with ``autoreset`` reset the done rows in the same step
        (SAME_STEP: their observation and entries become those of the reset)."""
        env, k = self.env, len(self.keys)
        # The wrappers publish no state; the step's own buffers are read (copied into host arrays) below,
        # before the next step overwrites them (a reset does not touch them).
        out = env.step_tensors(action, with_state=False, copy=False)
        code = out.reason.to(self.dtype) if self.pack else out.reason  # < 8: exact in the float pack
        tensors = [out.observation, out.reward, code, out.truncated, out.non_finite, *self._entries()]
        if autoreset:
            done = (out.reason > 0) | out.truncated
            if bool(done.any()):
                fresh, _ = env.reset_tensors(done, with_state=False)
                tensors += [fresh, *self._entries()]
        stepped, reward, reason, truncated, non_finite, *entries = self._host(tensors)
        reason = reason.astype(np.int64)  # a copy: the env may reuse the tensor behind a view
        terminated, truncated = reason > 0, truncated.copy()
        if non_finite.any():
            for value in entries[:k]:
                _zero_non_finite(value, non_finite)
        final_info = self._arrays(entries[:k], reason)
        if len(entries) == k:  # no env was reset
            self._keep(stepped, entries)
            observation = stepped.astype(np.float32)
            return Transition(observation, observation, reward.copy(), terminated, truncated, final_info,
                              final_info)
        done = terminated | truncated
        now = _select(done, entries[k], stepped)
        current = [_select(done, new, old) for new, old in zip(entries[k + 1:], entries[:k], strict=True)]
        self._keep(now, current)
        info = self._arrays(current, np.zeros(self.num_envs, dtype=np.int64))
        return Transition(now.astype(np.float32), stepped.astype(np.float32), reward.copy(), terminated,
                          truncated, info, final_info)

    # ------------------------------------------------------------------ internals
    def _keep(self, observation: np.ndarray, entries: list[np.ndarray]) -> None:
        """Own copies of the batch's observation [N, D] and task entries now (a partial reset keeps
        them for the rows it does not reset; the arrays handed out may be views or change hands)."""
        self.current, self.current_entries = observation.copy(), [value.copy() for value in entries]

    def _entries(self) -> list[torch.Tensor]:
        """The task's entries now ([N, ...] each, in key order; none for a lean env)."""
        if not self.keys:
            return []
        values = self.env.task.info()
        return [values[key] for key in self.keys]

    def _host(self, tensors: list[torch.Tensor]) -> list[np.ndarray]:
        """Host arrays of ``tensors`` ([N, ...] each, dtypes kept): on the CPU views (no copy); on another
        device one copy of those of the simulation's float dtype and the bool ones packed in that
        dtype (exact), plus one per tensor of another dtype."""
        if not self.pack:
            return [(tensor.detach() if tensor.requires_grad else tensor).numpy() for tensor in tensors]
        n = self.num_envs
        exact = [tensor.dtype in (self.dtype, torch.bool) for tensor in tensors]
        packed = torch.cat([tensor.reshape(n, -1).to(self.dtype)
                            for tensor, fits in zip(tensors, exact, strict=True) if fits], -1)
        flat, start, out = packed.detach().cpu().numpy(), 0, []
        for tensor, fits in zip(tensors, exact, strict=True):
            if not fits:
                out.append(tensor.detach().cpu().numpy())
                continue
            width = math.prod(tensor.shape[1:])
            out.append(flat[:, start:start + width].reshape(tensor.shape).astype(_numpy_dtype(tensor.dtype)))
            start += width
        return out

    def _arrays(self, entries: list[np.ndarray], reason: np.ndarray) -> dict[str, np.ndarray]:
        """{entry: [N] for a scalar, [N, ...] otherwise} of the task's ``entries`` (key order), then
        ``termination_reason`` [N] long."""
        n = self.num_envs
        out = {key: value.reshape(n) if math.prod(self.shapes[key]) == 1 else value
               for key, value in zip(self.keys, entries, strict=True)}
        out["termination_reason"] = reason
        return out


class NumpyStep:
    """One aircraft's step on NumPy views of the env's one-launch step (CPU, warp backend, a fused task
    step; ``FixedWingEnv.env_stepper``): the action is written into the step's input buffer, one launch
    runs the whole step, and the outputs are read from its buffers and the task's
    (``Task.info_views``): no torch operation, no TensorDict. It gives what :meth:`TensorCore.step`
    gives for the same env, number for number (tests/test_gym.py)."""

    def __init__(self, stepper: Any, entries: dict[str, np.ndarray]):
        self.stepper = stepper
        self.views: dict[str, np.ndarray] = stepper.numpy_views()
        #: {entry: (its [1] or [1, k] view, scalar?)} of the task's info, in ``info()`` order.
        self.entries = {key: (view, view[0].size == 1) for key, view in entries.items()}

    @classmethod
    def build(cls, env: FixedWingEnv) -> NumpyStep | None:
        """The NumPy step of a one-env CPU ``env``, or None where the env steps otherwise (another backend,
        no fused task step, or task entries that are computed rather than stored)."""
        stepper = env.env_stepper()
        views = {} if env.config.lean else env.task.info_views()
        if stepper is None or views is None or env.device.type != "cpu":
            return None
        return cls(stepper, {key: value.numpy() for key, value in views.items()})

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        """(observation [D] float32, reward, terminated, truncated, info) of one step with ``action``
        [A], a real floating array of that shape (checked by the caller; NaN and +-inf follow the action
        contract inside the step)."""
        views = self.views
        if action.dtype == np.float32:
            views["action"][0] = action
        else:
            with np.errstate(over="ignore"):  # a huge float64 becomes inf in float32, then clamped
                views["action"][0] = action
        self.stepper.launch()
        reason = int(views["reason"][0])
        info: dict[str, Any] = {key: view[0].item() if scalar else view[0].copy()
                                for key, (view, scalar) in self.entries.items()}
        if views["non_finite"][0]:
            info = {key: _finite_or_zero(value) for key, value in info.items()}
        info["termination_reason"] = reason
        return (views["observation"][0].copy(), views["reward"][0].item(), reason > 0,
                bool(views["truncated"][0]), info)


def _finite_or_zero(value: Any) -> Any:
    """``value`` (a float or a float array) with NaN and +-inf replaced by 0."""
    if isinstance(value, np.ndarray):
        return np.where(np.isfinite(value), value, 0).astype(value.dtype)
    return value if math.isfinite(value) else 0.0


@functools.cache
def _numpy_dtype(dtype: torch.dtype) -> np.dtype:
    """The NumPy dtype of a torch ``dtype``."""
    return torch.empty(0, dtype=dtype).numpy().dtype


def _zero_non_finite(values: np.ndarray, rows: np.ndarray) -> None:
    """Zero the NaN and +-inf of ``values`` [N, ...] (a float array; others untouched) in ``rows`` [N]
    bool, in place."""
    if values.dtype.kind == "f":
        bad = ~np.isfinite(values) & rows.reshape(-1, *([1] * (values.ndim - 1)))
        values[bad] = 0


def _select(rows: np.ndarray, where: np.ndarray, otherwise: np.ndarray) -> np.ndarray:
    """[N, ...]: ``where`` on ``rows`` [N] bool, ``otherwise`` elsewhere."""
    return np.where(rows.reshape(-1, *([1] * (where.ndim - 1))), where, otherwise)


__all__ = ["TensorCore", "Transition", "tensor_core_env"]
