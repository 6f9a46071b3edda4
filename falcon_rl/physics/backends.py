"""The backend registry: name -> engine class, the one place a backend is added.

    ENGINES["mine"] = "my_package.my_engine:MyEngine"      # or the class itself
    Simulator(airframe, backend="mine")

The engines (``engine.Engine`` subclasses) import only ``engine.py``; this module imports them
lazily, on first use, so that Warp is loaded only when a warp simulator is built.
"""

from __future__ import annotations

import importlib

from ..defaults import BATCH_BACKENDS, DEFAULT_BACKEND
from .engine import Engine

#: Registered backends: name -> "module:Class" (a bare module name is relative to ``falcon_rl.physics``;
#: a dotted one is imported as written; an Engine subclass may also be registered directly).
ENGINES: dict[str, str | type[Engine]] = {
    "torch": "torch_backend:TorchEngine",
    "warp": "warp_backend:WarpEngine",
    "scipy": "scipy_backend:ScipyEngine",
}


def engine_class(backend: str) -> type[Engine]:
    """The engine class registered as ``backend`` (ValueError naming the registered ones)."""
    if backend not in ENGINES:
        raise ValueError(f"backend must be one of {tuple(ENGINES)}, got {backend!r}")
    entry = ENGINES[backend]
    if isinstance(entry, str):
        module, name = entry.split(":")
        module = module if "." in module else f"{__package__}.{module}"
        entry = getattr(importlib.import_module(module), name)
    if not (isinstance(entry, type) and issubclass(entry, Engine)):
        raise TypeError(f"backend {backend!r} is registered as {entry!r}, not an Engine subclass")
    return entry


def runs_batches(backend: str) -> bool:
    """Whether ``backend`` steps more than one env at a time (its engine places a batch of two)."""
    import torch

    try:
        engine_class(backend).placement(2, torch.device("cpu"), torch.float32)
    except ValueError:
        return False
    return True


if DEFAULT_BACKEND not in BATCH_BACKENDS or not set(BATCH_BACKENDS) <= set(ENGINES):
    raise ImportError("falcon_rl.defaults names a backend that is not registered here")
