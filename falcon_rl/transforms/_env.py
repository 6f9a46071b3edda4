"""The flight-env interface the transforms, recipes and evaluation helpers use, and how they find it.

The members (shapes, meaning, users) are documented on :class:`falcon_rl.envs.FixedWingEnv`; any
base env that provides them (besides TorchRL's ``batch_size`` and ``device``) works under the
transforms. :func:`flight_env` finds the base env and names the members it lacks.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Protocol

import torch
from tensordict import TensorDictBase
from torchrl.envs import Transform, TransformedEnv

#: Members of the flight-env interface (see the table on FixedWingEnv's class docstring).
FLIGHT_ENV_INTERFACE: tuple[str, ...] = (
    "control_dt", "observe", "trim_action", "physical_parameters", "nominal_physical_parameters",
    "set_physical_parameters", "episode_step", "max_episode_steps", "set_episode_step", "stagger_episodes",
    "random_state", "set_random_state",
)


class FlightEnv(Protocol):
    """Typed view of the interface; N envs, D observation entries, A action channels."""

    batch_size: torch.Size
    device: torch.device
    max_episode_steps: int

    @property
    def control_dt(self) -> float: ...

    @property
    def episode_step(self) -> torch.Tensor: ...  # [N] long

    def observe(self, state: TensorDictBase) -> torch.Tensor: ...  # [N, D]

    def trim_action(self) -> torch.Tensor: ...  # [A]

    def physical_parameters(self, names: Iterable[str] | None = None) -> dict[str, torch.Tensor]: ...

    def nominal_physical_parameters(self, names: Iterable[str] | None = None) -> dict[str, torch.Tensor]: ...

    def set_physical_parameters(self, mask: torch.Tensor | None = None, **values: torch.Tensor) -> None: ...

    def set_episode_step(self, values: torch.Tensor | int, mask: torch.Tensor | None = None) -> None: ...

    def stagger_episodes(self, generator: torch.Generator) -> None: ...

    def random_state(self) -> dict[str, torch.Tensor]: ...

    def set_random_state(self, states: dict[str, torch.Tensor]) -> None: ...


def flight_env(source: object, *members: str) -> FlightEnv:
    """The base env under ``source`` (a transform appended to a TransformedEnv, a TransformedEnv, or
    the env itself), checked to provide ``members`` (the whole interface when none are named).

    Raises RuntimeError for a transform outside a TransformedEnv and TypeError naming the missing
    interface members.
    """
    if isinstance(source, Transform):
        try:
            parent = source.parent
        except AttributeError:
            parent = None
        if parent is None:
            raise RuntimeError(f"{type(source).__name__} must be appended to a TransformedEnv")
        source = parent
    env = source
    while isinstance(env, TransformedEnv):
        env = env.base_env
    missing = [name for name in (members or FLIGHT_ENV_INTERFACE) if not hasattr(env, name)]
    if missing:
        raise TypeError(f"{type(env).__name__} lacks flight-env interface member(s) {', '.join(missing)} "
                        "(documented on falcon_rl.envs.FixedWingEnv)")
    return env  # type: ignore[return-value]
