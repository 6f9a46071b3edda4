"""The examples run as documented (small sizes), so that a change of the env's defaults or layout
cannot silently break them."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _run(script: str, *args: str, timeout: float = 300.0) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(ROOT / "examples" / script), *args], capture_output=True,
                          text=True, timeout=timeout, cwd=ROOT, check=False)


def test_robustness_sweep_runs_every_cell(tmp_path: Path) -> None:
    done = _run("robustness_sweep.py", "--envs", "2", "--seconds", "1", "--out", str(tmp_path / "sweep"))
    assert done.returncode == 0, done.stderr[-2000:]
    results = json.loads(done.stdout.strip().splitlines()[-1])["results"]
    assert set(results) == {"sensors", "obs_delay", "action_delay", "turbulence"}
    for family, cells in results.items():
        assert set(cells) == {"nominal", "mild", "medium", "severe"}, family
    # every delay cell is a real delay at the paper's 10 ms control step (none rounds to nominal)
    levels = ("nominal", "mild", "medium", "severe")
    delays = [results["obs_delay"][level]["bank_rmse_deg"] for level in levels]
    assert len(set(delays)) == 4


def test_fly_doublet_writes_its_figure(tmp_path: Path) -> None:
    done = _run("fly_doublet.py", "--out", str(tmp_path / "doublet.png"))
    assert done.returncode == 0, done.stderr[-2000:]
    assert (tmp_path / "doublet.png").stat().st_size > 10_000


@pytest.mark.slow
def test_torchrl_pipeline_collects_batches() -> None:
    done = _run("torchrl_pipeline.py")
    assert done.returncode == 0, done.stderr[-2000:]
    assert "batch 3" in done.stdout


@pytest.mark.slow
def test_maneuver_tracks_figure(tmp_path: Path) -> None:
    done = _run("maneuver_tracks.py", "--seconds", "3", "--out", str(tmp_path))
    assert done.returncode == 0, done.stderr[-2000:]
    assert (tmp_path / "tracks.png").stat().st_size > 50_000
    assert len(list(tmp_path.glob("*.npz"))) == 8
