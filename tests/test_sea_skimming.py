"""The sea-skimming task: specs, Gymnasium, the per-episode sea, torch-warp parity of the task's step,
the LQR over a slight sea and MPPI over a moderate one on both backends, and the protocol's scoring."""

from __future__ import annotations

import json

import gymnasium
import pytest
import torch
from engine_parity import trim_flights
from gymnasium.utils.env_checker import check_env
from torchrl.envs.utils import check_env_specs

import falcon_rl  # noqa: F401 (registers the Gymnasium ids)
from falcon_rl import Simulator, make_env
from falcon_rl.baselines.mppi import MPPIConfig
from falcon_rl.envs.tasks import TERMINATION_CODE, task_spec
from falcon_rl.evaluation.sea_skimming import sea_skimming_metrics

needs_warp = pytest.mark.skipif(pytest.importorskip("warp") is None, reason="warp-lang is not installed")
BACKENDS = ["torch", pytest.param("warp", marks=needs_warp)]
#: Closed-loop flights: eager torch samples the sea in ~30 ops a sub-step (~20 s a flight), so its runs are
#: slow; the engines' parity over a sea is checked by default (test_the_task_step_agrees_on_both_engines).
FLIGHT_BACKENDS = [pytest.param("torch", marks=pytest.mark.slow), pytest.param("warp", marks=needs_warp)]


@pytest.mark.parametrize("backend", BACKENDS)
def test_the_env_passes_torchrl_spec_check(backend):
    env = make_env("sea_skimming", "volantex_ranger", num_envs=3, backend=backend, seed=0)
    check_env_specs(env, seed=0)


def test_the_gym_id_alone_makes_a_checked_env():
    env = gymnasium.make("falcon_rl/SeaSkimming-v0")
    check_env(env.unwrapped)
    observation, _ = env.reset(seed=1)
    assert observation.shape == (19,)  # 15 + the forward-looking altimeter's 4 readings


def test_each_episode_draws_its_sea_state_heading_and_clearance():
    env = make_env("sea_skimming", "volantex_ranger", num_envs=16, backend="torch", seed=4,
                   sea_states=(0.0, 3.0))
    td = env.reset()
    task, sea = env.task, env.sim.sea
    codes = task.sea_state
    assert set(codes.tolist()) == {0.0, 3.0}
    calm = codes == 0.0
    assert float(sea.amplitude[calm].abs().max()) == 0.0 and float(sea.amplitude[~calm].max()) > 0.0
    b = task.span
    assert bool(((task.commanded_clearance >= 0.15 * b) & (task.commanded_clearance <= 0.5 * b)).all())
    headings = task.heading_to_waves[:, None] - torch.tensor([0.0, torch.pi / 2, torch.pi])
    assert bool((headings.abs().min(-1).values < 1e-6).all())
    assert bool((td["task", "clearance"] > td["task", "commanded_clearance"] - 1e-4).all())
    # Over its sea an env starts above the water under it, wherever the sea's mean level is, climbing or
    # sinking with it (a level start over a rising crest would meet it before any controller could act).
    assert bool((td["task", "clearance"] > 0).all())
    zeros = torch.zeros(16)
    rising = sea.elevation_rate(zeros, zeros, 0.0)
    assert float(rising.abs().max()) > 0.1
    assert torch.allclose(-td["state", "velocity_ned"][:, 2], rising, atol=1e-4)
    # A partial reset draws only the reset rows' fields.
    before = sea.phase.clone()
    mask = torch.zeros(16, dtype=torch.bool)
    mask[3] = True
    td.set("_reset", mask[:, None])
    env.reset(td)
    assert torch.equal(sea.phase[~mask], before[~mask]) and not torch.equal(sea.phase[3], before[3])


