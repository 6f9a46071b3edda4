"""The speed-targets benchmark (``benchmarks/speed_targets.py``) runs end to end on tiny batches and
writes its table, JSON and figure; what counts as met. Functional only: no figure is checked against a
speed."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest


def test_a_target_is_met_when_its_median_reaches_it(benchmark_script):
    bench = benchmark_script("speed_targets")
    assert bench.Target("a", 0.8, "", 0.8, "x").met and not bench.Target("b", 0.79, "", 0.8, "x").met


def test_every_target_is_measured_and_written(tmp_path: Path, capsys, benchmark_script):
    pytest.importorskip("jsbsim")
    pytest.importorskip("stable_baselines3")
    bench = benchmark_script("speed_targets")
    code = bench.main(["--trials", "1", "--envs", "8", "--vector-envs", "8", "--out", str(tmp_path),
                       "--no-progress"])
    doc = json.loads((tmp_path / "speed_targets.json").read_text())
    assert len(doc["targets"]) == 6 and (tmp_path / "speed_targets.png").stat().st_size > 0
    assert all(math.isfinite(t["measured"]) and t["measured"] > 0 for t in doc["targets"])
    assert code == (0 if all(t["met"] for t in doc["targets"]) else 1)
    assert "| TorchRL env step / Simulator.step, 8 envs |" in capsys.readouterr().out
