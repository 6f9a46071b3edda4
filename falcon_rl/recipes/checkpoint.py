"""Atomic, weights-only checkpoints.

A checkpoint is one ``torch.save`` of plain containers and tensors (no pickled classes), so it loads
with ``torch.load(path, weights_only=True)``:

    {"format": 1, "algorithm": str, "config": dict, "counters": dict,
     "modules": {name: state_dict}, "optimizers": {name: state_dict}, "norm": {stat: tensor},
     "rng": {"torch": ByteTensor, "env": ByteTensor, "sim": ByteTensor, ...},
     "replay": {"size": int, "data": {key: tensor [size, ...]}, "writer": {...}}}   (SAC, TD3)

The replay entry holds the filled part of an off-policy run's replay buffer (nested dicts of tensors)
and its writer's cursor, so a resumed run samples from the same transitions it would have.

Files are written to ``<path>.tmp`` and moved over ``path`` with ``os.replace`` (atomic on POSIX), so
a run killed mid-write leaves the previous checkpoint intact and no partial file under ``path``.
"""

from __future__ import annotations

from pathlib import Path

import torch
from tensordict import TensorDict

from ..policies.format import atomic_save
from ..transforms import flight_env

FORMAT = 1


def rng_states(env=None) -> dict[str, torch.Tensor]:
    """Torch's global RNG state and the env's random state (``random_state()`` of the flight-env
    interface: its generator, the simulator's, the turbulence stream counter) when given."""
    states = {"torch": torch.get_rng_state()}
    if torch.cuda.is_available() and torch.cuda.is_initialized():
        states["cuda"] = torch.cuda.get_rng_state()
    if env is not None:
        states.update(flight_env(env, "random_state").random_state())
    return states


def set_rng_states(states: dict[str, torch.Tensor], env=None) -> None:
    torch.set_rng_state(states["torch"])
    if "cuda" in states and torch.cuda.is_available():
        torch.cuda.set_rng_state(states["cuda"])
    if env is not None:
        flight_env(env, "set_random_state").set_random_state(
            {k: v for k, v in states.items() if k not in ("torch", "cuda")})


def save_checkpoint(path: str | Path, *, algorithm: str, config: dict, counters: dict,
                    modules: dict[str, torch.nn.Module], optimizers: dict[str, torch.optim.Optimizer],
                    norm: dict[str, torch.Tensor], env=None, extra: dict | None = None,
                    replay=None) -> Path:
    """Write a resumable checkpoint atomically (see the module docstring for the layout);
    ``replay`` is the run's replay buffer (None for on-policy runs)."""
    doc = {"format": FORMAT, "algorithm": algorithm, "config": config, "counters": counters,
           "modules": {k: m.state_dict() for k, m in modules.items()},
           "optimizers": {k: o.state_dict() for k, o in optimizers.items()},
           "norm": norm, "rng": rng_states(env), "extra": extra or {}}
    if replay is not None:
        doc["replay"] = replay_state(replay)
    return atomic_save(doc, path)


def replay_state(buffer) -> dict:
    """The filled part of a TorchRL ``ReplayBuffer`` as plain tensors, and its writer's state."""
    size = len(buffer)
    data = buffer[:size].to("cpu").to_dict() if size else {}
    return {"size": size, "data": data, "writer": dict(buffer.writer.state_dict())}


def load_replay(buffer, state: dict) -> int:
    """Refill an empty ``buffer`` from :func:`replay_state`'s output; returns its length.

    The transitions go back to the same storage slots (0..size-1, in order) and the writer continues
    from its saved cursor, so a full, wrapped-around buffer overwrites the same oldest entries.
    """
    if len(buffer):
        raise ValueError("load_replay needs an empty replay buffer")
    size = int(state["size"])
    if size:
        buffer.extend(TensorDict.from_dict(state["data"], batch_size=[size]))
    buffer.writer.load_state_dict(state["writer"])
    return len(buffer)


def load_checkpoint(path: str | Path, map_location: str | torch.device = "cpu") -> dict:
    """Read a checkpoint with ``weights_only=True`` (plain containers and tensors only)."""
    doc = torch.load(path, map_location=map_location, weights_only=True)
    if doc.get("format") != FORMAT:
        raise ValueError(f"{path}: not a falcon-rl checkpoint (format {doc.get('format')!r})")
    return doc


def restore(doc: dict, modules: dict[str, torch.nn.Module], optimizers: dict[str, torch.optim.Optimizer],
            norm=None, env=None) -> dict:
    """Load ``doc`` into the modules, optimisers, normaliser and RNGs; returns its counters."""
    for name, module in modules.items():
        module.load_state_dict(doc["modules"][name])
    for name, optimizer in optimizers.items():
        optimizer.load_state_dict(doc["optimizers"][name])
    if norm is not None:
        norm.load_stats(doc["norm"])
    set_rng_states(doc["rng"], env)
    return doc["counters"]


__all__ = ["atomic_save", "load_checkpoint", "load_replay", "replay_state", "restore", "rng_states",
           "save_checkpoint", "set_rng_states"]
