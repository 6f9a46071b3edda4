"""The published layout of the env's entries: every entry has a feature dim, so a scalar the simulator
holds as [N] is published as [N, 1] (as TorchRL's reward and done flags). The tasks compute with the
simulator's [N]; the metrics and figures with [N, T] series. These functions move between the three.
"""

from __future__ import annotations

import torch
from tensordict import TensorDictBase

#: State fields that are [N] in the simulator and [N, 1] under ("state", ...).
SCALAR_STATE_KEYS: frozenset[str] = frozenset(
    {"airspeed", "alpha", "beta", "height", "time", "ground_contact", "crashed"})


def column(value: torch.Tensor) -> torch.Tensor:
    """[N] -> [N, 1]; wider entries as they are (the published layout)."""
    return value.unsqueeze(-1) if value.dim() == 1 else value


def flat_scalars(td: TensorDictBase) -> TensorDictBase:
    """``td`` (an env output or a rollout, batch [N] or [N, T]) with its one-column ("state", ...)
    scalars and ("task", ...) entries ([..., 1], the published layout) as [...], and those of its
    "next" entry likewise: the series the metrics and figures compute with. A shallow copy; entries
    already flat pass through."""
    out = td.clone(recurse=False)
    depth = td.batch_dims
    nxt = td.get("next", None)
    if isinstance(nxt, TensorDictBase):
        out.set("next", flat_scalars(nxt))
    for group in ("state", "task"):
        sub = td.get(group, None)
        if sub is None:
            continue
        flat = {key: value[..., 0] for key, value in sub.items()
                if value.dim() == depth + 1 and value.shape[-1] == 1
                and (group == "task" or key in SCALAR_STATE_KEYS)}
        if flat:
            out.set(group, sub.clone(recurse=False).update(flat))
    return out


def simulator_layout(state: TensorDictBase, num_envs: int) -> TensorDictBase:
    """``state`` with its [N, 1] scalar fields as the simulator's [N] (others as they are): the layout
    the tasks compute with, from the published one (a shallow copy; [N] fields pass through)."""
    scalars = {key: value[:, 0] for key, value in state.items()
               if key in SCALAR_STATE_KEYS and isinstance(value, torch.Tensor)
               and value.shape == (num_envs, 1)}
    return state.clone(recurse=False).update(scalars) if scalars else state


__all__ = ["SCALAR_STATE_KEYS", "column", "flat_scalars", "simulator_layout"]
