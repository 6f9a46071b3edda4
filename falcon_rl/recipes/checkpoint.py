"""Atomic, sealed, weights-only checkpoints.

A checkpoint is one ``torch.save`` of plain containers and tensors (no pickled classes), so it loads
with ``torch.load(path, weights_only=True)``:

    {"format": 2, "algorithm": str, "config": dict, "counters": dict,
     "modules": {name: state_dict}, "optimizers": {name: state_dict}, "norm": {stat: tensor},
     "rng": {"torch", "numpy", "python", "env", "sim", ...},
     "replay": {"size": int, "data": {key: tensor [size, ...]}, "writer": {...}},   (SAC, TD3)
     "sha256": str}

``rng`` holds every generator a run draws from: torch's global one (CUDA's too; the Collector's
random actions, the policies' samples, the replay buffer's minibatches and the losses' noise all draw
from it), numpy's and Python's, and the env's (``random_state()`` of the flight-env interface: its
generator, the simulator's, the turbulence stream) with those of its transforms that report theirs
alike. The replay entry holds the filled part of an off-policy run's replay buffer (a copy: its size
grows with the fill, not with the capacity) and its writer's cursor, so a resumed run samples from
the same transitions it would have. ``sha256`` is the content checksum of the rest
(:func:`falcon_rl.policies.format.content_digest`), verified on reading; format 1 (no checksum) is
read as legacy.

Files are written to a temporary of a unique name and moved over ``path`` with ``os.replace``
(:func:`falcon_rl.atomic_files.write_atomic`), so
a run killed mid-write leaves the previous checkpoint intact and no partial file under ``path``.
Every unreadable, corrupt, foreign or mismatched checkpoint is a one-line
:class:`~falcon_rl.policies.format.FileFormatError` naming the file.

Values are checked as well as the checksum (which only says that a file is as written): each
counter is a non-negative integer up to 2**63 - 1 (``wall_seconds`` a finite non-negative number)
with ``last_checkpoint_frames`` and ``last_eval_frames`` at most ``frames``; the config holds plain
values only (None, bools, numbers, strings, lists, dicts), as ``TrainConfig.to_dict`` writes them;
and every floating-point tensor of :data:`FINITE_ENTRIES` is finite
(:func:`~falcon_rl.policies.format.value_problem`): the networks (actor, critics, their targets and
the losses' entries), the optimiser states (a NaN moment makes NaN weights at the next step), the
normaliser and the kept best policy. Such a checkpoint is refused on loading and never written
(:func:`save_checkpoint` raises ValueError first; the earlier checkpoint stays). Not checked: the
generator states (integers) and the replay buffer's transitions, which are recorded env data (the env
publishes no NaN), not parameters.
"""

from __future__ import annotations

import math
import random
from collections.abc import Iterator
from dataclasses import fields
from pathlib import Path

import numpy as np
import torch
from tensordict import TensorDict
from torchrl.envs import TransformedEnv

from ..policies.format import (
    FileFormatError,
    atomic_save,
    read_document,
    refuse_unsound,
    seal,
    value_problem,
    verify_seal,
)
from ..transforms import flight_env
from .common import Counters

FORMAT = 2
LEGACY_FORMATS = (1,)

#: Config fields a resumed run must share with its checkpoint: the MDP, the networks, the generators.
IDENTITY_FIELDS = ("task", "airframe", "seed", "backend", "device", "cells", "activation", "critic_cells",
                   "critic_activation", "critic_layer_norm", "normalize_observations", "env_options",
                   "episode_seconds", "buffer_size", "n_step")
#: What a checkpoint written before an identity field existed had in its place.
IDENTITY_DEFAULTS = {"critic_layer_norm": False, "n_step": 1}
#: Entries whose floating-point tensors must be finite (see the module docstring).
FINITE_ENTRIES = ("modules", "optimizers", "norm", "extra")
#: Largest counter a checkpoint may hold (int64: what torch's and numpy's generators take as seeds).
MAX_COUNT = 2**63 - 1


# ---------------------------------------------------------------------------------------- generators
def _random_transforms(env) -> Iterator[tuple[str, object]]:
    """(key, transform) of every transform over ``env`` that reports its generators the way the flight
    env does (``random_state()`` / ``set_random_state(states)``)."""
    depth = 0
    while isinstance(env, TransformedEnv):
        for i, transform in enumerate(env.transform):
            if callable(getattr(transform, "random_state", None)) and callable(
                    getattr(transform, "set_random_state", None)):
                yield f"transform{depth}.{i}", transform
        env, depth = env.base_env, depth + 1


