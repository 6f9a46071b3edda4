"""Fault rows of the env inputs: non-finite or wrong-shaped steady wind is refused where it enters
(``Simulator``, ``make_env``, ``falcon-rl train``) with one line naming the field and the constraint,
before anything is built or written."""

from __future__ import annotations

import pytest
import torch

from falcon_rl import Simulator, make_env
from falcon_rl.cli import main

#: (wind as given, what the refusal says)
BAD_WINDS = [
    ((1e999, 0.0, 0.0), "wind must be finite"),
    ((float("nan"), 0.0, 0.0), "wind must be finite"),
    ((1.0, 2.0), r"wind must have shape \[3\] or \[2, 3\]"),
    ([[1.0, 2.0, 3.0]] * 3, r"wind must have shape \[3\] or \[2, 3\]"),
    ("abc", "wind must be real numbers"),
    (5.0, r"wind must have shape"),
]


@pytest.mark.parametrize(("wind", "message"), BAD_WINDS)
def test_simulator_refuses_bad_wind(navion, wind, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        Simulator(navion, num_envs=2, wind=wind)


@pytest.mark.parametrize(("wind", "message"), BAD_WINDS)
def test_make_env_refuses_bad_wind(wind, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        make_env("altitude", "navion", num_envs=2, backend="torch", wind=wind)


def test_good_wind_shapes_are_taken(navion) -> None:
    every = Simulator(navion, num_envs=2, wind=(1.0, -2.0, 0.5))
    torch.testing.assert_close(every.wind_ned, torch.tensor([[1.0, -2.0, 0.5]] * 2))
    per_env = Simulator(navion, num_envs=2, wind=[[1.0, 0.0, 0.0], [0.0, 3.0, 0.0]])
    torch.testing.assert_close(per_env.wind_ned, torch.tensor([[1.0, 0.0, 0.0], [0.0, 3.0, 0.0]]))


@pytest.mark.parametrize("wind", ["[1e999, 0, 0]", "[1, 2]"])
def test_train_refuses_bad_wind_in_one_line_and_writes_nothing(wind, tmp_path, capsys) -> None:
    out = tmp_path / "run"
    code = main(["train", "ppo", "--task", "altitude", "--airframe", "volantex_ranger", "--out", str(out),
                 "--set", f"env_options={{'wind': {wind}}}"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "wind must" in err
    assert not (out / "policy.pt").exists() and not (out / "checkpoint.pt").exists()
