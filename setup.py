"""Setuptools reads the project from pyproject.toml; this file adds one thing it cannot declare: the
start-up file ``falcon_rl_gymnasium.pth`` at the root of the wheel (so in site-packages), which registers
falcon-rl's Gymnasium ids in every interpreter that imports Gymnasium (see falcon_rl_gymnasium_hook.py).
Editable installs do not carry root files: ``make`` writes it with ``python -m falcon_rl_gymnasium_hook``."""

import sys
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the build runs isolated, outside this folder
from falcon_rl_gymnasium_hook import PTH_LINE, PTH_NAME


class BuildWithStartupFile(build_py):
    """``build_py`` that also writes the start-up file into the build's root (the wheel's root)."""

    def run(self) -> None:
        super().run()
        if not self.editable_mode:
            Path(self.build_lib, PTH_NAME).write_text(PTH_LINE)

    def get_outputs(self, include_bytecode: bool = True) -> list[str]:
        extra = [] if self.editable_mode else [str(Path(self.build_lib, PTH_NAME))]
        return [*super().get_outputs(include_bytecode), *extra]


setup(cmdclass={"build_py": BuildWithStartupFile})
