"""Checks of a recipe config before anything is built: every field's type (from its annotation) and
range, and the policy file format's limits on the networks; a one-line ValueError names the field.

    check_config(ppo.make_config("altitude", rollout_steps=0))   # ValueError: rollout_steps must be >= 1
"""

from __future__ import annotations

import itertools
import math
import types
import typing
from dataclasses import fields

from ..defaults import BATCH_BACKENDS
from ..envs import task_spec
from ..policies.format import ACTIVATIONS, MAX_LAYERS, MAX_PARAMETERS, MAX_WIDTH
from .logging import LOGGERS
from .selection import parse_stop_when

#: Largest count a field takes; frame counts may be larger.
MAX_COUNT = 10**9
MAX_FRAMES = 10**15
MAX_ENVS = 1 << 20

#: Fields (where a recipe has them) and their ranges.
AT_LEAST_ONE = ("num_envs", "rollout_steps", "epochs", "minibatches", "batch_size", "buffer_size",
                "updates_per_batch", "policy_delay", "frames", "checkpoint_every", "n_step")
AT_LEAST_ZERO = ("seed", "threads", "eval_every", "eval_episodes", "final_eval_episodes", "confirm_episodes",
                 "init_random_frames")
POSITIVE = ("lr", "actor_lr", "critic_lr", "alpha_lr", "alpha_init", "norm_min_std", "clip_epsilon",
            "max_grad_norm", "episode_seconds", "eval_seconds", "reward_scale")
NON_NEGATIVE = ("entropy_coeff", "critic_coeff", "exploration_noise", "policy_noise", "noise_clip")
UNIT_INTERVAL = ("gamma", "gae_lambda", "tau")
LARGE = ("frames", "checkpoint_every", "eval_every", "init_random_frames")
CHOICES: dict[str, tuple] = {"activation": tuple(ACTIVATIONS), "critic_activation": tuple(ACTIVATIONS),
                             "backend": BATCH_BACKENDS, "logger": LOGGERS, "resume": (False, True, "auto")}


def _finite(value: object) -> bool:
    try:
        return math.isfinite(value)  # type: ignore[arg-type]
    except (TypeError, OverflowError):
        return False


def _fits(value: object, hint: object) -> bool:
    """Whether ``value`` has the annotated type ``hint`` (bool is no int; floats are finite)."""
    origin = typing.get_origin(hint)
    if origin in (typing.Union, types.UnionType):
        return any(_fits(value, h) for h in typing.get_args(hint))
    if origin is tuple:
        return isinstance(value, tuple) and all(_fits(v, typing.get_args(hint)[0]) for v in value)
    if hint is type(None):
        return value is None
    if hint is float:
        return type(value) in (int, float) and _finite(value)
    if hint in (int, bool, str):
        return type(value) is hint
    return isinstance(value, origin or hint)  # type: ignore[arg-type]


def _describe(hint: object) -> str:
    origin = typing.get_origin(hint)
    if origin in (typing.Union, types.UnionType):
        return " or ".join(_describe(h) for h in typing.get_args(hint))
    if origin is tuple:
        return "a tuple of integers, e.g. (64, 64)"
    names = {int: "an integer", float: "a finite number", bool: "True or False", str: "a string",
             dict: "a dict", type(None): "None"}
    return names.get(hint, getattr(hint, "__name__", str(hint)))  # type: ignore[call-overload]


def _short(value: object) -> str:
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _check_range(name: str, value: object) -> str | None:
    """The reason ``value`` is out of range for field ``name``, or None."""
    high = MAX_FRAMES if name in LARGE else MAX_ENVS if name == "num_envs" else MAX_COUNT
    if value is None:
        return None
    if name in AT_LEAST_ONE + AT_LEAST_ZERO:
        low = 1 if name in AT_LEAST_ONE else 0
        return None if low <= value <= high else f"must be in [{low}, {high:,}]"  # type: ignore[operator]
    if name in POSITIVE and not value > 0:  # type: ignore[operator]
        return "must be > 0"
    if name in NON_NEGATIVE and not value >= 0:  # type: ignore[operator]
        return "must be >= 0"
    if name in UNIT_INTERVAL and not 0 < value <= 1:  # type: ignore[operator]
        return "must be in (0, 1]"
    if name in CHOICES and value not in CHOICES[name]:
        return f"must be one of {list(CHOICES[name])}"
    if name == "target_entropy" and isinstance(value, str) and value != "auto":
        return "must be a finite number or 'auto'"
    if name in ("cells", "critic_cells"):
        cells = list(value)  # type: ignore[call-overload]
        parameters = sum(a * b + b for a, b in itertools.pairwise(cells))
        if not 1 <= len(cells) <= MAX_LAYERS or not all(1 <= c <= MAX_WIDTH for c in cells) \
                or parameters > MAX_PARAMETERS:
            return (f"must be 1 to {MAX_LAYERS} widths in [1, {MAX_WIDTH}] with at most "
                    f"{MAX_PARAMETERS:,} parameters")
    return None


def check_config(cfg: object) -> None:
    """ValueError (one line naming the field) unless every field of the recipe config ``cfg`` (a
    dataclass) has its annotated type and lies in its range."""
    hints = typing.get_type_hints(type(cfg))
    for f in fields(cfg):  # type: ignore[arg-type]
        value = getattr(cfg, f.name)
        if not _fits(value, hints[f.name]):
            raise ValueError(f"{f.name} must be {_describe(hints[f.name])}, got {_short(value)}")
        reason = _check_range(f.name, value)
        if reason:
            raise ValueError(f"{f.name} {reason}, got {_short(value)}")
    batch_size, buffer_size = getattr(cfg, "batch_size", 1), getattr(cfg, "buffer_size", None)
    n_step, rollout_steps = getattr(cfg, "n_step", 1), getattr(cfg, "rollout_steps", 1)
    if n_step > rollout_steps:
        raise ValueError(f"n_step ({n_step}) must not exceed rollout_steps ({rollout_steps}): the returns "
                         "are summed within one collected batch")
    if buffer_size is not None and batch_size > buffer_size:
        raise ValueError(f"batch_size ({batch_size}) must not exceed buffer_size ({buffer_size})")
    stop_when = getattr(cfg, "stop_when", "")
    if stop_when:
        parse_stop_when(stop_when, task_spec(cfg.task).metric_keys)  # type: ignore[attr-defined]
        if not (cfg.eval_every and cfg.eval_episodes):  # type: ignore[attr-defined]
            raise ValueError("stop_when needs eval_every > 0 and eval_episodes > 0 (the validations it "
                             "is checked on)")
    if getattr(cfg, "keep_best", False):
        if not (cfg.eval_every and cfg.eval_episodes):  # type: ignore[attr-defined]
            raise ValueError("keep_best needs eval_every > 0 and eval_episodes > 0 (the validation "
                             "evaluations it picks the policy from)")
        if task_spec(cfg.task).select_on is None:  # type: ignore[attr-defined]
            raise ValueError(f"keep_best: task {cfg.task!r} names no metric to select on "  # type: ignore[attr-defined]
                             "(TaskSpec.select_on)")


__all__ = ["MAX_COUNT", "MAX_ENVS", "MAX_FRAMES", "check_config"]
