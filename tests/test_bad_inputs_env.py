"""Bad inputs at the env and simulator boundary, one row per case: each is refused with a one-line
ValueError before anything moves, or ends in the documented clean outcome (clamped, or the row
terminated with reason "non_finite"); the other envs are untouched, bit for bit."""

from __future__ import annotations

import math

import pytest
import torch
from tensordict import TensorDict

from falcon_rl import Simulator
from falcon_rl.envs import make_env
from falcon_rl.envs.tasks import TERMINATION_CODE
from falcon_rl.physics import state as S

N = 3


def _env(backend: str = "torch"):
    return make_env("altitude", "volantex_ranger", num_envs=N, backend=backend, seed=7, decimation=1)


def _snapshot(env) -> dict[str, torch.Tensor]:
    """Everything a step may move: simulator state and clock, task buffers, counters, generators."""
    return {"x": env.sim.x.clone(), "time": env.sim.time.clone(), "command": env.sim.command.clone(),
            "task_time": env.task.time.clone(), "previous_action": env.task.previous_action.clone(),
            "step_count": env.episode_step, "generator": env.generator.get_state(),
            "sim_generator": env.sim.generator.get_state()}


def _unchanged(before: dict[str, torch.Tensor], after: dict[str, torch.Tensor]) -> bool:
    return all(torch.equal(before[k], after[k]) for k in before)


# ------------------------------------------------------------------------------ refused actions
def _action(kind: str) -> object:
    trim = torch.zeros(N, 2)
    return {
        "one_column": trim[:, :1],
        "no_batch_dim": trim[0],
        "flat": trim.reshape(-1),
        "too_many_rows": torch.zeros(N + 1, 2),
        "three_channels": torch.zeros(N, 3),
        "bool": torch.zeros(N, 2, dtype=torch.bool),
        "int": torch.zeros(N, 2, dtype=torch.long),
        "complex": torch.zeros(N, 2, dtype=torch.complex64),
        "missing": None,
    }[kind]


@pytest.mark.parametrize("kind, message", [
    ("one_column", r"shape \[3, 2\]"),
    ("no_batch_dim", r"shape \[3, 2\]"),
    ("flat", r"shape \[3, 2\]"),
    ("too_many_rows", r"shape \[3, 2\]"),
    ("three_channels", r"shape \[3, 2\]"),
    ("bool", "real floating"),
    ("int", "real floating"),
    ("complex", "real floating"),
    ("missing", "missing 'action'"),
])
@pytest.mark.parametrize("backend", ["torch", "warp"])
def test_a_refused_action_is_one_line_and_moves_nothing(backend: str, kind: str, message: str) -> None:
    env = _env(backend)
    env.reset()
    before = _snapshot(env)
    with pytest.raises(ValueError, match=message) as info:
        env._step({"action": _action(kind)})  # the env's own contract (any mapping with .get)
    assert "\n" not in str(info.value)
    assert _unchanged(before, _snapshot(env))


@pytest.mark.parametrize("kind", ["one_column", "bool", "int", "complex", "missing"])
def test_a_refused_action_through_env_step_moves_nothing(kind: str) -> None:
    env = _env()
    td = env.reset()
    before = _snapshot(env)
    action = _action(kind)
    data = td.exclude("action") if action is None else td.clone().set("action", action)
    with pytest.raises((ValueError, RuntimeError, KeyError)):
        env.step(data)
    assert _unchanged(before, _snapshot(env))


# ------------------------------------------------------------------------------ accepted actions
@pytest.mark.parametrize("value", [math.inf, -math.inf, 1e30, -1e30, 5.0])
@pytest.mark.parametrize("backend", ["torch", "warp"])
def test_huge_and_infinite_actions_are_clamped_everywhere(backend: str, value: float) -> None:
    env, control = _env(backend), _env(backend)
    td, reference = env.reset(), control.reset()
    action = torch.zeros(N, 2)
    action[1, 0] = value
    clamped = action.clamp(-1.0, 1.0)
    out = env.step(td.set("action", action))["next"]
    expected = control.step(reference.set("action", clamped))["next"]
    assert torch.equal(out["reward"], expected["reward"]) and torch.isfinite(out["reward"]).all()
    assert torch.equal(env.task.previous_action, clamped)
    assert not out["terminated"].any()
    # the next step's action-rate term sees the clamped value too
    out = env.step(env.step_mdp(env.step(td.set("action", action))).set("action", torch.zeros(N, 2)))
    assert torch.isfinite(out["next", "reward"]).all()


@pytest.mark.parametrize("dtype", [torch.float64, torch.float16, torch.bfloat16])
def test_other_float_dtypes_are_cast_to_the_spec(dtype: torch.dtype) -> None:
    env = _env()
    td = env.reset()
    out = env.step(td.set("action", torch.zeros(N, 2, dtype=dtype)))["next"]
    assert out["reward"].dtype == env.reward_spec.dtype == torch.float32
    assert out["observation"].dtype == torch.float32


