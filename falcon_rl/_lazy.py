"""Public names that load on first use (PEP 562), for the package ``__init__`` modules:

    _LAZY = {"make_env": "factory", ...}          # public name -> the submodule that defines it
    __getattr__, __dir__ = lazy_exports(__name__, _LAZY, __all__)

so that ``import falcon_rl`` imports neither torch, torchrl nor warp until a name that needs them is
used. A loaded name is cached in the package's namespace.
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Iterable, Mapping
from typing import Any


def lazy_exports(package: str, table: Mapping[str, str], public: Iterable[str]
                 ) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """(``__getattr__``, ``__dir__``) of ``package`` whose names in ``table`` come from
    ``package.<table[name]>``, imported when first asked for; ``public`` is its ``__all__``."""
    names = tuple(public)

    def __getattr__(name: str) -> Any:  # noqa: N807 (the module hook PEP 562 names)
        if name not in table:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(f"{package}.{table[name]}"), name)
        setattr(sys.modules[package], name, value)
        return value

    def __dir__() -> list[str]:  # noqa: N807
        return sorted({*vars(sys.modules[package]), *names})

    return __getattr__, __dir__


__all__ = ["lazy_exports"]
