"""The sea in the visuals: recordings carry the wave fields, the 3D view and the GIF draw the waves the
physics flies over, the Tacview export names the sea and rides a marker on the water."""

from __future__ import annotations

import math
from datetime import datetime

import imageio.v3 as iio
import numpy as np
import pytest
import torch
from torchrl.envs import TransformedEnv

import falcon_rl
from falcon_rl.physics.sea import SeaState, sample_sea
from falcon_rl.recording import SEA_COMPONENTS, FlightLog, Recording, RecordingError, record_simulator
from falcon_rl.transforms.flight_recorder import FlightRecorder
from falcon_rl.viz.acmi import FIRST_OBJECT_ID, read_acmi, write_acmi
from falcon_rl.viz.acmi_sea import FIRST_SEA_ID, SEA_MARKER_TYPE, parse_wave_field
from falcon_rl.viz.animation import write_animation
from falcon_rl.viz.geodesy import DEFAULT_REFERENCE
from falcon_rl.viz.pixels import FlightPixels
from falcon_rl.viz.scene import FrameRenderer
from falcon_rl.viz.sea import SeaField, recorded_sea, scene_sea, sea_clock, sea_mesh

WATER = torch.tensor([True, False, True])


def sea_fraction(image: np.ndarray) -> float:
    """The share of the lower third's pixels [H, W, 3] uint8 that are sea blue (blue well above red)."""
    lower = image[2 * image.shape[0] // 3:].astype(int)
    return float(np.mean((lower[..., 2] > lower[..., 0] + 60) & (lower[..., 2] > lower[..., 1])))


@pytest.fixture(scope="module")
def sea_flight() -> tuple[Recording, dict[str, np.ndarray]]:
    """Three rangers over 1 s of the attitude task, envs 0 and 2 over their own sea state 4, env 1 over the
    ground: the recording and the simulator's wave fields {component: [3, K]}."""
    base = falcon_rl.make_env("attitude", "volantex_ranger", num_envs=3, seed=4, backend="torch")
    base.sim.set_sea(4, WATER)
    env = TransformedEnv(base, FlightRecorder([0, 1, 2]))
    env.rollout(20, break_when_any_done=False)
    physics = {name: getattr(base.sim.sea, name).numpy().copy() for name in SEA_COMPONENTS}
    rec = env.transform.recording()
    env.close()
    return rec, physics


@pytest.fixture(scope="module")
def sea_recording(sea_flight) -> Recording:
    return sea_flight[0]


@pytest.fixture(scope="module")
def flat_recording() -> Recording:
    sim = falcon_rl.Simulator("volantex_ranger", num_envs=1, backend="torch", seed=0)
    sim.reset()
    return record_simulator(sim, sim.command.clone(), steps=6, substeps=5)


def test_a_recording_over_the_sea_carries_its_wave_fields(sea_flight, tmp_path):
    rec, physics = sea_flight
    assert rec.has_sea and rec.num_frames == 21
    for name in SEA_COMPONENTS:
        assert rec.sea[name].shape == (1, 3, physics[name].shape[1])
        expected = physics[name] * (WATER.numpy()[:, None] if name == "amplitude" else 1.0)
        np.testing.assert_array_equal(rec.sea[name][0], expected)  # env 1 (ground): zero amplitudes
    assert (rec["sea_field"] == 0).all()
    np.testing.assert_array_equal(rec["over_water"][0], [1.0, 0.0, 1.0])
    surface_fields = {"surface_elevation", "surface_clearance", "lowest_tip_clearance", "wave_velocity_ned"}
    assert surface_fields <= set(rec.fields)
    np.testing.assert_allclose(rec["surface_clearance"], rec["height"] - rec["surface_elevation"], atol=1e-4)
    assert (rec["surface_elevation"][:, 1] == 0).all() and np.abs(rec["surface_elevation"][:, 0]).max() > 0.01
    # The recorded field at the aircraft's clock gives the elevation the physics sampled under the CG.
    for frame in (0, 10, 20):
        field = recorded_sea(rec, frame, 2)
        north, east = rec["position_ned"][frame, 2, :2]
        assert field is not None and recorded_sea(rec, frame, 1) is None
        assert field.elevation(north, east, sea_clock(rec, frame, 2)) == pytest.approx(
            rec["surface_elevation"][frame, 2], abs=2e-4)
    loaded = Recording.load(rec.save(tmp_path / "sea.npz"))
    assert loaded.has_sea and loaded.meta == rec.meta
    for name in SEA_COMPONENTS:
        np.testing.assert_array_equal(loaded.sea[name], rec.sea[name])
    np.testing.assert_array_equal(loaded["sea_field"], rec["sea_field"])
    only = loaded.select([2])
    np.testing.assert_array_equal(only.sea["phase"][:, 0], rec.sea["phase"][:, 2])


def test_a_new_field_is_a_new_snapshot_and_the_ground_has_none():
    env = falcon_rl.make_env("altitude", "volantex_ranger", num_envs=2, seed=1, backend="torch")
    env.reset()
    log = FlightLog(env, [0, 1])
    log.capture()  # no sea yet: no field
    env.sim.set_sea(3)
    log.capture()
    log.capture()
    env.sim.set_sea(5, torch.tensor([False, True]))  # a new draw for env 1
    log.capture()
    env.sim.set_sea(None)  # back over the ground
    log.capture()
    rec = log.recording()
    np.testing.assert_array_equal(rec["sea_field"][:, 0], [-1, 0, 0, 1, -1])
    assert rec.sea["amplitude"].shape[0] == 2
    np.testing.assert_array_equal(rec.sea["phase"][0, 0], rec.sea["phase"][1, 0])
    assert not np.array_equal(rec.sea["phase"][0, 1], rec.sea["phase"][1, 1])
    assert recorded_sea(rec, 3, 1).significant_height > recorded_sea(rec, 1, 1).significant_height
    assert [scene_sea(rec, k) is None for k in range(5)] == [True, False, False, False, True]


def test_recordings_without_a_sea_load_and_bad_seas_are_refused(flat_recording, tmp_path):
    rec = flat_recording
    assert not rec.has_sea and "sea_field" not in rec.fields
    loaded = Recording.load(rec.save(tmp_path / "flat.npz"))
    assert not loaded.has_sea and loaded.num_frames == rec.num_frames
    old = Recording(rec.time, {k: rec[k] for k in ("position_ned", "quaternion", "height")},
                    {"airframe": "navion"})
    assert not Recording.load(old.save(tmp_path / "old.npz")).has_sea
    envs, k = rec.num_envs, 8
    sea = {name: np.zeros((1, envs, k), np.float32) for name in SEA_COMPONENTS}
    sea["direction_cos"][:] = 1.0
    index = {"sea_field": np.zeros((rec.num_frames, envs), np.int64)}
    Recording(rec.time, {**rec.fields, **index}, rec.meta, sea)  # a valid calm sea
    with pytest.raises(RecordingError, match="needs the integer field 'sea_field'"):
        Recording(rec.time, rec.fields, rec.meta, sea)
    with pytest.raises(RecordingError, match="missing \\['phase'\\]"):
        Recording(rec.time, {**rec.fields, **index}, rec.meta, {n: v for n, v in sea.items() if n != "phase"})
    with pytest.raises(RecordingError, match="must index the 1 wave fields"):
        Recording(rec.time, {**rec.fields, "sea_field": index["sea_field"] + 1}, rec.meta, sea)
    with pytest.raises(RecordingError, match="unit vectors"):
        Recording(rec.time, {**rec.fields, **index}, rec.meta, {**sea, "direction_sin": sea["direction_cos"]})
    bogus = tmp_path / "bogus.npz"
    np.savez(bogus, time=rec.time, meta=np.frombuffer(b'{"format": "falcon-rl-recording/1"}', np.uint8),
             **{"field/position_ned": rec["position_ned"], "field/quaternion": rec["quaternion"],
                "sea/swell": np.zeros((1, envs, k))})
    with pytest.raises(RecordingError, match="not a wave field array"):
        Recording.load(bogus)


def test_the_viewers_sea_is_the_physics_sea():
    surface = sample_sea(SeaState.from_code(4, direction=0.7), 3, torch.Generator().manual_seed(5),
                         components=64, dtype=torch.float64)
    generator = np.random.default_rng(0)
    north, east = generator.uniform(-300, 300, (2, 3, 7))
    for time in (0.0, 3.7, 41.0):
        physics = surface.elevation(torch.from_numpy(north), torch.from_numpy(east), time).numpy()
        for env in range(3):
            viewer = SeaField.from_surface(surface, env).elevation(north[env], east[env], time)
            np.testing.assert_allclose(viewer, physics[env], rtol=1e-12, atol=1e-12)
    field = SeaField.from_surface(surface, 1)
    assert field.sea_state == 4 and 1.25 < field.significant_height < 2.5
    assert abs(math.remainder(math.radians(field.mean_direction_deg) - 0.7, 2 * math.pi)) < 0.3
    # The mesh a camera 6 m over the water sees: where it is fine enough for every component, its
    # vertices lie on the physics' surface.
    pitch = math.radians(20.0)
    world_to_cam = np.array([[0.0, 1.0, 0.0], [-math.sin(pitch), 0.0, -math.cos(pitch)],
                             [math.cos(pitch), 0.0, math.sin(pitch)]])
    mesh = sea_mesh(field, 12.5, np.array([0.0, 0.0, -6.0]), world_to_cam, 380.0, 480, 360, far=400.0,
                    columns=96, rows=96)
    assert mesh is not None and mesh.shape == (97, 97, 3)
    rows = np.linalg.norm(np.diff(mesh[..., :2], axis=0), axis=-1)[:, :-1]
    cols = np.linalg.norm(np.diff(mesh[..., :2], axis=1), axis=-1)[:-1]
    fine = np.maximum(rows, cols) * 4.0 <= 2 * math.pi / field.wavenumber.max()
    assert fine.sum() > 100
    points = mesh[:-1, :-1][fine]
    physics = surface.elevation(torch.from_numpy(points[None, :, 0]).expand(3, -1),
                                torch.from_numpy(points[None, :, 1]).expand(3, -1), 12.5)[1].numpy()
    np.testing.assert_allclose(-points[:, 2], physics, atol=1e-9)
    assert sea_mesh(field, 0.0, np.array([0.0, 0.0, 1.0]), world_to_cam, 380.0, 480, 360, far=400.0) is None


def test_the_3d_view_and_the_gif_draw_the_sea(sea_recording, tmp_path):
    rec = sea_recording.select([0])
    renderer = FrameRenderer("volantex_ranger", width=160, height=120)
    frame = 10
    args = (rec["position_ned"][frame], rec["quaternion"][frame])
    field, clock = scene_sea(rec, frame)
    flat = renderer.render(*args, time=0.5)
    sea = renderer.render(*args, time=0.5, sea=field, sea_time=clock)
    later = renderer.render(*args, time=0.5, sea=field, sea_time=clock + 2.0)
    assert sea_fraction(flat) < 0.01 and sea_fraction(sea) > 0.9
    assert np.abs(sea.astype(int) - later).mean() > 1.0  # the waves move
    np.testing.assert_array_equal(renderer.render(*args, time=0.5), flat)  # back over the ground as before
    path = write_animation(sea_recording, tmp_path / "sea.gif", width=160, height=120, every=5)
    frames = iio.imread(path)
    assert frames.shape == (5, 120, 160, 3)
    assert all(sea_fraction(image) > 0.5 for image in frames)
    renderer.close()


def test_pixels_draw_an_env_over_its_sea():
    base = falcon_rl.make_env("altitude", "volantex_ranger", num_envs=2, seed=3, backend="torch")
    base.sim.set_sea(4, torch.tensor([True, False]))
    env = TransformedEnv(base, FlightPixels(160, 120))
    pixels = env.reset()["pixels"].numpy()
    assert sea_fraction(pixels[0]) > 0.5 and sea_fraction(pixels[1]) < 0.01
    env.close()


def test_the_tacview_export_names_the_sea_and_rides_the_waves(sea_recording, tmp_path):
    rec = sea_recording
    acmi = read_acmi(write_acmi(rec, tmp_path / "sea.zip.acmi", reference_time=datetime(2024, 1, 1)))
    assert "WMO sea state 4" in acmi.header["Comments"] and "eta(n e t)" in acmi.header["Comments"]
    markers = {format(FIRST_SEA_ID + e, "x"): e for e in (0, 2)}
    assert set(acmi.objects) == {format(FIRST_OBJECT_ID + e, "x") for e in range(3)} | set(markers)
    for oid, env in markers.items():
        marker = acmi.objects[oid]
        assert marker.properties["Type"] == SEA_MARKER_TYPE and marker.properties["SeaState"] == "4"
        assert marker.properties["Parent"] == format(FIRST_OBJECT_ID + env, "x")
        field = parse_wave_field(marker.properties["WaveField"])
        for name in SEA_COMPONENTS:
            np.testing.assert_allclose(getattr(field, name), rec.sea[name][0, env], rtol=1e-7, atol=1e-12)
        assert float(marker.properties["WaveHeight"]) == pytest.approx(field.significant_height, abs=1e-3)
        np.testing.assert_allclose(marker.altitude - DEFAULT_REFERENCE.altitude_m,
                                   rec["surface_elevation"][:, env], atol=2e-3)
        aircraft = acmi.objects[format(FIRST_OBJECT_ID + env, "x")]
        np.testing.assert_allclose(aircraft.values["AGL"], rec["surface_clearance"][:, env], atol=6e-3)
        np.testing.assert_allclose(marker.longitude, aircraft.longitude, atol=1e-9)


def test_a_flat_recording_is_drawn_and_exported_as_before(flat_recording, tmp_path):
    rec = flat_recording
    assert scene_sea(rec, 0) is None
    frames = iio.imread(write_animation(rec, tmp_path / "flat.gif", width=160, height=120, every=3))
    renderer = FrameRenderer("volantex_ranger", width=160, height=120, labels=rec.meta["labels"])
    assert all(sea_fraction(image) < 0.01 for image in frames)
    first = renderer.render(rec["position_ned"][0], rec["quaternion"][0], [rec["position_ned"][:1, 0]],
                            [np.zeros(1)], time=0.0)
    assert np.abs(first.astype(int) - frames[0]).mean() < 3.0  # GIF palette only
    acmi = read_acmi(write_acmi(rec, tmp_path / "flat.acmi"))
    assert "Comments" not in acmi.header and set(acmi.objects) == {format(FIRST_OBJECT_ID, "x")}
    np.testing.assert_allclose(acmi.objects["101"].values["AGL"], rec["height"][:, 0], atol=1e-3)