def rng_states(env=None) -> dict:
    """The state of every generator a run draws from (see the module docstring)."""
    keys, pos, has_gauss, gauss = np.random.get_state()[1:]
    version, words, gauss_next = random.getstate()
    states = {"torch": torch.get_rng_state(),
              "numpy": {"keys": torch.from_numpy(keys.astype(np.int64)), "pos": int(pos),
                        "has_gauss": int(has_gauss), "gauss": float(gauss)},
              "python": {"version": version, "state": torch.tensor(words, dtype=torch.int64),
                         "gauss": gauss_next}}
    if torch.cuda.is_available() and torch.cuda.is_initialized():
        states["cuda"] = torch.cuda.get_rng_state()
    if env is not None:
        states.update(flight_env(env, "random_state").random_state())
        for key, transform in _random_transforms(env):
            states[key] = transform.random_state()
    return states


def set_rng_states(states: dict, env=None) -> None:
    """Restore what :func:`rng_states` returned."""
    torch.set_rng_state(states["torch"])
    if "cuda" in states and torch.cuda.is_available():
        torch.cuda.set_rng_state(states["cuda"])
    if "numpy" in states:
        n = states["numpy"]
        np.random.set_state(("MT19937", n["keys"].numpy().astype(np.uint32), n["pos"], n["has_gauss"],
                             n["gauss"]))
    if "python" in states:
        p = states["python"]
        random.setstate((p["version"], tuple(int(w) for w in p["state"].tolist()), p["gauss"]))
    if env is None:
        return
    flight_env(env, "set_random_state").set_random_state(
        {k: v for k, v in states.items() if k in ("env", "sim", "turbulence")})
    for key, transform in _random_transforms(env):
        if key in states:
            transform.set_random_state(states[key])


# ---------------------------------------------------------------------------------------- writing
def save_checkpoint(path: str | Path, *, algorithm: str, config: dict, counters: dict,
                    modules: dict[str, torch.nn.Module], optimizers: dict[str, torch.optim.Optimizer],
                    norm: dict[str, torch.Tensor], env=None, extra: dict | None = None,
                    replay=None) -> Path:
    """Write a sealed, resumable checkpoint atomically (see the module docstring for the layout);
    ``replay`` is the run's replay buffer (None for on-policy runs). ValueError, with nothing written,
    when a network, optimiser state or the normaliser holds non-finite values."""
    doc = {"format": FORMAT, "algorithm": algorithm, "config": config, "counters": counters,
           "modules": {k: m.state_dict() for k, m in modules.items()},
           "optimizers": {k: o.state_dict() for k, o in optimizers.items()},
           "norm": norm, "rng": rng_states(env), "extra": extra or {}}
    refuse_unsound(doc, FINITE_ENTRIES, path)
    if replay is not None:
        doc["replay"] = replay_state(replay)
    return atomic_save(seal(doc), path)


def replay_state(buffer) -> dict:
    """The filled part of a TorchRL ``ReplayBuffer`` as plain tensors (a compact copy: slicing the
    storage alone would save all of it), and its writer's state."""
    size = len(buffer)
    data = buffer.storage[:size].to("cpu").clone().to_dict() if size else {}
    return {"size": size, "data": data, "writer": dict(buffer.writer.state_dict())}


# ---------------------------------------------------------------------------------------- reading
def load_checkpoint(path: str | Path, map_location: str | torch.device = "cpu") -> dict:
    """Read and check a checkpoint: weights-only, its format, checksum and layout; FileFormatError (one
    line naming the file) for anything that is not a sound falcon-rl checkpoint."""
    doc = read_document(path, "training checkpoint", map_location)
    fmt = doc.get("format")
    if isinstance(fmt, str) and fmt.startswith("falcon-rl-policy"):
        raise FileFormatError(path, "a policy file, not a training checkpoint (resume reads "
                                    "<out>/checkpoint.pt)")
    if fmt not in (FORMAT, *LEGACY_FORMATS):
        raise FileFormatError(path, f"not a falcon-rl training checkpoint (format {fmt!r})")
    if fmt == FORMAT:
        verify_seal(doc, path)
    layout = {"algorithm": str, "config": dict, "counters": dict, "modules": dict, "optimizers": dict,
              "norm": dict, "rng": dict}
    bad = [key for key, kind in layout.items() if not isinstance(doc.get(key), kind)]
    bad += [key for key in ("extra", "replay") if key in doc and not isinstance(doc[key], dict)]
    if bad or not isinstance(doc["rng"].get("torch"), torch.Tensor):
        raise FileFormatError(path, f"incomplete training checkpoint ({', '.join(bad) or 'rng'})")
    problem = (counters_problem(doc["counters"]) or config_problem(doc["config"])
               or value_problem(doc, FINITE_ENTRIES))
    if problem is not None:
        raise FileFormatError(path, problem)
    return doc


