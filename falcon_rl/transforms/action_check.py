"""The action contract every entry point checks before anything moves (env, delay line, Gymnasium).

    clean, non_finite = check_action(action, num_envs=N, action_dim=A, dtype=torch.float32)

- shape: [N, A] exactly (no broadcasting of a one-column action, no missing batch dim);
- dtype: any real floating dtype, cast to the spec's ``dtype``; bool, integer and complex actions are
  refused (a bool or integer action is almost always a bug, e.g. a mask or an index);
- finiteness: +-inf (and any huge value) is clamped to the action bounds [-1, 1], and the clamped
  value is what the physics, the reward's action-rate term, ``previous_action`` and the delay
  buffers see; a NaN cannot be clamped, so its row is set to 0 (the centre of the range) and
  flagged in ``non_finite`` [N] bool; the env terminates those rows that step with reason
  "non_finite" (a documented clean termination; the other envs are untouched).

A refused action raises ``ValueError`` with one line naming the entry and the constraint, before
any state, clock or buffer has changed.
"""

from __future__ import annotations

import torch


def refuse_bad_action(action: object, num_envs: int, action_dim: int, name: str = "action") -> None:
    """ValueError (one line) unless ``action`` is an [N, A] real floating tensor: the contract's
    refusals, without touching the values (no tensor operation runs)."""
    if action is None:
        raise ValueError(f"missing {name!r} entry: the step needs an [{num_envs}, {action_dim}] float action")
    if not isinstance(action, torch.Tensor):
        raise ValueError(f"{name} must be a torch.Tensor of shape [{num_envs}, {action_dim}], "
                         f"got {type(action).__name__}")
    if not action.is_floating_point():  # bool, integer and complex dtypes are not floating point
        raise ValueError(f"{name} must be a real floating tensor, got dtype {action.dtype}")
    if action.shape != (num_envs, action_dim):
        raise ValueError(f"{name} must have shape [{num_envs}, {action_dim}], got {list(action.shape)}")


def check_action(action: object, num_envs: int, action_dim: int, dtype: torch.dtype,
                 device: torch.device | str | None = None, name: str = "action"
                 ) -> tuple[torch.Tensor, torch.Tensor]:
    """(clean [N, A] in ``dtype`` within [-1, 1], non_finite [N] bool) from ``action``.

    ``action`` must be an [N, A] real floating tensor (anything else raises ValueError, one line,
    see :func:`refuse_bad_action`).
    """
    refuse_bad_action(action, num_envs, action_dim, name)
    assert isinstance(action, torch.Tensor)
    action = action.to(device=device if device is not None else action.device, dtype=dtype)
    nan = torch.isnan(action)
    non_finite = nan.any(-1)
    clean = action.masked_fill(non_finite.unsqueeze(-1), 0.0).clamp(-1.0, 1.0)
    return clean, non_finite


__all__ = ["check_action", "refuse_bad_action"]
