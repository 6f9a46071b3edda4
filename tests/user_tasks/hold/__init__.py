"""The throttle hold task: :mod:`.task`, :mod:`.kernels` and :mod:`.spec`, as CONTRIBUTING.md lays out a
task folder."""

from .spec import SPEC
from .task import HoldConfig, HoldTask

__all__ = ["SPEC", "HoldConfig", "HoldTask"]