def _shown(value: object, width: int = 40) -> str:
    """``repr(value)``, cut to ``width`` characters."""
    text = repr(value)
    return text if len(text) <= width else text[: width - 3] + "..."


def counters_problem(counters: dict) -> str | None:
    """What is wrong with a checkpoint's ``counters`` (the fields of :class:`~.common.Counters`; see the
    module docstring), None when nothing is."""
    names = [f.name for f in fields(Counters)]
    missing, unknown = [n for n in names if n not in counters], [k for k in counters if k not in names]
    if missing or unknown:
        return f"counters lack {missing}" if missing else f"counters hold unknown entries {unknown}"
    for f in fields(Counters):
        value = counters[f.name]
        if isinstance(f.default, float):
            if type(value) not in (int, float) or not math.isfinite(value) or value < 0:
                return f"counters.{f.name} must be a finite non-negative number, got {_shown(value)}"
        elif type(value) is not int or not 0 <= value <= MAX_COUNT:
            return f"counters.{f.name} must be a non-negative integer (at most 2**63 - 1), got " \
                   f"{_shown(value)}"
    for name in ("last_checkpoint_frames", "last_eval_frames"):
        if counters[name] > counters["frames"]:
            return f"counters.{name} must be at most counters.frames ({counters['frames']}), got " \
                   f"{counters[name]}"
    return None


def config_problem(config: dict) -> str | None:
    """The first entry of a checkpoint's ``config`` that is not a plain value (None, bool, number,
    string, or a list / dict of them with string keys), None when there is none."""
    return next(_unplain(config, "config"), None)


def _unplain(value: object, name: str) -> Iterator[str]:
    """What is wrong with each entry of ``value`` (named ``name``) that is not a plain value."""
    if isinstance(value, dict):
        for key, item in value.items():
            if isinstance(key, str):
                yield from _unplain(item, f"{name}.{key}")
            else:
                yield f"{name} keys must be strings, got {_shown(key)}"
    elif isinstance(value, (list, tuple)):
        for i, item in enumerate(value):
            yield from _unplain(item, f"{name}[{i}]")
    elif value is not None and type(value) not in (bool, int, float, str):
        yield f"{name} must be a plain value (None, bool, number, string, list or dict), got a " \
              f"{type(value).__name__}"


def _plain(value):
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    return value


def check_resumable(doc: dict, path: str | Path, algorithm: str, config: dict) -> None:
    """FileFormatError unless the checkpoint ``doc`` is of ``algorithm`` and shares this run's
    ``config`` in every :data:`IDENTITY_FIELDS` entry (task, airframe, networks, seed, ...)."""
    if doc["algorithm"] != algorithm:
        raise FileFormatError(path, f"checkpoint of a {doc['algorithm']} run, cannot resume it as "
                                    f"{algorithm}")
    saved = doc["config"]
    for name in IDENTITY_FIELDS:
        had = saved.get(name, IDENTITY_DEFAULTS.get(name))
        if name in config and _plain(had) != _plain(config[name]):
            raise FileFormatError(path, f"checkpoint has {name}={_plain(had)!r}, this run "
                                        f"{_plain(config[name])!r} (resume with the same settings, or train "
                                        "into another output folder)")


def _shapes(state: dict) -> dict:
    return {k: tuple(v.shape) if isinstance(v, torch.Tensor) else type(v) for k, v in state.items()}


def _check_optimizer(saved: dict, optimizer: torch.optim.Optimizer) -> bool:
    """Whether an optimizer state dict fits ``optimizer``: its groups' sizes and its per-parameter
    state tensors' shapes."""
    groups, params = saved.get("param_groups"), [p for g in optimizer.param_groups for p in g["params"]]
    if not isinstance(groups, list) or [len(g.get("params", ())) for g in groups] != [
            len(g["params"]) for g in optimizer.param_groups]:
        return False
    for index, state in (saved.get("state") or {}).items():
        if not (isinstance(index, int) and 0 <= index < len(params) and isinstance(state, dict)):
            return False
        for value in state.values():
            if isinstance(value, torch.Tensor) and value.dim() and value.shape != params[index].shape:
                return False
    return True


