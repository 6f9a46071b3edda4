"""Stable-Baselines3 ``VecEnv`` over one batched simulator: SB3 trains on 64-1,024 aircraft in one
process, one simulator call per step (stable-baselines3 is optional; importing this module without
it raises a one-line ImportError).

    from stable_baselines3 import PPO
    from falcon_rl.envs.gym.sb3 import FalconSB3VecEnv
    venv = FalconSB3VecEnv.make("altitude", num_envs=256, airframe="volantex_ranger")
    PPO("MlpPolicy", venv, n_steps=64).learn(1_000_000)

SB3's conventions: ``step`` returns (obs [N, D] float32, reward [N] float32, done [N] bool, infos: a
list of N dicts); an env that is done is reset in the same step, its ``obs`` row is the next
episode's first observation and its info holds ``terminal_observation`` [D];
``info["TimeLimit.truncated"]`` is True where the episode ended at the horizon without terminating.
Infos carry only those keys unless ``info_keys`` names task entries ("altitude_error",
"termination_reason", ...) to copy per env (N dictionaries per step cost Python time). ``seed(s)``
takes effect at the next ``reset()``, which reseeds the whole batch (one seed, distinct draws per
env). Attributes and methods (``get_attr``, ``set_attr``, ``env_method``) are those of the
:class:`~falcon_rl.envs.gym.vector.FalconVectorEnv` underneath, one object for every index: reading
works for any indices, writing and calling act on the whole batch and need all indices.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium
import numpy as np

try:
    from stable_baselines3.common.vec_env import VecEnv
    from stable_baselines3.common.vec_env.base_vec_env import VecEnvIndices, VecEnvObs, VecEnvStepReturn
except ImportError as exc:
    raise ImportError("falcon_rl.envs.gym.sb3 needs stable-baselines3: pip install stable-baselines3"
                      ) from exc

from ...physics.engine import fresh_seed
from .vector import FalconVectorEnv


class FalconSB3VecEnv(VecEnv):
    """SB3 vectorised env over a :class:`FalconVectorEnv` (N envs of one batched simulator)."""

    def __init__(self, venv: FalconVectorEnv, info_keys: Sequence[str] = ()):
        self.venv = venv
        self.info_keys = tuple(info_keys)
        self._actions: np.ndarray | None = None
        super().__init__(venv.num_envs, venv.single_observation_space, venv.single_action_space)

    @classmethod
    def make(cls, task: str = "altitude", num_envs: int = 1, info_keys: Sequence[str] = (),
             **kwargs: Any) -> FalconSB3VecEnv:
        """An adapter over ``FalconVectorEnv(num_envs, task, **kwargs)`` (kwargs of ``make_env``)."""
        return cls(FalconVectorEnv(num_envs=num_envs, task=task, **kwargs), info_keys)

    # ------------------------------------------------------------------ stepping
    def reset(self) -> VecEnvObs:
        """Reset every env (reseeded when ``seed`` was called since the last reset); obs [N, D]."""
        if any(self._options):
            raise ValueError("the falcon_rl envs take no reset options")
        seed = self._seeds[0]
        observation, info = self.venv.reset(seed=seed)
        self.reset_infos = self._per_env(info)
        self._reset_seeds()
        self._reset_options()
        return observation

    def seed(self, seed: int | None = None) -> Sequence[int | None]:
        """Seed the next :meth:`reset` with ``seed`` (None: fresh OS entropy). One seed for the whole
        batch, whose envs draw distinct values of the seeded streams; returned once per env."""
        self._seeds = [fresh_seed() if seed is None else int(seed)] * self.num_envs
        return list(self._seeds)

    def step_async(self, actions: np.ndarray) -> None:
        """Keep ``actions`` [N, A] for :meth:`step_wait` (checked there, before any env moves)."""
        self._actions = actions

    def step_wait(self) -> VecEnvStepReturn:
        """(obs [N, D] float32, reward [N] float32, done [N] bool, infos) of the kept actions."""
        if self._actions is None:
            raise RuntimeError("step_wait() needs step_async(actions) first")
        actions, self._actions = self._actions, None
        step = self.venv.step_transition(actions, infos=bool(self.info_keys))
        done = step.done
        time_limit = (step.truncated & ~step.terminated).tolist()
        infos: list[dict[str, Any]] = [{"TimeLimit.truncated": flag} for flag in time_limit]
        if step.final_info is not None:
            self._copy_keys(infos, step.final_info)
        rows = np.flatnonzero(done)
        for row in rows:
            infos[row]["terminal_observation"] = step.final_observation[row].copy()
        if len(rows):
            self._record_reset_infos(step.info, rows)
        return step.observation, step.reward.astype(np.float32), done, infos

    def close(self) -> None:
        """Close the batch (and its TorchRL env)."""
        self.venv.close()

    # ------------------------------------------------------------------ attributes and methods
    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        """``venv.<attr_name>`` once per index (AttributeError when it has none)."""
        value = getattr(self.venv, attr_name)
        return [value for _ in self._get_indices(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        """Set ``venv.<attr_name>`` (for the whole batch: ``indices`` must name every env)."""
        self._whole_batch(indices, f"set_attr({attr_name!r})")
        setattr(self.venv, attr_name, value)

    def env_method(self, method_name: str, *method_args: Any, indices: VecEnvIndices = None,
                   **method_kwargs: Any) -> list[Any]:
        """Call ``venv.<method_name>(...)`` once (it acts on the whole batch: ``indices`` must name
        every env); its result is returned once per env."""
        count = self._whole_batch(indices, f"env_method({method_name!r})")
        result = getattr(self.venv, method_name)(*method_args, **method_kwargs)
        return [result] * count

    def env_is_wrapped(self, wrapper_class: type[gymnasium.Wrapper], indices: VecEnvIndices = None
                       ) -> list[bool]:
        """False for every index: the batch is one simulator, no env in it is a gymnasium.Wrapper."""
        return [False for _ in self._get_indices(indices)]

    # ------------------------------------------------------------------ internals
    def _whole_batch(self, indices: VecEnvIndices, what: str) -> int:
        """Number of indices; ValueError unless they name every env (one simulator for all)."""
        chosen = sorted(int(i) for i in self._get_indices(indices))
        if chosen != list(range(self.num_envs)):
            raise ValueError(f"{what} acts on the whole batch of {self.num_envs} envs (one simulator); "
                             f"pass indices=None, got {chosen}")
        return len(chosen)

    def _per_env(self, info: dict[str, Any]) -> list[dict[str, Any]]:
        """N dicts of the ``info_keys`` entries of a vector ``info`` (empty dicts without info_keys)."""
        infos: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        self._copy_keys(infos, {key: info[key] for key in self.info_keys if key in info})
        return infos

    def _copy_keys(self, infos: list[dict[str, Any]], arrays: dict[str, np.ndarray]) -> None:
        """Add ``arrays[key][i]`` of every ``info_keys`` entry to ``infos[i]`` (KeyError naming the
        entries when one is unknown)."""
        for key in self.info_keys:
            if key not in arrays:
                raise KeyError(f"info key {key!r} is not an entry of this env; entries: {sorted(arrays)}")
            values = arrays[key]
            rows = values.tolist() if values.ndim == 1 else list(values)
            for info, value in zip(infos, rows, strict=True):
                info[key] = value

    def _record_reset_infos(self, arrays: dict[str, np.ndarray] | None, rows: np.ndarray) -> None:
        """``reset_infos`` of the envs ``rows`` reset this step (their ``info_keys`` entries after the
        reset; ``arrays`` is the step's info after the autoreset, None without info_keys)."""
        for row in rows:
            entries = {} if arrays is None else {key: _entry(arrays[key], row) for key in self.info_keys}
            self.reset_infos[row] = entries


def _entry(values: np.ndarray, row: int) -> Any:
    """Row ``row`` of an entry array as ``_copy_keys`` gives it: a Python number of an [N] array, the
    row array of an [N, k] one."""
    return values[row].item() if values.ndim == 1 else values[row]


__all__ = ["FalconSB3VecEnv"]
