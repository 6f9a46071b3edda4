"""The backend contract: engines own their buffers, run sub-steps inside, register by one line; the
facade works with any registered engine; multi-motor airframes reset and fly."""

from __future__ import annotations

import math

import pytest
import torch

from falcon_rl import Simulator, make_env
from falcon_rl.physics import backends
from falcon_rl.physics.backends import engine_class
from falcon_rl.physics.derived import DERIVED_FIELDS, DERIVED_WIDTH, split_derived
from falcon_rl.physics.engine import Engine
from falcon_rl.physics.torch_backend import TorchEngine


class HalfStepEngine(TorchEngine):
    """A toy backend defined outside the package: two Euler half-steps per step."""

    def advance(self, substeps: int) -> None:
        dt = self.dt
        for _ in range(2 * substeps):
            self.dt = 0.5 * dt
            self.x.copy_(self.integrate_step())
            self.time += self.dt
        self.dt = dt


def _command(sim: Simulator) -> torch.Tensor:
    return sim.command.clone()


@pytest.mark.parametrize("backend", ["torch", "warp"])
def test_substeps_inside_the_engine_equal_repeated_steps(backend):
    """step(command, substeps=k) == k x step(command), turbulence included (same noise draws)."""
    sims = [Simulator("volantex_ranger", num_envs=8, backend=backend, turbulence="moderate", seed=3)
            for _ in range(2)]
    command = _command(sims[0])
    command[:, 0] += 0.1
    for _ in range(3):
        sims[0].step(command, substeps=4)
        for _ in range(4):
            sims[1].step(command)
    assert torch.allclose(sims[0].x, sims[1].x, atol=1e-6, rtol=0)
    assert torch.allclose(sims[0].time, sims[1].time)
    assert torch.allclose(sims[0].turbulence.filter, sims[1].turbulence.filter, atol=1e-6)


def test_bad_substeps_are_refused():
    sim = Simulator("navion", num_envs=2)
    for bad in (0, -1, 1.5):
        with pytest.raises(ValueError, match="substeps"):
            sim.step(_command(sim), substeps=bad)


def test_a_backend_is_one_class_and_one_registry_line(monkeypatch):
    monkeypatch.setitem(backends.ENGINES, "half", HalfStepEngine)
    assert engine_class("half") is HalfStepEngine
    sim = Simulator("navion", num_envs=3, backend="half", integrator="euler")
    ref = Simulator("navion", num_envs=3, backend="torch", integrator="euler", dt=0.005)
    for _ in range(10):
        sim.step(_command(sim))
        ref.step(_command(ref), substeps=2)
    assert torch.allclose(sim.x, ref.x, atol=1e-6)
    assert sim.state["height"].shape == (3,)


def test_unknown_backend_and_options_are_one_line_errors():
    with pytest.raises(ValueError, match="backend must be one of"):
        Simulator("navion", backend="nope")
    with pytest.raises(ValueError, match="compile=True applies to the torch backend"):
        Simulator("navion", backend="scipy", compile=True)
    assert issubclass(engine_class("scipy"), Engine)


def test_the_facade_names_no_backend():
    """Simulator reaches engines through the registry only (no name branches, no engine imports)."""
    import inspect

    from falcon_rl.physics import simulator

    source = inspect.getsource(simulator)
    for name in ("warp_backend", "torch_backend", "scipy_backend", '== "warp"', '== "torch"', '== "scipy"'):
        assert name not in source


@pytest.mark.parametrize("backend", ["torch", "warp"])
def test_derived_columns_follow_the_declaration(backend):
    sim = Simulator("airship_v7", num_envs=4, backend=backend)
    derived = sim.engine.derived()
    assert derived.shape == (4, DERIVED_WIDTH)
    fields = split_derived(derived)
    for name, width in DERIVED_FIELDS:
        assert fields[name].shape == ((4,) if width == 1 else (4, width))
    assert torch.allclose(fields["height"], -sim.x[:, 2])
    assert not fields["ground_contact"].any()


def test_multi_motor_initial_throttle_shapes():
    sim = Simulator("airship_v7", num_envs=3)
    assert sim.airframe.num_motors == 2
    sim.reset({"throttle": torch.tensor([0.2, 0.6])})
    assert torch.allclose(sim.state["throttle"], torch.tensor([0.2, 0.6]).expand(3, 2))
    rows = torch.tensor([[0.1, 0.9], [0.5, 0.5], [0.9, 0.1]])
    sim.reset({"throttle": rows})
    assert torch.allclose(sim.state["throttle"], rows)
    with pytest.raises(ValueError, match=r"initial throttle must be \[2\] or \[3, 2\]"):
        sim.reset({"throttle": torch.ones(3)})


