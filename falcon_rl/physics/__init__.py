"""The flight model: one batched 6DoF model, written per backend (see DESIGN.md section 5).

The public names load on first use (PEP 562): importing this package imports no backend.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._lazy import lazy_exports

if TYPE_CHECKING:
    from .simulator import Simulator
    from .trim import TrimError, TrimResult, trim_level

#: Public name -> the submodule that defines it.
_LAZY = {"Simulator": "simulator", "TrimError": "trim", "TrimResult": "trim", "trim_level": "trim"}

__all__ = ["Simulator", "TrimError", "TrimResult", "trim_level"]


__getattr__, __dir__ = lazy_exports(__name__, _LAZY, __all__)
