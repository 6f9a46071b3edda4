"""Registers falcon-rl's Gymnasium ids whenever Gymnasium is imported, in any interpreter of the environment.

Gymnasium 1.x loads no plugins: an id is known only once the package that registers it has been
imported. Tools that take only an id string (CleanRL's ``--env-id``, RLlib, a worker process started
with ``spawn``) would then get ``NamespaceNotFound`` for ``falcon_rl/Altitude-v0``. The installed
``falcon_rl_gymnasium.pth`` (run by ``site`` at interpreter start) calls :func:`install`, which puts a
finder on ``sys.meta_path`` that does nothing until ``gymnasium`` itself is imported; right after
Gymnasium's own import it imports ``falcon_rl.envs``, which registers the built-in ids (no torch:
a few ms). Interpreters that never import Gymnasium pay a string compare per first import of a module.

This module lives outside the ``falcon_rl`` package so that the start-up line imports nothing else. Any
failure in the registration is swallowed: a broken falcon_rl must never break ``import gymnasium``.
``python -m falcon_rl_gymnasium_hook`` writes the ``.pth`` into this interpreter's site-packages (for
editable installs, which do not install it; wheels carry it).
"""

from __future__ import annotations

import contextlib
import sys

TYPE_CHECKING = False  # not typing's: the start-up path imports nothing that is not already loaded
if TYPE_CHECKING:
    from importlib.abc import Loader
    from importlib.machinery import ModuleSpec
    from pathlib import Path
    from types import ModuleType

#: The start-up file's name and its one line (a guarded import: harmless once falcon-rl is removed).
PTH_NAME = "falcon_rl_gymnasium.pth"
PTH_LINE = ('import importlib.util as _u; _u.find_spec("falcon_rl_gymnasium_hook") and '
            '__import__("falcon_rl_gymnasium_hook").install()\n')
#: The module whose import triggers the registration, and the module that registers.
WATCHED, REGISTRAR = "gymnasium", "falcon_rl.envs"


class _RegisterAfterGymnasium:
    """A meta-path finder that hands out Gymnasium's own spec with its loader wrapped
    (:class:`_LoaderThenRegister`). Asking for the spec alone (``importlib.util.find_spec``, as TorchRL
    does to see whether Gymnasium is installed) imports nothing and keeps the finder in place."""

    _searching = False

    def find_spec(self, fullname: str, path: object = None, target: ModuleType | None = None
                  ) -> ModuleSpec | None:
        if fullname != WATCHED or self._searching:
            return None
        import importlib.util

        self._searching = True  # the other finders find the real spec
        try:
            spec = importlib.util.find_spec(fullname)
        finally:
            self._searching = False
        if spec is not None and spec.loader is not None:
            spec.loader = _LoaderThenRegister(spec.loader, self)
        return spec


class _LoaderThenRegister:
    """Gymnasium's loader, then the import of :data:`REGISTRAR`; the finder leaves ``sys.meta_path``."""

    def __init__(self, loader: Loader, finder: _RegisterAfterGymnasium) -> None:
        self.loader, self.finder = loader, finder

    def create_module(self, spec: ModuleSpec) -> ModuleType | None:
        return self.loader.create_module(spec)

    def exec_module(self, module: ModuleType) -> None:
        self.loader.exec_module(module)
        if self.finder in sys.meta_path:
            sys.meta_path.remove(self.finder)
        with contextlib.suppress(Exception):  # a broken falcon_rl never breaks Gymnasium
            __import__(REGISTRAR)


def install() -> None:
    """Watch for Gymnasium's import (nothing to do when it is already imported: register now)."""
    if WATCHED in sys.modules:
        with contextlib.suppress(Exception):
            __import__(REGISTRAR)
        return
    if not any(isinstance(finder, _RegisterAfterGymnasium) for finder in sys.meta_path):
        sys.meta_path.insert(0, _RegisterAfterGymnasium())


def write_pth(site_packages: str | None = None) -> Path:
    """Write :data:`PTH_NAME` into ``site_packages`` (default: this interpreter's purelib)."""
    import sysconfig
    from pathlib import Path

    path = Path(site_packages or sysconfig.get_paths()["purelib"]) / PTH_NAME
    path.write_text(PTH_LINE)
    return path


if __name__ == "__main__":
    print(write_pth())
