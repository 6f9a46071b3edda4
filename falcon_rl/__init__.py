"""falcon-rl: TorchRL-native simulator and control-learning suite for fixed-wing aircraft
flying near the ground."""

from .airframe import Airframe, AirframeError, list_airframes, load_airframe
from .envs import make_env
from .physics import Simulator, TrimError, trim_level

__version__ = "0.1.0"
__all__ = ["Airframe", "AirframeError", "Simulator", "TrimError", "__version__", "list_airframes",
           "load_airframe", "make_env", "trim_level"]
