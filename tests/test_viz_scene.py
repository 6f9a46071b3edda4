"""The 3D flight view: aircraft glyph, frame renderer, animations and the maneuver track figure."""

from __future__ import annotations

import math
from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest
import torch

import falcon_rl
from falcon_rl.recording import Recording, record_simulator
from falcon_rl.viz.animation import frame_indices, write_animation
from falcon_rl.viz.glyph import aircraft_glyph
from falcon_rl.viz.scene import FrameRenderer
from falcon_rl.viz.track import plot_tracks

LEVEL = np.array([[1.0, 0.0, 0.0, 0.0]])


def _roll(deg: float) -> np.ndarray:
    half = math.radians(deg) / 2
    return np.array([[math.cos(half), math.sin(half), 0.0, 0.0]])


@pytest.fixture(scope="module")
def recording(ranger) -> Recording:
    """Two rangers for 1.6 s: one level, one rolling into a turn (aileron 0.3)."""
    sim = falcon_rl.Simulator(ranger, num_envs=2, backend="torch")
    sim.reset()
    commands = torch.tensor([[0.0, 0.0, 0.0, 0.6], [0.0, 0.3, 0.0, 0.6]])
    return record_simulator(sim, commands, steps=16, substeps=5)


@pytest.fixture(scope="module")
def renderer(ranger) -> FrameRenderer:
    return FrameRenderer(ranger, width=160, height=120, camera_azimuth_deg=0.0)


@pytest.mark.parametrize("name", ["volantex_ranger", "navion", "cirrus_sr22"])
@pytest.mark.parametrize("scale", [1.0, 7.5])
def test_glyph_span_is_the_airframe_span_times_scale(name: str, scale: float) -> None:
    airframe = falcon_rl.load_airframe(name)
    glyph = aircraft_glyph(airframe, scale)
    vertices = glyph.vertices()
    assert vertices.shape[1] == 3 and len(glyph.polygons) == len(glyph.roles) == len(glyph.colors)
    assert np.ptp(vertices[:, 1]) == pytest.approx(airframe.geometry.span * scale, rel=1e-9)
    assert glyph.span == pytest.approx(airframe.geometry.span * scale)
    # The fuselage is longer fore-and-aft than high, and the wing area of the drawn trapezoid matches.
    assert np.ptp(vertices[:, 0]) > np.ptp(vertices[:, 2])
    wing = [p for p, role in zip(glyph.polygons, glyph.roles, strict=True) if role == "wing"]
    area = sum(0.5 * abs(np.cross(p[2] - p[0], p[3] - p[1])[2]) for p in wing)
    assert area == pytest.approx(airframe.geometry.wing_area * scale**2, rel=0.08)


def test_glyph_refuses_a_bad_scale() -> None:
    with pytest.raises(ValueError, match="scale"):
        aircraft_glyph("navion", 0.0)


def test_frame_shape_dtype_and_determinism(renderer: FrameRenderer) -> None:
    position = np.array([[10.0, -5.0, -40.0]])
    first = renderer.render(position, LEVEL, time=1.0)
    assert first.shape == (120, 160, 3) and first.dtype == np.uint8
    # Something besides sky and ground is drawn: many distinct colours.
    assert len(np.unique(first.reshape(-1, 3), axis=0)) > 20
    renderer.render(position + 50.0, _roll(60), time=9.0)  # another frame in between
    again = renderer.render(position, LEVEL, time=1.0)
    np.testing.assert_array_equal(first, again)


def test_banked_glyph_renders_differently(renderer: FrameRenderer) -> None:
    position = np.array([[0.0, 0.0, -30.0]])
    level = renderer.render(position, LEVEL)
    banked = renderer.render(position, _roll(40))
    changed = np.any(level != banked, axis=2).mean()
    assert changed > 0.01, f"only {changed:.4f} of the pixels changed with a 40 deg bank"


def test_several_aircraft_trails_and_tensors(ranger, recording: Recording) -> None:
    renderer = FrameRenderer([ranger, "volantex_ranger"], width=160, height=120, scale=5.0)
    t = recording.num_frames - 1
    trails = [torch.from_numpy(recording["position_ned"][: t + 1, e]) for e in range(2)]
    banks = [recording["euler"][: t + 1, e, 0] for e in range(2)]
    with_trails = renderer.render(torch.from_numpy(recording["position_ned"][t]),
                                  torch.from_numpy(recording["quaternion"][t]), trails, banks, time=1.6)
    without = renderer.render(recording["position_ned"][t], recording["quaternion"][t], time=1.6)
    assert with_trails.shape == (120, 160, 3)
    assert np.any(with_trails != without)
    with pytest.raises(ValueError, match="airframes"):
        renderer.render(recording["position_ned"][t, :1], recording["quaternion"][t, :1])
    with pytest.raises(ValueError, match="trails"):
        renderer.render(recording["position_ned"][t], recording["quaternion"][t], trails[:1])


def test_renderer_refuses_bad_input(renderer: FrameRenderer) -> None:
    with pytest.raises(ValueError, match="position_ned"):
        renderer.render(np.zeros((1, 2)), LEVEL)
    with pytest.raises(ValueError, match="NaN"):
        renderer.render(np.full((1, 3), np.nan), LEVEL)
    with pytest.raises(ValueError, match="width"):
        FrameRenderer("navion", width=0)


def test_frame_indices_keep_the_last_frame() -> None:
    assert frame_indices(11, 0.01, 20.0).tolist() == [0, 5, 10]
    assert frame_indices(12, 0.01, 20.0).tolist() == [0, 5, 10, 11]
    assert frame_indices(4, 0.1, 20.0, every=2).tolist() == [0, 2, 3]


def test_gif_is_written_with_the_right_frame_count(recording: Recording, tmp_path: Path) -> None:
    path = write_animation(recording, tmp_path / "flight.gif", fps=10, every=4, width=96, height=72)
    frames = iio.imread(path, index=None)
    expected = len(frame_indices(recording.num_frames, recording.dt, 10, 4))
    assert expected == 5
    assert frames.shape[:3] == (expected, 72, 96)
    assert np.any(frames[0] != frames[-1])


def test_mp4_is_written(recording: Recording, tmp_path: Path) -> None:
    pytest.importorskip("imageio_ffmpeg")
    path = write_animation(recording, tmp_path / "flight.mp4", every=4, width=96, height=72, envs=[1])
    assert path.exists() and path.stat().st_size > 1000


def test_animation_refuses_bad_arguments(recording: Recording, tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="unknown animation format"):
        write_animation(recording, tmp_path / "flight.avi")
    with pytest.raises(ValueError, match="envs"):
        write_animation(recording, tmp_path / "flight.gif", envs=[5])
    with pytest.raises(ValueError, match="even"):
        write_animation(recording, tmp_path / "flight.mp4", width=95)
    assert not list(tmp_path.iterdir())


def test_track_figure_for_a_2x2_grid(recording: Recording, tmp_path: Path) -> None:
    level, turn = recording.select([0]), recording.select([1])
    recordings = {("volantex_ranger", "level"): level, ("volantex_ranger", "turn"): turn,
                  ("navion", "level"): level, ("navion", "turn"): turn}
    path = plot_tracks(recordings, tmp_path / "tracks.png", glyphs_per_track=2)
    image = iio.imread(path)
    assert image.shape[0] > 400 and image.shape[1] > 500
    with pytest.raises(ValueError, match="keys"):
        plot_tracks({"navion": level}, tmp_path / "bad.png")
