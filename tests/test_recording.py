"""Flight recordings: the file, the TorchRL recorder transform and the Gymnasium recorder wrappers."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest
import torch
from torchrl.envs import TransformedEnv

import falcon_rl
from falcon_rl.envs.gym.recorder import RecordFlight, RecordFlightVector
from falcon_rl.recording import RECORDING_FORMAT, Recording, RecordingError, record_simulator
from falcon_rl.transforms.flight_recorder import FlightRecorder


def small_recording(frames: int = 5, envs: int = 2) -> Recording:
    position = np.zeros((frames, envs, 3), np.float32)
    position[:, :, 0] = np.arange(frames)[:, None]
    quaternion = np.zeros((frames, envs, 4), np.float32)
    quaternion[..., 0] = 1.0
    return Recording(np.arange(frames) * 0.1, {"position_ned": position, "quaternion": quaternion},
                     {"airframe": "volantex_ranger"})


def test_file_round_trip(tmp_path):
    sim = falcon_rl.Simulator("volantex_ranger", num_envs=2, backend="torch", seed=0)
    sim.reset()
    rec = record_simulator(sim, torch.tensor([[0.0, 0.2, 0.0, 0.6]]).expand(2, 4), steps=10, substeps=5)
    path = rec.save(tmp_path / "flight")
    assert path.suffix == ".npz"
    back = Recording.load(path)
    assert back.meta["format"] == RECORDING_FORMAT and back.meta["airframe"] == "volantex_ranger"
    assert back.num_frames == 11 and back.num_envs == 2 and back.dt == pytest.approx(0.05)
    assert set(back.fields) == set(rec.fields)
    for name, value in rec.fields.items():
        np.testing.assert_array_equal(back[name], value)
    assert back["motor_thrust"].shape == (11, 2, 1)
    np.testing.assert_allclose(back["position_ned"][-1], sim.state["position_ned"].numpy())
    one = back.select([1])
    assert one.num_envs == 1 and one.meta["labels"] == ["aircraft 1"]


def test_bad_recordings_are_refused(tmp_path):
    rec = small_recording()
    with pytest.raises(RecordingError, match="field 'euler' has shape"):
        Recording(rec.time, {**rec.fields, "euler": np.zeros((4, 2, 3))})
    with pytest.raises(RecordingError, match="time must increase"):
        Recording(rec.time[::-1], rec.fields)
    with pytest.raises(RecordingError, match="needs the fields quaternion"):
        Recording(rec.time, {"position_ned": rec["position_ned"]})
    foreign = tmp_path / "foreign.npz"
    np.savez(foreign, x=np.zeros(3))
    with pytest.raises(RecordingError, match=r"foreign\.npz: not a falcon-rl recording"):
        Recording.load(foreign)
    garbage = tmp_path / "garbage.npz"
    garbage.write_bytes(b"not a zip")
    with pytest.raises(RecordingError, match=r"garbage\.npz: not a recording"):
        Recording.load(garbage)
    other = tmp_path / "other.npz"
    np.savez(other, time=rec.time, meta=np.frombuffer(b'{"format": "x/9"}', dtype=np.uint8))
    with pytest.raises(RecordingError, match=r"meta\.format is 'x/9'"):
        Recording.load(other)


def test_recorder_transform_logs_the_chosen_envs(tmp_path):
    env = TransformedEnv(falcon_rl.make_env("attitude", "volantex_ranger", num_envs=3, seed=4),
                         FlightRecorder([0, 2], path=tmp_path / "run.npz"))
    rollout = env.rollout(30, break_when_any_done=False)
    rec = env.transform.recording()
    assert rec.num_frames == 31 and rec.num_envs == 2 and rec.meta["env_ids"] == [0, 2]
    assert rec.meta["task"] == "attitude" and rec.dt == pytest.approx(env.base_env.control_dt)
    # Frames 1.. are the states after each step: they equal the rollout's next states.
    np.testing.assert_allclose(rec["position_ned"][1:], rollout["next", "state", "position_ned"][[0, 2]]
                               .transpose(0, 1).numpy(), rtol=1e-6)
    np.testing.assert_allclose(rec["action"][1:], rollout["action"][[0, 2]].transpose(0, 1).numpy())
    np.testing.assert_allclose(rec["reward"][1:], rollout["next", "reward"][[0, 2], :, 0].T.numpy())
    assert np.isnan(rec["reward"][0]).all()
    assert {"reference/bank", "reference/airspeed", "aero_force_body", "ge_lift_factor"} <= set(rec.fields)
    env.close()
    assert Recording.load(tmp_path / "run.npz").num_frames == 31


def test_recorder_changes_nothing():
    plain = falcon_rl.make_env("altitude", "volantex_ranger", num_envs=2, seed=7)
    recorded = TransformedEnv(falcon_rl.make_env("altitude", "volantex_ranger", num_envs=2, seed=7),
                              FlightRecorder([1], every=3, max_frames=4))
    def policy(td):
        return td.set("action", torch.full((2, 2), 0.3))

    a = plain.rollout(12, policy, break_when_any_done=False)
    b = recorded.rollout(12, policy, break_when_any_done=False)
    torch.testing.assert_close(a["next", "observation"], b["next", "observation"])
    assert recorded.transform.num_frames == 4  # the reset frame and steps 3, 6, 9


def test_recorder_argument_errors():
    with pytest.raises(ValueError, match="every must be at least 1"):
        FlightRecorder(every=0)
    env = TransformedEnv(falcon_rl.make_env("altitude", "volantex_ranger", num_envs=2, seed=0),
                         FlightRecorder([5]))
    with pytest.raises(ValueError, match=r"env_ids must be .* in \[0, 2\)"):
        env.reset()
    with pytest.raises(ValueError, match="nothing was recorded"):
        FlightRecorder().recording()


def test_gymnasium_recorders(tmp_path):
    env = RecordFlight(gymnasium.make("falcon_rl/Attitude-v0", airframe="volantex_ranger", seed=0),
                       tmp_path / "single.npz")
    env.reset(seed=0)
    for _ in range(8):
        env.step(np.array([0.0, 0.3, 0.0, 0.5], np.float32))
    env.close()
    rec = Recording.load(tmp_path / "single.npz")
    assert rec.num_frames == 9 and rec["action"].shape == (9, 1, 4)
    assert rec["euler"][-1, 0, 0] > rec["euler"][0, 0, 0]  # right aileron banks right
    vector = RecordFlightVector(gymnasium.make_vec("falcon_rl/Altitude-v0", num_envs=3,
                                                   airframe="volantex_ranger"), env_ids=[2])
    vector.reset(seed=1)
    for _ in range(5):
        vector.step(np.zeros((3, 2), np.float32))
    rec = vector.recording()
    assert rec.num_frames == 6 and rec.num_envs == 1 and "reference/altitude" in rec.fields


def test_numpy_euler_matches_the_physics():
    from falcon_rl.physics.rotations import quaternion_to_euler
    from falcon_rl.recording import quaternion_euler

    q = torch.nn.functional.normalize(torch.randn(64, 4, generator=torch.Generator().manual_seed(0),
                                                  dtype=torch.float64), dim=-1)
    np.testing.assert_allclose(quaternion_euler(q.numpy()), quaternion_to_euler(q).numpy(), atol=1e-12)
