"""The ``falcon-rl bench`` CLI: JSON shape on a tiny run, and bad input -> exit code 2."""

from __future__ import annotations

import json

import pytest

from falcon_rl.cli import main


def test_bench_json_shape(capsys, tmp_path):
    code = main(["bench", "--json", "--backend", "torch,warp", "--envs", "1,4", "--steps", "2",
                 "--trials", "5", "--warmup", "1", "--no-env", "--out", str(tmp_path)])
    assert code == 0
    doc = json.loads(capsys.readouterr().out)
    assert {"step_contents", "airframe", "dt", "integrator", "device", "cases"} <= doc.keys()
    assert "rk4" in doc["step_contents"]
    cases = doc["cases"]
    assert [(c["backend"], c["num_envs"]) for c in cases] == [("torch", 1), ("torch", 4), ("warp", 1),
                                                              ("warp", 4)]
    for c in cases:
        assert c["target"] == "simulator" and c["error"] is None
        assert c["min_s"] <= c["median_s"] <= c["max_s"]
        assert c["env_steps_per_s"] == pytest.approx(c["num_envs"] / c["median_s"])
        assert c["ratio_to_jsbsim"] is None
    assert (tmp_path / "bench.png").stat().st_size > 0
    assert json.loads((tmp_path / "bench.json").read_text())["cases"] == cases


@pytest.mark.parametrize("argv", [["--backend", "jax"], ["--envs", "0"], ["--envs", "a"],
                                  ["--trials", "2"]])
def test_bench_bad_input(capsys, argv):
    assert main(["bench", "--json", *argv]) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and "error" in captured.err


def test_jsbsim_baseline_before_and_after(capsys):
    """The baseline is timed before and after the other cases; ratios use the faster of the two."""
    code = main(["bench", "--json", "--backend", "warp", "--envs", "2", "--steps", "2", "--trials", "5",
                 "--warmup", "1", "--no-env", "--baseline", "jsbsim"])
    assert code == 0
    cases = json.loads(capsys.readouterr().out)["cases"]
    baselines = [c for c in cases if c["target"] == "jsbsim"]
    assert [c["backend"] for c in baselines] == ["jsbsim-c172p before", "jsbsim-c172p after"]
    reference = max(c["env_steps_per_s"] for c in baselines)
    for c in cases:
        assert c["ratio_to_jsbsim"] == pytest.approx(c["env_steps_per_s"] / reference)