def restore(doc: dict, path: str | Path, modules: dict[str, torch.nn.Module],
            optimizers: dict[str, torch.optim.Optimizer], norm=None, env=None) -> dict:
    """Load ``doc`` into the modules, optimisers, normaliser and generators, after checking that every
    network and optimiser state has this run's shapes (FileFormatError otherwise); returns its counters."""
    for name, module in modules.items():
        saved = doc["modules"].get(name)
        if not isinstance(saved, dict) or _shapes(saved) != _shapes(module.state_dict()):
            raise FileFormatError(path, f"network {name!r} of the checkpoint has other shapes than "
                                        "this run's")
    for name, optimizer in optimizers.items():
        saved = doc["optimizers"].get(name)
        if not isinstance(saved, dict) or not _check_optimizer(saved, optimizer):
            raise FileFormatError(path, f"optimiser {name!r} of the checkpoint does not fit this "
                                        "run's networks")
    if norm is not None:
        dim, shapes = tuple(norm.mean.shape), _shapes(doc["norm"])
        expected = {"mean": dim, "var": dim, "count": (), "enabled": (), "clip": (), "min_std": ()}
        if {k: shapes.get(k) for k in expected} != expected:
            raise FileFormatError(path, "observation normaliser of the checkpoint has another size")
    try:
        for name, module in modules.items():
            module.load_state_dict(doc["modules"][name])
        for name, optimizer in optimizers.items():
            optimizer.load_state_dict(doc["optimizers"][name])
        if norm is not None:
            norm.load_stats(doc["norm"])
        set_rng_states(doc["rng"], env)
    except (KeyError, TypeError, ValueError, RuntimeError, IndexError) as exc:
        raise FileFormatError(path, f"damaged training checkpoint ({type(exc).__name__} while restoring "
                                    "it)") from None
    return doc["counters"]


def load_replay(buffer, state: dict, path: str | Path = "checkpoint",
                shapes: dict[tuple[str, ...], tuple[int, ...]] | None = None) -> int:
    """Refill an empty ``buffer`` from :func:`replay_state`'s output; returns its length.

    The transitions go back to the same storage slots (0..size-1, in order) and the writer continues
    from its saved cursor, so a full, wrapped-around buffer overwrites the same oldest entries.
    ``shapes`` ({nested key: per-transition shape}) checks the saved transitions first.
    """
    if len(buffer):
        raise ValueError("load_replay needs an empty replay buffer")
    size, data, writer = state.get("size"), state.get("data"), state.get("writer")
    capacity = buffer.storage.max_size
    if type(size) is not int or not 0 <= size <= capacity or not isinstance(data, dict) \
            or not isinstance(writer, dict):
        raise FileFormatError(path, f"replay buffer entry is damaged or larger than the buffer ({capacity})")
    if size:
        flat = TensorDict.from_dict(data, batch_size=[size]) if _batched(data, size) else None
        found = None if flat is None else {k: tuple(v.shape[1:]) for k, v in flat.items(True, True)}
        if flat is None or (shapes is not None and found != {_key(k): v for k, v in shapes.items()}):
            raise FileFormatError(path, "replay buffer transitions do not fit this run's env")
    cursor = writer.get("_cursor", 0)
    if type(cursor) is not int or not 0 <= cursor < max(capacity, 1):
        raise FileFormatError(path, "replay buffer cursor is damaged")
    if size:
        buffer.extend(flat)
    buffer.writer.load_state_dict(writer)
    return len(buffer)


def _key(key: tuple[str, ...]):
    return key[0] if len(key) == 1 else key


def _batched(data: dict, size: int) -> bool:
    """Whether every tensor in the nested ``data`` has ``size`` rows."""
    return all(_batched(v, size) if isinstance(v, dict) else isinstance(v, torch.Tensor) and v.dim()
               and v.shape[0] == size for v in data.values())


__all__ = ["FINITE_ENTRIES", "FORMAT", "IDENTITY_FIELDS", "LEGACY_FORMATS", "MAX_COUNT", "atomic_save",
           "check_resumable", "config_problem", "counters_problem", "load_checkpoint", "load_replay",
           "replay_state", "restore", "rng_states", "save_checkpoint", "set_rng_states"]
