"""falcon-rl: a TorchRL-native simulator and control-learning suite for fixed-wing aircraft flying near
the ground.

The public names load on first use (PEP 562), so ``import falcon_rl`` stays light: it imports neither
torch, TorchRL nor Warp, and registers the tasks' Gymnasium ids (``gym.make("falcon_rl/Altitude-v0")``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from . import envs as _envs  # noqa: F401 (registers the Gymnasium ids)
from ._lazy import lazy_exports

if TYPE_CHECKING:
    from .airframe import Airframe, AirframeError, list_airframes, load_airframe
    from .envs import make_env
    from .physics import Simulator, TrimError, trim_level
    from .recording import Recording

__version__ = "0.1.0"

#: Public name -> the module that defines it.
_LAZY = {"Airframe": "airframe", "AirframeError": "airframe", "list_airframes": "airframe",
         "load_airframe": "airframe", "make_env": "envs", "Simulator": "physics", "TrimError": "physics",
         "trim_level": "physics", "Recording": "recording"}

__all__ = ["Airframe", "AirframeError", "Recording", "Simulator", "TrimError", "__version__",
           "list_airframes", "load_airframe", "make_env", "trim_level"]


__getattr__, __dir__ = lazy_exports(__name__, _LAZY, __all__)
