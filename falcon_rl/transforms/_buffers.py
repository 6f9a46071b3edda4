"""Per-env ring buffers, the seeded base of the random transforms, and the small functions the
transforms share."""

from __future__ import annotations

import math
from typing import Any

import torch
from tensordict import TensorDictBase
from torchrl.envs import EnvBase, Transform

from ..physics.engine import PicklableGenerator, derive_seed, fresh_seed, make_generator
from ._env import chain_position, seed_record


class SeededTransform(Transform):
    """Base of the transforms that draw random numbers: each owns one stream, seeded from the env.

    The stream is a generator seeded with ``derive_seed(root, position, class name)`` (position: the
    transform's place in the env's chain, :func:`~._env.chain_position`), so the transforms of one env
    draw distinct streams from one root seed. The root is the latest of

    - the base env's seeding (its ``seed_record``): ``make_env(seed=s)``, ``env.set_seed(s)`` (also
      through ParallelEnv / SerialEnv / collectors, which seed their workers distinctly) and
      ``reset(seed=s)`` on envs that take it all reach every transform;
    - the transform's own seed (constructor, :meth:`reseed`, assigning ``seed``); an env seeded
      before the transform was appended counts as older, and an unseeded transform follows the env.

    With neither (unseeded, over an env that keeps no seed record) it is fresh OS entropy. A reseed
    restarts the stream at the next draw. The transform pickles with its stream (state bytes), its
    buffers and the record it follows.
    """

    def __init__(self, seed: int | None = None):
        super().__init__(in_keys=[], out_keys=[])
        self._seed = None if seed is None else int(seed)
        self._root: int | None = None  # root seed of the current stream (decided at the first draw)
        self._record: tuple[int, int] | None = None  # the env's seed record last seen
        self._generator: PicklableGenerator | None = None

    def set_container(self, container: Transform | EnvBase) -> None:
        super().set_container(container)
        record = seed_record(self)
        if record is not None and record != self._record:
            self._record = record  # seen at appending: only a later reseed of the env restarts us
            if self._seed is None and self._generator is None:
                self._root = record[1]

    @property
    def seed(self) -> int | None:
        """The transform's own seed (None: follow the env, else fresh entropy); assigning it reseeds."""
        return self._seed

    @seed.setter
    def seed(self, value: int | None) -> None:
        self.reseed(value)

    def reseed(self, seed: int | None) -> None:
        """Restart this transform's stream from ``seed`` (None: fresh entropy) at its next draw (a
        later reseed of the env takes over again)."""
        self._seed = None if seed is None else int(seed)
        self._root = self._seed
        self._generator = None
        self._record = seed_record(self) or self._record  # the env's current seeding is older

    def stream(self, device: torch.device | str = "cpu") -> torch.Generator:
        """This transform's generator on ``device``, restarted first when the env was reseeded since
        the last draw (or made on another device)."""
        record = seed_record(self)
        if record is not None and record != self._record:
            self._record = record
            self._root = record[1]
            self._generator = None
        device = torch.device(device)
        if device.type == "cuda" and device.index is None:
            device = torch.device("cuda", torch.cuda.current_device())
        if self._generator is None or self._generator.device != device:
            if self._root is None:
                self._root = self._seed if self._seed is not None else fresh_seed()
            self._generator = make_generator(device, derive_seed(self._root, chain_position(self),
                                                                 type(self).__name__))
        return self._generator

    @property
    def root_seed(self) -> int | None:
        """The seed the current stream derives from (None before the first draw)."""
        return self._root

    def random_state(self) -> dict[str, torch.Tensor]:
        """This transform's stream as tensors (checkpoints): "seeds" [4] long (own seed, root, and the
        env seed record followed; -1 for none) and "generator" (its state bytes, empty before the
        first draw)."""
        record = self._record or (-1, -1)
        seeds = [-1 if v is None else v for v in (self._seed, self._root)] + list(record)
        generator = (self._generator.get_state() if self._generator is not None
                     else torch.zeros(0, dtype=torch.uint8))
        return {"seeds": torch.tensor(seeds, dtype=torch.long), "generator": generator,
                "device": torch.tensor(-1 if self._generator is None or self._generator.device.type == "cpu"
                                       else int(self._generator.device.index or 0))}

    def set_random_state(self, states: dict[str, torch.Tensor]) -> None:
        """Restore what :meth:`random_state` returned: the next draw continues the same stream."""
        own, root, count, last = (int(v) for v in states["seeds"].tolist())
        self._seed = None if own < 0 else own
        self._root = None if root < 0 else root
        self._record = None if count < 0 else (count, last)
        self._generator = None
        if states["generator"].numel():
            index = int(states["device"])
            device = torch.device("cpu") if index < 0 else torch.device("cuda", index)
            self._generator = make_generator(device, 0)
            self._generator.set_state(states["generator"])

    def __getstate__(self) -> dict[str, Any]:
        state = super().__getstate__()
        state["_parent"] = None  # a cache of the env up to this transform, rebuilt on demand
        return state


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


#: Longest delay a transform accepts, ms (its ring buffer holds this many env steps per env).
MAX_DELAY_MS = 10_000.0


def delay_bounds(spec: object) -> tuple[float, float]:
    """(low, high) ms of a fixed delay or a (low, high) range; ValueError (one line) unless both are
    finite numbers in [0, MAX_DELAY_MS] with low <= high."""
    pair = (spec, spec) if isinstance(spec, int | float) else spec
    if not (isinstance(pair, tuple | list) and len(pair) == 2):
        raise ValueError(f"a delay is milliseconds or a (low, high) pair of them, got {spec!r}")
    for value in pair:
        if not (isinstance(value, int | float) and math.isfinite(value) and 0.0 <= value <= MAX_DELAY_MS):
            raise ValueError(f"delays must be finite numbers in [0, {MAX_DELAY_MS:g}] ms, got {spec!r}")
    low, high = float(pair[0]), float(pair[1])
    if high < low:
        raise ValueError(f"delay range must be (low, high) with low <= high, got {spec!r}")
    return low, high


def delay_steps(delay_ms: float, control_dt: float) -> int:
    """A delay in ms as a whole number of env steps (rounded)."""
    low, _ = delay_bounds(delay_ms)
    return round(low / 1000.0 / control_dt)


def delay_range(spec: float | tuple[float, float], control_dt: float) -> tuple[int, int]:
    """(low, high) steps of a fixed delay or of a (low, high) range in ms (see :func:`delay_bounds`);
    ValueError when a delay that is not zero rounds to no step at this control period (a 20 ms delay
    at 20 Hz control would silently be no delay)."""
    low, high = delay_bounds(spec)
    steps = round(low / 1000.0 / control_dt), round(high / 1000.0 / control_dt)
    if high > 0 and steps[1] == 0:
        raise ValueError(f"a delay of {high:g} ms is under half the {1000 * control_dt:g} ms control step "
                         f"and would round to no delay; use a longer delay or a faster control (decimation)")
    return steps


def draw_delays(low: int, high: int, num_envs: int, generator: torch.Generator,
                device: torch.device) -> torch.Tensor:
    """[N] long delays uniform in {low, ..., high}."""
    return torch.randint(low, high + 1, (num_envs,), generator=generator, device=device)
