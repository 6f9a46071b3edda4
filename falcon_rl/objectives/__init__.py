"""Deprecated alias of :mod:`falcon_rl.recipes` (renamed so as not to shadow ``torchrl.objectives``).

``import falcon_rl.objectives`` and ``from falcon_rl.objectives.ppo import ...`` keep working for
one release and warn; import :mod:`falcon_rl.recipes` instead.
"""

from __future__ import annotations

import importlib
import sys
import warnings

warnings.warn("falcon_rl.objectives is deprecated and will be removed in the next release; "
              "import falcon_rl.recipes instead", DeprecationWarning, stacklevel=2)

_recipes = importlib.import_module("falcon_rl.recipes")
_SUBMODULES = ("checkpoint", "common", "evaluate", "export", "logging", "off_policy", "ppo", "runner", "sac",
               "td3")
for _name in _SUBMODULES:
    sys.modules[f"{__name__}.{_name}"] = importlib.import_module(f"falcon_rl.recipes.{_name}")
globals().update({k: v for k, v in vars(_recipes).items() if not k.startswith("__")})
