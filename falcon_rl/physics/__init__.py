"""The flight model: one batched 6DoF model, written per backend (see DESIGN.md section 5)."""

from .simulator import Simulator
from .trim import TrimError, TrimResult, trim_level

__all__ = ["Simulator", "TrimError", "TrimResult", "trim_level"]
