"""The flight-env interface the transforms, recipes and evaluation helpers use, and how they find it.

The members (shapes, meaning, users) are documented on :class:`falcon_rl.envs.FixedWingEnv`; any
base env that provides them (besides TorchRL's ``batch_size`` and ``device``) works under the
transforms. :func:`flight_env` finds the base env and names the members it lacks.

Seeding: TorchRL's ``TransformedEnv.set_seed`` seeds only the base env (transforms have no seed hook),
so the random transforms follow the base env's optional ``seed_record`` (:func:`seed_record`) and
derive their streams from it (``_buffers.SeededTransform``); :func:`chain_position` tells the
transforms of one env apart.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Protocol

import torch
from tensordict import TensorDictBase
from torchrl.envs import Compose, EnvBase, Transform, TransformedEnv

#: Members of the flight-env interface (see the table on FixedWingEnv's class docstring).
FLIGHT_ENV_INTERFACE: tuple[str, ...] = (
    "control_dt", "observe", "trim_action", "physical_parameters", "nominal_physical_parameters",
    "set_physical_parameters", "episode_step", "max_episode_steps", "set_episode_step", "stagger_episodes",
    "random_state", "set_random_state",
)
#: Optional members: ``seed_record`` (int, int), how many times the env was seeded (construction
#: included) and the seed it last used (the drawn one when seeded with None): the random transforms
#: reseed themselves from it when it changes (without it they keep their own seeds);
#: ``reward_term_means()``, the named reward terms' means since the last call: the recipes log them.
OPTIONAL_FLIGHT_ENV_MEMBERS: tuple[str, ...] = ("seed_record", "reward_term_means")


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


def _container(node: Transform) -> Transform | EnvBase | None:
    """The Compose or env ``node`` is appended to (None when it is not)."""
    ref = node.__dict__.get("_container")
    return ref() if ref is not None else None


def base_env_of(transform: Transform) -> EnvBase | None:
    """The env under ``transform``'s TransformedEnv chain (None while it is not appended to one)."""
    node: Transform | EnvBase | None = transform
    while isinstance(node, Transform):
        node = _container(node)
    while isinstance(node, TransformedEnv):
        node = node.base_env
    return node


def _leaves(transform: Transform) -> int:
    if isinstance(transform, Compose):
        return sum(_leaves(child) for child in transform.transforms)
    return 1


def chain_position(transform: Transform) -> int:
    """How many transforms act between the base env and ``transform`` (0: the first one; nested
    Composes and TransformedEnvs are flattened); 0 while it is not appended to an env."""
    position, node = 0, transform
    while True:
        container = _container(node)
        if isinstance(container, Compose):
            index = next(i for i, child in enumerate(container.transforms) if child is node)
            position += sum(_leaves(child) for child in container.transforms[:index])
            node = container
            continue
        if isinstance(container, TransformedEnv):
            env = container.base_env
            while isinstance(env, TransformedEnv):
                position += _leaves(env.transform)
                env = env.base_env
        return position


def seed_record(transform: Transform) -> tuple[int, int] | None:
    """The base env's ``seed_record`` (times seeded, last seed) under ``transform``; None while the
    transform is not appended to an env or when the env keeps no record."""
    record = getattr(base_env_of(transform), "seed_record", None)
    return None if record is None else (int(record[0]), int(record[1]))
