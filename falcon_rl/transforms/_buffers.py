"""Per-env ring buffers and the small helpers the transforms share."""

from __future__ import annotations

import torch
from tensordict import TensorDictBase


class DelayLine:
    """Per-env transport delay: ``push(x)`` returns the value pushed ``delay`` pushes ago.

    All envs push together (one write slot per call); each env reads its own lag, so the delay can
    differ per env (and per episode). Buffer [N, K + 1, *shape] with K the largest delay.
    """

    def __init__(self, num_envs: int, max_delay: int, shape: tuple[int, ...], dtype: torch.dtype,
                 device: torch.device):
        if max_delay < 0:
            raise ValueError(f"max_delay must be >= 0, got {max_delay}")
        self.size = max_delay + 1
        self.buffer = torch.zeros(num_envs, self.size, *shape, dtype=dtype, device=device)
        self.delay = torch.zeros(num_envs, dtype=torch.long, device=device)
        self.head = 0
        self._rows = torch.arange(num_envs, device=device)

    def push(self, value: torch.Tensor) -> torch.Tensor:
        """Write ``value`` [N, *shape] and return the delayed values [N, *shape] (a new tensor)."""
        self.buffer[:, self.head] = value
        out = self.buffer[self._rows, (self.head - self.delay) % self.size]
        self.head = (self.head + 1) % self.size
        return out

    def last_output(self) -> torch.Tensor:
        """What the last ``push`` returned (after a ``fill``, the fill value of those rows). [N, ...]"""
        return self.buffer[self._rows, (self.head - 1 - self.delay) % self.size]

    def fill(self, mask: torch.Tensor, value: torch.Tensor) -> None:
        """Set every slot of the rows in ``mask`` [N] to ``value`` [N, *shape] (the rows' history)."""
        self.buffer[mask] = value[mask].unsqueeze(1).expand(-1, self.size, *value.shape[1:]).to(self.buffer)


def reset_mask(tensordict: TensorDictBase | None, num_envs: int, device: torch.device) -> torch.Tensor:
    """The [N] bool rows a reset call touches ("_reset" of the input, all rows when absent)."""
    mask = None if tensordict is None else tensordict.get("_reset", None)
    if mask is None:
        return torch.ones(num_envs, dtype=torch.bool, device=device)
    return mask.reshape(num_envs).to(device)


def delay_steps(delay_ms: float, env_dt: float) -> int:
    """A delay in ms as a whole number of env steps (rounded)."""
    if delay_ms < 0:
        raise ValueError(f"delays must be >= 0 ms, got {delay_ms}")
    return round(delay_ms / 1000.0 / env_dt)


def delay_range(spec: float | tuple[float, float], env_dt: float) -> tuple[int, int]:
    """(low, high) steps of a fixed delay or of a (low, high) range in ms."""
    low, high = (spec, spec) if isinstance(spec, int | float) else spec
    if high < low:
        raise ValueError(f"delay range must be (low, high) with low <= high, got {spec}")
    return delay_steps(float(low), env_dt), delay_steps(float(high), env_dt)


def draw_delays(low: int, high: int, num_envs: int, generator: torch.Generator,
                device: torch.device) -> torch.Tensor:
    """[N] long delays uniform in {low, ..., high}."""
    return torch.randint(low, high + 1, (num_envs,), generator=generator, device=device)