@pytest.mark.parametrize("backend", ["torch", "warp"])
def test_differential_thrust_through_the_env(backend):
    """Airship V7 (two motors) in the altitude env: per-motor throttle states [N, 2] are published, and
    an asymmetric start (left motor at full throttle, right idle, throttle commands held) yaws the
    craft towards the idle motor while the symmetric one holds its heading."""
    env = make_env("altitude", "airship_v7", num_envs=2, backend=backend, seed=0, decimation=1)
    td = env.reset()
    assert td["state", "throttle"].shape == (2, 2)
    sim = env.sim
    positions = torch.tensor([m.position[1] for m in sim.airframe.motors])
    left = int(positions.argmin())  # body y < 0 is the left wing
    start = sim.state["throttle"].clone()
    start[0, left], start[0, 1 - left] = 1.0, 0.0
    sim.reset({"throttle": start, "height": torch.full((2,), 60.0)})
    # The left motor leads for the first few tenths of a second (throttle lags before the states meet).
    for _ in range(30):
        td = env.step(td.set("action", torch.tensor([[0.0, 0.0], [0.0, 0.0]])))["next"]
        assert torch.isfinite(td["observation"]).all()
    yaw_rate = sim.state["angular_rate_body"][:, 2]
    assert yaw_rate[0] > 1e-3, "more thrust on the left motor must yaw the nose right (r > 0)"
    assert abs(float(yaw_rate[1])) < 0.1 * float(yaw_rate[0])
    assert math.isfinite(float(td["reward"].sum()))


@pytest.mark.parametrize("derive", [True, False])
def test_warp_reset_launch_equals_the_torch_writes(derive):
    """``WarpEngine.start`` (one launch: the masked rows held, projected and written, then, with
    ``derive``, the batch's derived state) leaves the buffers bit for bit as the contract's torch writes
    do and returns what ``derived()`` evaluates (None without ``derive``); rows outside the mask, their
    gusts, clocks and crash flags included, are untouched."""
    sims = [Simulator("volantex_ranger", num_envs=16, backend="warp", turbulence="moderate", seed=5)
            for _ in range(2)]
    command = _command(sims[0])
    command[:, 0] += 0.3
    for sim in sims:  # gusts, clocks and Dryden filters away from zero, one env on the ground
        for _ in range(5):
            sim.step(command, substeps=3)
        sim.engine.crashed[[2, 9]] = True
    initial = sims[0].x.clone()
    initial[:, 2] = -torch.linspace(1.0, 60.0, 16)  # heights
    initial[:, 3:7] *= 1.7  # a quaternion to renormalise
    initial[:, 13:16] = 0.7  # surfaces beyond their limits: saturated, or on the command (ideal actuators)
    start_command = command.clamp(-1.0, 1.0).flip(0)
    mask = torch.zeros(16, dtype=torch.bool)
    mask[[0, 2, 5, 11]] = True
    before = sims[0].x.clone()
    derived = sims[0].engine.start(initial, start_command, mask, derive=derive)
    assert Engine.start(sims[1].engine, initial, start_command, mask) is None
    one, two = sims[0].engine, sims[1].engine
    for name in ("x", "command", "time", "gust_velocity_body", "gust_rate_body", "crashed"):
        assert torch.equal(getattr(one, name), getattr(two, name)), name
    assert torch.equal(one.turbulence.filter, two.turbulence.filter)
    assert torch.equal(one.x[~mask], before[~mask]) and bool(one.crashed[9]) and not bool(one.crashed[2])
    if derive:
        assert torch.equal(derived.clone(), one.derived())
    else:
        assert derived is None


def test_the_warp_reset_screen_calls_the_check_for_bad_rows_only():
    """The device screen before a Warp reset: good rows skip the caller's check (no torch check per
    reset); each kind of bad row in the mask calls it before anything is written; rows outside the
    mask are not read."""
    sim = Simulator("volantex_ranger", num_envs=4, backend="warp", seed=0)
    calls: list[str] = []
    good, command = sim.x.clone(), sim.command.clone()
    mask = torch.tensor([True, True, False, True])
    sim.engine.start(good, command, mask, check=lambda: calls.append(1))
    assert calls == []
    for column, value in ((0, math.nan), (slice(3, 7), 1e-4), (2, 1.0), (0, 2e7), (7, 400.0), (11, 30.0)):
        bad = good.clone()
        bad[1, column] = value  # NaN, a short quaternion, underground, far away, too fast, spinning
        bad[2, :] = math.nan  # outside the mask
        sim.engine.start(bad, command, mask, check=lambda column=column: calls.append(str(column)))
    bad_command = command.clone()
    bad_command[3, 1] = 1.5
    sim.engine.start(good, bad_command, mask, check=lambda: calls.append("command"))
    assert calls == ["0", "slice(3, 7, None)", "2", "0", "7", "11", "command"]
