"""Training recipes on TorchRL: :mod:`ppo`, :mod:`sac` and :mod:`td3`, one file each, and the
pieces they share (networks, checkpoints, policy export, logging, evaluation).

    from falcon_rl.recipes import algorithm
    module = algorithm("ppo")                       # falcon_rl.recipes.ppo
    summary = module.train(module.make_config("altitude", frames=2_000_000))
"""

from __future__ import annotations

import importlib
from types import ModuleType

from ..policies import load_policy, read_policy, save_policy

NAMES = ("ppo", "sac", "td3")


def algorithm(name: str) -> ModuleType:
    """The recipe module of ``name`` (one of ``NAMES``): ``make_config`` and ``train``."""
    if name not in NAMES:
        raise ValueError(f"unknown algorithm {name!r}; choose one of {list(NAMES)}")
    return importlib.import_module(f"{__name__}.{name}")


__all__ = ["NAMES", "algorithm", "load_policy", "read_policy", "save_policy"]
