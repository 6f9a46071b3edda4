"""Recording flights from a TorchRL env: :class:`FlightRecorder`, a transform that logs chosen envs'
trajectories (the simulator's whole state and diagnostics, the action, reward, done flags, termination
reason and the task's references) into a :class:`~falcon_rl.recording.Recording` for the plots,
the 3D replays, Tacview and FlightGear.

    env = TransformedEnv(make_env("attitude", "volantex_ranger", num_envs=64), FlightRecorder([0, 1]))
    env.rollout(400, policy)
    env.transform.save("flight.npz")      # or .recording() for the object

It changes no entry and no spec, so it can sit anywhere in a transform chain (it reads the action the
base env received and the state after the step). Unappended (``parent is None``) it records nothing.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import Any

from tensordict import TensorDictBase
from torchrl.envs import Transform

from ..recording import FlightLog, Recording, save_recording, task_extras
from ._env import flight_env


class FlightRecorder(Transform):
    """Logs the envs ``env_ids`` every ``every`` steps (frames at the reset that starts recording and
    after each logged step, before any auto-reset), up to ``max_frames`` frames; ``path`` is written
    by :meth:`save` with no argument and when the env is closed."""

    def __init__(self, env_ids: Iterable[int] = (0,), every: int = 1, max_frames: int | None = None,
                 path: str | Path | None = None, meta: dict[str, Any] | None = None):
        super().__init__(in_keys=[], out_keys=[])
        if every < 1:
            raise ValueError(f"every must be at least 1, got {every}")
        self.env_ids = [int(e) for e in env_ids]
        self.every = int(every)
        self.max_frames = max_frames
        self.path = None if path is None else Path(path)
        self.meta = dict(meta or {})
        self._log: FlightLog | None = None
        self._steps = 0

    def _flight_log(self) -> FlightLog:
        if self._log is None:
            base = flight_env(self, "control_dt")
            if not hasattr(base, "sim"):
                raise TypeError(f"FlightRecorder needs a flight env with a simulator (sim), "
                                f"got {type(base).__name__}")
            meta = {"every": self.every, **self.meta}
            self._log = FlightLog(base, self.env_ids, self.max_frames, meta)
            self._log.builder.meta["dt"] = float(base.control_dt) * self.every
        return self._log

    def _reset(self, tensordict: TensorDictBase, tensordict_reset: TensorDictBase) -> TensorDictBase:
        log = self._flight_log()
        if len(log.builder) == 0:
            log.capture(task_extras(tensordict_reset.get("task", None)))
        return tensordict_reset

    def _step(self, tensordict: TensorDictBase, next_tensordict: TensorDictBase) -> TensorDictBase:
        self._steps += 1
        if self._steps % self.every or (self._log is not None and self._log.full):
            return next_tensordict  # not a recorded step, or max_frames reached: nothing gathered
        extras = task_extras(next_tensordict.get("task", None))
        for key in ("reward", "done", "terminated", "truncated", "termination_reason"):
            if key in next_tensordict:
                extras[key] = next_tensordict.get(key)
        if "action" in tensordict:
            extras["action"] = tensordict.get("action")
        self._flight_log().capture(extras)
        return next_tensordict

    def _call(self, next_tensordict: TensorDictBase) -> TensorDictBase:
        return next_tensordict

    @property
    def num_frames(self) -> int:
        """Frames recorded so far."""
        return 0 if self._log is None else len(self._log.builder)

    def recording(self) -> Recording:
        """The recording so far (raises ValueError when nothing was recorded)."""
        if self._log is None:
            raise ValueError("nothing was recorded: append the recorder to an env and reset it")
        return self._log.recording()

    def save(self, path: str | Path | None = None) -> Path:
        """Write the recording to ``path`` (default: the constructor's) and return the file written."""
        return save_recording(self._log, path, self.path)

    def close(self) -> None:
        if self.path is not None and self.num_frames:
            self.save()
        super().close()
