"""Shared fixtures: airframes are loaded once per session; the benchmark scripts as modules."""

from __future__ import annotations

import functools
import importlib.util
import sys
from pathlib import Path

import pytest
import torch

from falcon_rl import load_airframe

torch.set_num_threads(2)


@pytest.fixture(scope="session")
def navion():
    return load_airframe("navion")


@pytest.fixture(scope="session")
def ranger():
    return load_airframe("volantex_ranger")


@functools.cache
def _benchmark_script(name: str):
    """``benchmarks/<name>.py`` imported as a module (once; its dataclasses find it in sys.modules)."""
    path = Path(__file__).resolve().parents[1] / "benchmarks" / f"{name}.py"
    spec = importlib.util.spec_from_file_location(f"{name}_benchmark", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="session")
def benchmark_script():
    """``benchmark_script("env_step")``: a script under benchmarks/ as a module."""
    return _benchmark_script