@needs_warp
def test_the_task_step_agrees_on_both_engines():
    outputs = trim_flights("sea_skimming", "airship_v7", sea_states=(3.0,))
    torch_td, warp_td = outputs["torch"], outputs["warp"]
    assert torch.allclose(torch_td["observation"], warp_td["observation"], atol=5e-3)
    assert torch.allclose(torch_td["task", "clearance"], warp_td["task", "clearance"], atol=5e-3)


@pytest.mark.parametrize("backend", BACKENDS)
def test_the_forward_looking_altimeter_reads_the_water_ahead(backend):
    """Observations 15.. are (h - eta(p + V_g tau, t) - c*)/(b/4) over the env's own waves: computed here
    from the sea's torch twin; a look-ahead of ~0 reads what the altimeter under the CG reads."""
    taus = (1e-4, 0.5, 1.0)
    env = make_env("sea_skimming", "airship_v7", num_envs=6, backend=backend, seed=5, sea_states=(3.0,),
                   preview_seconds=taus)
    td = env.reset()
    action = env.trim_action().expand(6, -1).clone()
    for _ in range(5):
        td["action"] = action
        td = env.step_mdp(env.step(td))
    sim, task = env.sim, env.task
    position, velocity = sim.state["position_ned"].float(), sim.state["velocity_ned"].float()
    tau = torch.tensor(taus)
    ahead = position[:, :2, None] + velocity[:, :2, None] * tau  # [N, 2, P]
    water = sim.sea.elevation(ahead[:, 0], ahead[:, 1], sim.time.float())
    commanded = task.commanded_clearance[:, None]
    expected = ((-position[:, 2:3] - water - commanded) / (0.25 * task.span)).clamp(-5, 5)
    assert td["observation"].shape == (6, 18)
    assert torch.allclose(td["observation"][:, 15:], expected, atol=1e-3)
    assert torch.allclose(td["observation"][:, 15], td["observation"][:, 0], atol=1e-3)
    assert float((expected[:, 2] - expected[:, 0]).abs().max()) > 0.05  # the water ahead is not the same


def test_without_look_ahead_the_observation_is_the_fifteen_values():
    env = make_env("sea_skimming", "volantex_ranger", num_envs=2, backend="torch", seed=0, preview_seconds=())
    assert env.reset()["observation"].shape == (2, 15)


@pytest.mark.parametrize("preview", [(0.0,), (-1.0,), (6.0,), tuple(0.1 * k for k in range(1, 10))])
def test_a_bad_look_ahead_is_refused_in_one_line(preview):
    with pytest.raises(ValueError, match=r"preview_seconds must hold at most 8 look-ahead times in "
                                         r"\(0, 5\] s"):
        make_env("sea_skimming", "volantex_ranger", num_envs=1, backend="torch", seed=0,
                 preview_seconds=preview)


@pytest.mark.parametrize("backend", FLIGHT_BACKENDS)
def test_the_lqr_skims_a_slight_sea(backend):
    env = make_env("sea_skimming", "airship_v7", num_envs=4, backend=backend, seed=1, sea_states=(2.0,),
                   clearance_min=0.25, clearance_max=0.25, episode_seconds=12.0)
    policy = task_spec("sea_skimming").controller("lqr")(env)
    with torch.no_grad():
        rollout = env.rollout(env.max_episode_steps, policy, break_when_any_done=False)
    nxt = rollout["next"]
    assert not bool(nxt["terminated"].any())
    error = (nxt["task", "clearance_error"][:, -60:]).squeeze(-1)  # the last 3 s
    assert float(error.pow(2).mean().sqrt()) < 0.1 * env.task.span
    assert float(nxt["task", "lowest_tip_clearance"].min()) > 0.0


