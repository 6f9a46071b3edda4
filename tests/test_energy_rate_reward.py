"""The altitude task's specific energy-rate penalty (``w_energy_rate``): its value against the state
history, and its physics (level trim misses a ramp's energy rate by the whole climb rate; thrust above
trim gains energy, below it loses energy; a pull-up trades airspeed for height at nearly constant energy)."""

from __future__ import annotations

import torch
from tensordict import TensorDictBase

from falcon_rl.constants import G0
from falcon_rl.envs import make_env

N, WEIGHT = 4, 0.5


class ConstantAction:
    """The trim command plus ``delta`` [A] on every step."""

    def __init__(self, trim: torch.Tensor, delta: tuple[float, float]):
        self.action = (trim + torch.tensor(delta)).clamp(-1.0, 1.0)

    def __call__(self, td: TensorDictBase) -> TensorDictBase:
        td["action"] = self.action.expand(td.batch_size[0], -1).clone()
        return td


def rollout(delta: tuple[float, float], steps: int, weight: float = WEIGHT) -> tuple[TensorDictBase, float]:
    """[N, steps] rollout of the V7's altitude task at 20 Hz from trim, and the climb-rate limit r."""
    env = make_env("altitude", "airship_v7", num_envs=N, backend="torch", seed=5, decimation=5,
                   w_energy_rate=weight, episode_seconds=60.0)
    td = env.rollout(steps, ConstantAction(env.trim_action(), delta), break_when_any_done=False)
    return td, env.task.airframe.envelope.climb_rate_limit


def energy_rate_error(td: TensorDictBase, r: float, dt: float = 0.05) -> torch.Tensor:
    """e_E [N, T-1] from the state history: (hdot + V dV/dt / g - hdot_ref) / r, dV/dt the airspeed's
    difference between consecutive steps."""
    v = td["next", "state", "airspeed"].squeeze(-1)
    climb = -td["next", "state", "velocity_ned"][..., 2]
    rate = td["next", "task", "reference_climb_rate"].reshape(v.shape)
    return (climb[:, 1:] + v[:, 1:] * (v[:, 1:] - v[:, :-1]) / dt / G0 - rate[:, 1:]) / r


def test_penalty_is_the_energy_rate_error_of_the_state_history():
    with_term, r = rollout((0.0, 0.3), 40)
    without, _ = rollout((0.0, 0.3), 40, weight=0.0)
    cost = (without["next", "reward"] - with_term["next", "reward"]).squeeze(-1)[:, 1:]
    expected = WEIGHT * energy_rate_error(with_term, r).abs().clamp(max=4.0)
    # float32 noise: dV/dt is a difference of close airspeeds over 0.05 s (the kernel's and the history's)
    torch.testing.assert_close(cost, expected.to(cost.dtype), rtol=1e-4, atol=3e-4)


def test_level_trim_misses_the_ramps_energy_rate_by_the_climb_rate():
    td, r = rollout((0.0, 0.0), 20)
    error = energy_rate_error(td, r)[:, -5:]
    gap = td["task", "target_altitude"] - td["task", "initial_altitude"]
    direction = torch.sign(gap.reshape(error.shape[0], -1))[:, :1]
    torch.testing.assert_close(error, -direction.expand_as(error).to(error.dtype), atol=0.05, rtol=0.0)


def test_thrust_sets_the_energy_rate_and_a_pull_up_keeps_it():
    steps = 40
    full, r = rollout((0.0, 1.0), steps)
    idle, _ = rollout((0.0, -1.0), steps)
    pull, _ = rollout((-0.3, 0.0), steps)
    level, _ = rollout((0.0, 0.0), steps)
    rate = {name: (energy_rate_error(td, r) * r
                   + td["next", "task", "reference_climb_rate"].reshape(N, -1)[:, 1:])[:, -20:]
            for name, td in (("full", full), ("idle", idle), ("pull", pull), ("level", level))}
    assert (rate["full"] > 0.3).all() and (rate["idle"] < -0.3).all()
    climb = -pull["next", "state", "velocity_ned"][:, -20:, 2]
    assert (climb.abs() > 1.0).any(), "the pull-up should change the height"
    # exchanged, not gained: the energy rate stays far below the height rate
    assert (rate["pull"] - rate["level"]).abs().mean() < 0.3 * climb.abs().mean()
