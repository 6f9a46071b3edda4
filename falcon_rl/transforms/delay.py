"""Observation and action (command) latency as TorchRL transforms, in milliseconds.

A delay is a whole number of env steps, ``round(ms / control_dt)``, fixed or drawn per env and per
episode from a (low, high) range at each reset. Each env keeps its own ring buffer, refilled on its
reset (partial resets touch only the reset rows).

- :class:`ObservationDelay`: after step t the policy sees the observation of step t - k (and the
  policy's view of the state, ("measured", ...), created from ("state", ...) when no sensor
  transform made it). The true ("state", ...) is never delayed, so metrics stay on the truth.
  Until k steps have passed since a reset, the reset observation is repeated.
- :class:`ActionDelay`: the command the policy emits at step t reaches the simulator at step t + k;
  until then the task's trim command is applied. The rollout keeps the policy's own "action"; the
  command that acted is published as "applied_action". The action contract
  (:func:`~.action_check.check_action`) is applied as the action enters the delay line: a wrong
  shape or dtype raises before anything moves, infinities are clamped, and the clean value is what
  the line holds and "applied_action" shows; a row whose action has a NaN gets a NaN command this
  very step, so that the base env terminates it now (reason "non_finite"), not k steps later.

Ranged delays are drawn from the transform's own stream (``SeededTransform``: seeded from the env).
"""

from __future__ import annotations

import torch
from tensordict import TensorDictBase
from torchrl.data import Composite

from ._buffers import DelayLine, SeededTransform, delay_bounds, delay_range, draw_delays, reset_mask
from ._env import flight_env
from .action_check import check_action


class _DelayTransform(SeededTransform):
    """Delay bookkeeping shared by the two transforms (lazy buffers sized on first reset)."""

    def __init__(self, delay_ms: float | tuple[float, float], seed: int | None = None):
        super().__init__(seed)
        delay_bounds(delay_ms)  # one-line ValueError now rather than at the first reset
        self.delay_ms = delay_ms
        self._lines: dict = {}
        self._delays: torch.Tensor | None = None

    def _steps_range(self) -> tuple[int, int]:
        return delay_range(self.delay_ms, flight_env(self, "control_dt").control_dt)

    def _draw(self, mask: torch.Tensor, num_envs: int, device: torch.device) -> torch.Tensor:
        """Per-env delays [N] long, redrawn on the rows in ``mask``."""
        low, high = self._steps_range()
        fresh = draw_delays(low, high, num_envs, self.stream("cpu"), torch.device("cpu")).to(device)
        if self._delays is None:
            self._delays = fresh
        else:
            self._delays = torch.where(mask, fresh, self._delays)
        for line in self._lines.values():
            line.delay = self._delays
        return self._delays

    def _line(self, key, value: torch.Tensor) -> DelayLine:
        line = self._lines.get(key)
        if line is None:
            line = DelayLine(value.shape[0], self._steps_range()[1], tuple(value.shape[1:]), value.dtype,
                             value.device)
            if self._delays is not None:
                line.delay = self._delays
            self._lines[key] = line
        return line

    @property
    def delays(self) -> torch.Tensor | None:
        """Current per-env delays in env steps [N] (None before the first reset)."""
        return self._delays


class ObservationDelay(_DelayTransform):
    """Delay "observation" and ("measured", ...) by ``delay_ms`` (fixed or a (low, high) range)."""

    def transform_observation_spec(self, observation_spec: Composite) -> Composite:
        if "measured" not in observation_spec.keys():  # noqa: SIM118 (a spec, not a dict)
            observation_spec["measured"] = observation_spec["state"].clone()
        return observation_spec

    def _view(self, td: TensorDictBase) -> dict:
        source = td.get("measured", None)
        if source is None:
            source = td.get("state")
        view = {("measured", k): source.get(k) for k in source.keys()}  # noqa: SIM118
        view["observation"] = td.get("observation")
        return view

    def _reset(self, tensordict: TensorDictBase, tensordict_reset: TensorDictBase) -> TensorDictBase:
        n = tensordict_reset.batch_size[0]
        mask = reset_mask(tensordict, n, tensordict_reset.device)
        self._draw(mask, n, tensordict_reset.device)
        for key, value in self._view(tensordict_reset).items():
            line = self._line(key, value)
            line.fill(mask, value)
            tensordict_reset.set(key, line.last_output())
        return tensordict_reset

    def _call(self, next_tensordict: TensorDictBase) -> TensorDictBase:
        for key, value in self._view(next_tensordict).items():
            next_tensordict.set(key, self._line(key, value).push(value))
        return next_tensordict


class ActionDelay(_DelayTransform):
    """Apply the policy's action ``delay_ms`` later (fixed or a (low, high) range per episode)."""

    def __init__(self, delay_ms: float | tuple[float, float], seed: int | None = None):
        super().__init__(delay_ms, seed)
        self._applied: torch.Tensor | None = None  # [N, A] the clean command released this step

    def transform_observation_spec(self, observation_spec: Composite) -> Composite:
        observation_spec["applied_action"] = self.parent.full_action_spec["action"].clone()
        return observation_spec

    def _reset_env_preprocess(self, tensordict: TensorDictBase) -> TensorDictBase:
        return tensordict  # a reset pushes nothing into the command path

    def _trim_action(self, n: int) -> torch.Tensor:
        """[N, A] the base env's trim action, the command applied until the first delayed one."""
        return flight_env(self, "trim_action").trim_action().expand(n, -1)

    def _reset(self, tensordict: TensorDictBase, tensordict_reset: TensorDictBase) -> TensorDictBase:
        n = tensordict_reset.batch_size[0]
        mask = reset_mask(tensordict, n, tensordict_reset.device)
        self._draw(mask, n, tensordict_reset.device)
        trim = self._trim_action(n)
        line = self._line("action", trim)
        line.fill(mask, trim)
        tensordict_reset.set("applied_action", line.last_output())
        return tensordict_reset

    def _inv_call(self, tensordict: TensorDictBase) -> TensorDictBase:
        """Check the action [N, A], push its clean value and pass the released command down (NaN on
        the rows whose action had a NaN)."""
        line = self._lines.get("action")
        if line is None:  # a step before any reset: the line starts at the trim command
            line = self._line("action", self._trim_action(flight_env(self, "trim_action").batch_size[0]))
        buffer = line.buffer  # [N, K + 1, A]
        clean, non_finite = check_action(tensordict.get("action", None), buffer.shape[0], buffer.shape[-1],
                                         buffer.dtype, buffer.device)
        self._applied = line.push(clean)
        tensordict.set("action", self._applied.masked_fill(non_finite.unsqueeze(-1), float("nan")))
        return tensordict  # on the shallow copy the base env reads

    def _step(self, tensordict: TensorDictBase, next_tensordict: TensorDictBase) -> TensorDictBase:
        next_tensordict.set("applied_action", self._applied)  # the delayed command, clean
        return next_tensordict
