"""Named state: StateLayout's field table, pack/unpack round trips and errors, the names MPPI and
the linear models use, and the constants module."""

from __future__ import annotations

import pytest
import torch

from falcon_rl import constants, load_airframe, make_env
from falcon_rl.baselines.linear_models import FULL_STATES, reduced_state
from falcon_rl.physics import constants as physics_constants
from falcon_rl.physics import state as S


def _fields(n: int, motors: int, seed: int = 0) -> dict[str, torch.Tensor]:
    g = torch.Generator().manual_seed(seed)
    layout = S.StateLayout(motors)
    return {f.name: torch.randn(n, f.size, generator=g, dtype=torch.float64) for f in layout.fields}


def test_field_table_matches_the_slices():
    layout = S.StateLayout(2)
    assert layout.names == ("position_ned", "quaternion", "velocity_body", "angular_rate_body",
                            "surface_position", "surface_rate", "throttle")
    assert [f.slice for f in layout.fields][:6] == [S.POSITION, S.QUATERNION, S.VELOCITY, S.ANGULAR_RATE,
                                                    S.SURFACE_POSITION, S.SURFACE_RATE]
    assert layout.fields[-1].slice == layout.throttle == slice(S.THROTTLE_START, S.THROTTLE_START + 2)
    assert sum(f.size for f in layout.fields) == layout.size == 21
    assert S.STATE_INDEX["velocity_body"][S.X] == S.VELOCITY_START
    assert S.STATE_INDEX["surface_rate"][0] == S.SURFACE_RATE_START
    assert S.DOWN_INDEX == 2
    assert S.COMMAND_CHANNELS[S.ELEVATOR] == "elevator" and S.COMMAND_CHANNELS[S.THROTTLE] == "throttle"
    assert len(S.COMMAND_CHANNELS) == S.NUM_CONTROLS


@pytest.mark.parametrize("motors", [1, 2])
def test_pack_unpack_round_trip(motors):
    layout = S.StateLayout(motors)
    fields = _fields(5, motors)
    x = layout.pack(fields)
    assert x.shape == (5, layout.size)
    back = layout.unpack(x)
    assert back.keys() == fields.keys()
    for name, value in fields.items():
        assert torch.equal(back[name], value)
        assert torch.equal(layout.field(x, name), value)
    assert torch.equal(layout.pack(back), x)
    assert torch.equal(S.height(x), -fields["position_ned"][:, S.DOWN])


def test_unpack_returns_views():
    layout = S.StateLayout(1)
    x = torch.zeros(3, layout.size)
    layout.unpack(x)["velocity_body"][:, S.X] = 7.0
    assert torch.equal(x[:, S.VELOCITY_START], torch.full((3,), 7.0))


def test_pack_defaults_and_broadcasts():
    fields = _fields(4, 1)
    rates = fields.pop("surface_rate")
    x = S.StateLayout(1).pack({**fields, "throttle": fields["throttle"][:, 0], "euler": rates})
    assert torch.equal(x[:, S.SURFACE_RATE], torch.zeros(4, 3, dtype=torch.float64))
    assert torch.equal(x[:, S.THROTTLE_START], fields["throttle"][:, 0])


def test_pack_errors_name_the_field():
    two = S.StateLayout(2)
    fields = _fields(4, 2)
    with pytest.raises(ValueError, match="'throttle'"):
        two.pack({**fields, "throttle": fields["throttle"][:, 0]})  # [N] is ambiguous for 2 motors
    with pytest.raises(ValueError, match="'quaternion'"):
        two.pack({**fields, "quaternion": fields["quaternion"][:, :3]})
    with pytest.raises(ValueError, match="'velocity_body'"):
        two.pack({**fields, "velocity_body": fields["velocity_body"][:3]})
    with pytest.raises(ValueError, match="angular_rate_body"):
        two.pack({k: v for k, v in fields.items() if k != "angular_rate_body"})
    with pytest.raises(ValueError, match="21"):
        two.unpack(torch.zeros(4, 20))
    with pytest.raises(KeyError, match="euler"):
        two.field(torch.zeros(4, 21), "euler")


def test_env_state_packs_to_the_simulator_state():
    env = make_env("altitude", "volantex_ranger", num_envs=2, backend="torch")
    td = env.reset()
    x = S.StateLayout(env.sim.airframe.num_motors).pack(td["state"])
    assert torch.allclose(x, env.sim.x.to(x.dtype), atol=1e-6)
    assert torch.allclose(S.height(x), td["state", "height"][:, 0], atol=1e-5)  # published [N, 1]
    # The linear models' reduced state reads the same fields by name.
    xr = reduced_state(td["state"], FULL_STATES)
    assert torch.equal(xr[:, FULL_STATES.index("q")], td["state", "angular_rate_body"][:, S.PITCH])
    assert torch.equal(xr[:, FULL_STATES.index("throttle")], td["state", "throttle"][:, 0])


def test_mppi_initial_state_is_the_simulator_state():
    from falcon_rl.baselines.mppi import MPPI, MPPIConfig

    env = make_env("altitude", "volantex_ranger", num_envs=2, backend="torch")
    td = env.reset()
    policy = MPPI(env, MPPIConfig(samples=2, horizon_seconds=0.2, plan_dt=0.05, replan_seconds=0.05))
    assert torch.allclose(policy._initial_state(td), env.sim.x, atol=1e-6)


def test_two_motor_airframe_throttle():
    airframe = load_airframe("airship_v7")
    assert airframe.num_motors == 2
    layout = S.StateLayout(airframe.num_motors)
    fields = _fields(3, 2, seed=1)
    fields["throttle"] = torch.tensor([[0.2, 0.8], [0.5, 0.5], [1.0, 0.0]], dtype=torch.float64)
    x = layout.pack(fields)
    assert torch.equal(x[:, S.THROTTLE_START:], fields["throttle"])
    assert torch.equal(layout.unpack(x)["throttle"], fields["throttle"])


def test_constants_are_defined_once():
    c = constants
    assert physics_constants.G0 is c.G0
    knot, isa_density, slug = c.KT, c.P0 / (c.R_AIR * c.T0), c.LBM * c.G0 / c.FT
    assert knot == pytest.approx(0.514444, rel=1e-6)
    assert isa_density == pytest.approx(c.RHO0, rel=1e-5)
    assert slug == pytest.approx(c.SLUG, rel=1e-15)
    ranger = load_airframe("volantex_ranger")
    assert ranger.weight == pytest.approx(ranger.mass * 9.80665)