@pytest.mark.parametrize("backend", ["torch", "warp"])
def test_a_nan_action_terminates_its_row_only(backend: str) -> None:
    env, control = _env(backend), _env(backend)
    td, reference = env.reset(), control.reset()
    action = torch.full((N, 2), 0.1)
    bad = action.clone()
    bad[1, 1] = math.nan
    out = env.step(td.set("action", bad))["next"]
    expected = control.step(reference.set("action", action))["next"]
    assert out["terminated"][:, 0].tolist() == [False, True, False]
    assert out["termination_reason"][1, 0] == TERMINATION_CODE["non_finite"]
    for key in out.keys(True, True):
        value = out[key]
        if value.is_floating_point():
            assert torch.isfinite(value).all(), key
        keep = torch.tensor([0, 2])
        assert torch.equal(value[keep], expected[key][keep]), key  # the other envs, bit for bit


# ------------------------------------------------------------------------------ termination reasons
@pytest.mark.parametrize("cause, edit", [
    ("ground_contact", lambda env: env.sim.x[0].__setitem__(S.DOWN_INDEX, 1.0)),
    ("speed_stall", lambda env: env.sim.x[0, S.VELOCITY].copy_(torch.tensor([3.0, 0.0, 0.0]))),
    ("alpha_stall", lambda env: env.sim.x[0, S.VELOCITY].copy_(
        12.0 * torch.tensor([math.cos(1.6 * env.airframe.aero.alpha_stall), 0.0,
                             math.sin(1.6 * env.airframe.aero.alpha_stall)]))),
    ("non_finite", lambda env: env.sim.x[0].__setitem__(S.STATE_INDEX["angular_rate_body"][0], math.nan)),
])
@pytest.mark.parametrize("backend", ["torch", "warp"])
def test_the_termination_reason_names_the_cause(backend: str, cause: str, edit) -> None:
    env = _env(backend)
    td = env.reset()
    edit(env)
    out = env.step(td.set("action", env.trim_action().expand(N, -1)))["next"]
    assert out["termination_reason"][:, 0].tolist() == [TERMINATION_CODE[cause], 0, 0]
    assert out["terminated"][:, 0].tolist() == [True, False, False]
    reset = env.reset(TensorDict({"_reset": out["done"]}, batch_size=[N]))
    assert (reset["termination_reason"] == 0).all()


# ------------------------------------------------------------------------------ reset inputs
def _bad_initial(kind: str) -> object:
    x = Simulator("volantex_ranger", num_envs=N).x.clone()
    if kind == "nan_tensor":
        x[1, 0] = math.nan
        return x
    if kind == "wrong_width":
        return x[:, :-1]
    return {
        "zero_quaternion": {"quaternion": torch.zeros(4)},
        "tiny_quaternion": {"quaternion": torch.full((4,), 1e-30)},
        "huge_velocity": {"velocity_body": torch.tensor([1e6, 0.0, 0.0])},
        "huge_rate": {"angular_rate_body": torch.tensor([0.0, 1e4, 0.0])},
        "underground": {"height": torch.full((N,), -5.0)},
        "far_away": {"position_ned": torch.tensor([1e9, 0.0, -100.0])},
        "inf_velocity": {"velocity_body": torch.tensor([math.inf, 0.0, 0.0])},
        "command_out_of_range": {"command": torch.tensor([0.0, 0.0, 0.0, 2.0])},
        "nan_command": {"command": torch.tensor([0.0, math.nan, 0.0, 0.5])},
    }[kind]


@pytest.mark.parametrize("kind, message", [
    ("nan_tensor", "NaN or Inf"),
    ("wrong_width", "must have shape"),
    ("zero_quaternion", "quaternion has norm"),
    ("tiny_quaternion", "quaternion has norm"),
    ("huge_velocity", "speed above"),
    ("huge_rate", "body rate above"),
    ("underground", "height below the surface"),
    ("far_away", "position beyond"),
    ("inf_velocity", "NaN or Inf"),
    ("command_out_of_range", r"outside \[-1, 1\]"),
    ("nan_command", "command contains NaN"),
])
@pytest.mark.parametrize("backend", ["torch", "warp"])
def test_a_bad_reset_is_refused_and_moves_nothing(backend: str, kind: str, message: str) -> None:
    sim = Simulator("volantex_ranger", num_envs=N, backend=backend)
    sim.step(torch.zeros(N, 4))
    before = (sim.x.clone(), sim.time.clone(), sim.command.clone())
    with pytest.raises(ValueError, match=message) as info:
        sim.reset(_bad_initial(kind))
    assert "\n" not in str(info.value)
    assert all(torch.equal(a, b) for a, b in zip(before, (sim.x, sim.time, sim.command), strict=True))


def test_rows_outside_the_reset_mask_are_not_read() -> None:
    sim = Simulator("volantex_ranger", num_envs=N)
    x = sim.x.clone()
    x[0, 0] = math.nan  # row 0 is not reset: its garbage is never read
    sim.reset(x, mask=torch.tensor([False, True, True]))
    assert torch.isfinite(sim.x).all()


