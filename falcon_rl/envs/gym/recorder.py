"""Recording flights from the Gymnasium envs: :class:`RecordFlight` wraps a single falcon_rl env,
:class:`RecordFlightVector` the native vector env; both log the simulator's whole state and
diagnostics, the action, reward, termination flags and the task's entries (from ``info``) into a
:class:`~falcon_rl.recording.Recording` (see that module for the file's schema).

    env = RecordFlight(gymnasium.make("falcon_rl/Attitude-v0", airframe="volantex_ranger"), "run.npz")
    ...                                    # reset / step as usual; the file is written on close()

Frames are the state after each step (the vector env's auto-reset rows show the next episode's first
state, as its observation does) and after each reset.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np
from gymnasium.vector import VectorWrapper

from ...recording import FlightLog, Recording, save_recording, task_extras


def _flight_base(env: Any) -> Any:
    """The FixedWingEnv under a falcon_rl Gymnasium env (its ``env`` attribute, transforms peeled)."""
    inner = getattr(env, "env", None)
    base = getattr(inner, "base_env", inner)
    if base is None or not hasattr(base, "sim"):
        raise TypeError(f"{type(env).__name__} is not a falcon_rl Gymnasium env (no flight env inside)")
    return base


def _info_extras(info: Mapping[str, Any], rows: int) -> dict[str, np.ndarray]:
    """Task entries of a Gymnasium ``info`` as [rows, ...] arrays (masks and final_* left out)."""
    entries = {key: np.asarray(value).reshape(rows, -1) for key, value in info.items()
               if not key.startswith("_") and not key.startswith("final_")
               and np.asarray(value).dtype != object}
    return {name: value[:, 0] if value.shape[1] == 1 else value
            for name, value in task_extras(entries).items()}


class _Recorder:
    """What both wrappers share: the log, the path and saving."""

    log: FlightLog
    path: Path | None

    def recording(self) -> Recording:
        """The recording so far."""
        return self.log.recording()

    def save(self, path: str | Path | None = None) -> Path:
        """Write the recording to ``path`` (default: the constructor's) and return the file."""
        return save_recording(self.log, path, self.path)


class RecordFlight(gymnasium.Wrapper, _Recorder):
    """Records a single falcon_rl Gymnasium env; ``path`` is written on :meth:`close`."""

    def __init__(self, env: gymnasium.Env, path: str | Path | None = None, max_frames: int | None = None,
                 meta: Mapping[str, Any] | None = None):
        super().__init__(env)
        self.path = None if path is None else Path(path)
        self.log = FlightLog(_flight_base(env.unwrapped), (0,), max_frames, meta)

    def reset(self, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
        observation, info = self.env.reset(**kwargs)
        self.log.capture(_info_extras(info, 1))
        return observation, info

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        observation, reward, terminated, truncated, info = self.env.step(action)
        extras = _info_extras(info, 1)
        extras.update(action=np.asarray(action, dtype=np.float32)[None], reward=np.array([reward]),
                      terminated=np.array([terminated]), truncated=np.array([truncated]))
        self.log.capture(extras)
        return observation, reward, terminated, truncated, info

    def close(self) -> None:
        if self.path is not None and len(self.log.builder):
            self.save()
        super().close()


class RecordFlightVector(VectorWrapper, _Recorder):
    """Records the envs ``env_ids`` of a :class:`~falcon_rl.envs.gym.vector.FalconVectorEnv`;
    ``path`` is written on :meth:`close`."""

    def __init__(self, env: Any, path: str | Path | None = None, env_ids: Iterable[int] = (0,),
                 max_frames: int | None = None, meta: Mapping[str, Any] | None = None):
        super().__init__(env)
        self.path = None if path is None else Path(path)
        self.log = FlightLog(_flight_base(env.unwrapped), env_ids, max_frames, meta)

    def reset(self, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
        observations, infos = self.env.reset(**kwargs)
        self.log.capture(_info_extras(infos, self.num_envs))
        return observations, infos

    def step(self, actions: Any) -> tuple[Any, Any, Any, Any, dict[str, Any]]:
        observations, rewards, terminations, truncations, infos = self.env.step(actions)
        extras = _info_extras(infos, self.num_envs)
        extras.update(action=np.asarray(actions, dtype=np.float32), reward=np.asarray(rewards),
                      terminated=np.asarray(terminations), truncated=np.asarray(truncations))
        self.log.capture(extras)
        return observations, rewards, terminations, truncations, infos

    def close(self, **kwargs: Any) -> None:
        if self.path is not None and len(self.log.builder):
            self.save()
        super().close(**kwargs)
