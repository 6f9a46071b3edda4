"""The defaults every entry point shares when a user names none, defined once (no imports: the CLI's
argument parsers read them without loading torch).

``physics.backends`` checks that the backend names are registered engines.
"""

from __future__ import annotations

#: The airframe every entry point flies when none is named (make_env, the Gymnasium ids, the CLI, the
#: recipes, the benchmarks): the Volantex Ranger, the paper's small UAV and the speed targets' airframe.
DEFAULT_AIRFRAME = "volantex_ranger"

#: The backend every entry point uses when none is named (the env, the Gymnasium ids, the recipes, the
#: evaluation protocols, the CLI): the fused Warp kernels, the fastest on CPU and GPU.
DEFAULT_BACKEND = "warp"

#: The backends that step batches of envs (the env's and the CLI's ``backend``); the SciPy reference
#: flies one env.
BATCH_BACKENDS: tuple[str, ...] = ("torch", "warp")

__all__ = ["BATCH_BACKENDS", "DEFAULT_AIRFRAME", "DEFAULT_BACKEND"]