# ------------------------------------------------------------------------------ the crash state
@pytest.mark.parametrize("backend", ["torch", "warp"])
def test_a_crashed_aircraft_stops_at_the_ground_until_reset(backend: str) -> None:
    sim = Simulator("volantex_ranger", num_envs=2, backend=backend)
    sim.reset({"height": torch.tensor([0.5, 100.0]),
               "velocity_body": torch.tensor([[10.0, 0.0, 8.0], [15.0, 0.0, 0.0]])})  # row 0 sinks fast
    command = torch.zeros(2, 4)
    for _ in range(50):
        sim.step(command)
    state = sim.state
    assert state["crashed"].tolist() == [True, False]
    assert float(state["height"][0]) == 0.0 and bool(state["ground_contact"][0])
    stopped = sim.x[0].clone()
    for _ in range(20):
        sim.step(command)
    assert torch.equal(sim.x[0], stopped)  # it stays where it stopped
    assert float(sim.state["height"][1]) > 50.0  # the other env flies on
    sim.reset(mask=torch.tensor([True, False]))
    assert not sim.state["crashed"].any()
    assert float(sim.state["height"][0]) == pytest.approx(100.0)


def test_without_the_crash_state_the_model_integrates_through_the_ground() -> None:
    sim = Simulator("volantex_ranger", num_envs=1, stop_at_ground=False)
    sim.reset({"height": torch.tensor([0.5]), "velocity_body": torch.tensor([[10.0, 0.0, 8.0]])})
    for _ in range(50):
        sim.step(torch.zeros(1, 4))
    assert float(sim.state["height"][0]) < 0.0 and not sim.state["crashed"].any()


# ------------------------------------------------------------------------------ task options
@pytest.mark.parametrize(("task", "options", "message"), [
    ("altitude", {"episode_seconds": -1.0}, "altitude option episode_seconds must be > 0, got -1.0"),
    ("altitude", {"sigma_altitude": 0.0}, "altitude option sigma_altitude must be > 0, got 0.0"),
    ("altitude", {"w_airspeed": math.nan}, "altitude option w_airspeed must be a finite number, got nan"),
    ("altitude", {"capture_band": math.inf}, "altitude option capture_band must be a finite number, got inf"),
    ("altitude", {"w_energy_rate": "0.5"}, "w_energy_rate must be a finite number, got '0.5'"),
    ("altitude", {"offset_min": 20.0}, "offset_min <= offset_max required, got 20.0 > 18.0"),
    ("altitude", {"target_altitudes": ()}, "target_altitudes must be a non-empty tuple of finite numbers"),
    ("altitude", {"target_altitudes": (10.0, -5.0)}, "target_altitudes must be > 0, got (10.0, -5.0)"),
    ("climb_descend", {"floor": 300.0}, "floor <= ceiling required, got 300.0 > 200.0"),
    ("attitude", {"sigma_bank": -0.1}, "attitude option sigma_bank must be > 0, got -0.1"),
    ("path_following", {"offset_min": -1.0}, "path_following option offset_min must be >= 0, got -1.0"),
    ("trajectory", {"bank_min": 0.6}, "bank_min <= bank_max required, got 0.6 > 0.5"),
])
def test_a_task_option_the_task_cannot_run_is_refused_in_one_line(task: str, options: dict, message: str):
    with pytest.raises(ValueError, match="^[^\n]*" + message.replace("(", r"\(").replace(")", r"\)")
                       .replace(".", r"\.") + "[^\n]*$"):
        make_env(task, "navion", num_envs=1, **options)


def test_the_paper_defaults_and_lists_from_json_pass_the_option_checks():
    for task in ("altitude", "climb_descend", "attitude", "path_following", "trajectory"):
        make_env(task, "navion", num_envs=1)
    env = make_env("altitude", "navion", num_envs=1, target_altitudes=[30, 50], climb_rate=None,
                   w_energy_rate=1)
    assert list(env.task.config.target_altitudes) == [30, 50]


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_finite_rows_flags_exactly_the_rows_with_a_nan_or_an_infinity(dtype: torch.dtype) -> None:
    from falcon_rl.envs.staged_step import finite_rows

    generator = torch.Generator().manual_seed(0)
    values = torch.randn(64, 39, generator=generator, dtype=dtype) * 10.0 ** torch.randint(
        -30, 30, (64, 39), generator=generator).to(dtype)
    largest = torch.finfo(dtype).max
    values[0, 0], values[1, 5], values[2, 38], values[3, 7] = math.nan, math.inf, -math.inf, -0.0
    values[4] = largest  # a row of the largest numbers: finite, and nothing may overflow
    values[5, :2] = torch.tensor([largest, -largest], dtype=dtype)
    expected = torch.isfinite(values).all(-1)
    assert torch.equal(finite_rows(values), expected)
    assert expected[3:].all() and not expected[:3].any()