def test_the_metrics_score_a_contact_and_the_power_saved():
    n, t = 2, 10
    done = torch.zeros(n, t, 1, dtype=torch.bool)
    done[1, 4] = True
    reason = torch.zeros(n, t, 1, dtype=torch.long)
    reason[1, 4] = TERMINATION_CODE["water_contact"]
    clearance = torch.full((n, t, 1), 1.2)
    from tensordict import TensorDict

    nxt = TensorDict({"done": done, "terminated": done.clone(), "termination_reason": reason,
                      "task": {"clearance": clearance, "commanded_clearance": torch.ones(n, t, 1),
                               "lowest_tip_clearance": torch.full((n, t, 1), 0.5)},
                      "state": {"thrust": torch.full((n, t, 1), 8.0),
                                "airspeed": torch.full((n, t, 1), 10.0)}},
                     batch_size=[n, t])
    metrics = sea_skimming_metrics(TensorDict({"next": nxt}, batch_size=[n, t]), span=2.0, dt=0.1,
                                   free_power=100.0, grace_seconds=0.2)
    assert metrics["water_contact"].tolist() == [False, True]
    assert metrics["survival"].tolist() == [True, False]
    assert torch.allclose(metrics["clearance_rmse_span"], torch.tensor([0.1, 0.1]))
    assert torch.allclose(metrics["power_saved"], torch.tensor([0.2, 0.2]))


def test_a_bad_sea_state_is_refused_in_one_line():
    with pytest.raises(ValueError, match="sea_states must hold WMO sea-state codes 0-6"):
        make_env("sea_skimming", "volantex_ranger", num_envs=1, backend="torch", seed=0, sea_states=(7.0,))


def test_a_planner_flies_the_envs_own_waves():
    """``Simulator.set_sea_field`` gives a simulator another's wave fields (here each row twice), sampled at
    once; a field of the wrong shape is refused in one line."""
    source = Simulator("airship_v7", 2, backend="torch", seed=0, sea=3)
    planner = Simulator("airship_v7", 4, backend="torch", seed=1)
    sea = source.sea
    planner.set_sea_field(type(sea)(**{k: v.repeat_interleave(2, dim=0) for k, v in vars(sea).items()}))
    assert torch.equal(planner.sea.phase[::2], sea.phase) and torch.equal(planner.sea.phase[1::2], sea.phase)
    assert torch.allclose(planner.surface[::2], source.surface, atol=1e-6)
    with pytest.raises(ValueError, match=r"a sea field's amplitude must be \[4, 64\]"):
        planner.set_sea_field(sea)


@pytest.mark.parametrize("backend", FLIGHT_BACKENDS)
def test_mppi_skims_the_waves_it_plans_over(backend):
    env = make_env("sea_skimming", "airship_v7", num_envs=2, backend=backend, seed=5, sea_states=(3.0,),
                   clearance_min=0.25, clearance_max=0.25, episode_seconds=4.0)
    policy = task_spec("sea_skimming").controller("mppi")(env, MPPIConfig(samples=32, horizon_seconds=2.0))
    with torch.no_grad():
        rollout = env.rollout(env.max_episode_steps, policy, break_when_any_done=False)
    assert not bool(rollout["next", "terminated"].any())
    assert torch.equal(policy.planner.sea.phase[::32], env.sim.sea.phase)
    error = rollout["next", "task", "clearance_error"][:, -20:]
    assert float(error.pow(2).mean().sqrt()) < 0.1 * env.task.span


def test_eval_flies_the_sea_state_and_clearance_asked(tmp_path, capsys):
    """``falcon-rl eval --sea-state --clearance`` reach the protocol, whose results say what it flew."""
    from falcon_rl.cli import main

    code = main(["eval", "--task", "sea_skimming", "--controller", "lqr", "--airframe", "airship_v7",
                 "--episodes", "2", "--seconds", "2", "--sea-state", "1", "--clearance", "0.3", "--backend",
                 "warp", "--out", str(tmp_path), "--json"])
    assert code == 0
    settings = json.loads((tmp_path / "results.json").read_text())[0]["settings"]
    assert settings["sea_state"] == 1 and settings["clearance"] == 0.3
