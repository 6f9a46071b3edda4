"""Shared fixtures: airframes are loaded once per session."""

from __future__ import annotations

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
