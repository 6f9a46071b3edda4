"""A helper for the tests: fly a task's env at trim on both engines, for the parity of its Warp step."""

from __future__ import annotations

from tensordict import TensorDictBase

from falcon_rl import make_env


def trim_flights(task: str, airframe: str, steps: int = 20, num_envs: int = 4, seed: int = 2,
                 **options) -> dict[str, TensorDictBase]:
    """{backend: the env's TensorDict after ``steps`` trim steps from the same seeded reset} for the torch
    and warp engines."""
    outputs = {}
    for backend in ("torch", "warp"):
        env = make_env(task, airframe, num_envs=num_envs, backend=backend, seed=seed, **options)
        td = env.reset()
        action = env.trim_action().expand(num_envs, -1).clone()
        for _ in range(steps):
            td["action"] = action
            td = env.step_mdp(env.step(td))
        outputs[backend] = td
    return outputs
