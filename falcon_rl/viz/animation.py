"""Animations of flight recordings: GIF (imageio, Pillow plugin) or MP4 (imageio with imageio-ffmpeg),
one :class:`~.scene.FrameRenderer` frame per written frame, every aircraft of the recording in one
scene with its trail coloured by bank angle. A recording over the sea draws the sea (the wave field of
the first aircraft over it in each frame, at that aircraft's clock: :func:`.sea.scene_sea`) instead of
the ground.

Timing: the recording's frames are ``dt`` seconds apart. Every ``every``-th frame is drawn and the file
plays at ``fps`` frames per second, so it runs ``every * dt * fps`` times real time. By default
``every = max(1, round(1 / (fps * dt)))``: real time, as near as whole frames allow (a recording at
10 Hz written at 20 fps draws every frame and plays at 2x real time; one at 100 Hz keeps every 5th
frame and plays in real time). The last recorded frame is always drawn.

A GIF is kept in memory until it is written (about 0.7 MB a 480x360 frame); use MP4 for long flights.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from ..recording import Recording, quaternion_euler
from .scene import FrameRenderer
from .sea import scene_sea

#: Suffixes write_animation understands.
ANIMATION_SUFFIXES: tuple[str, ...] = (".gif", ".mp4")
#: A trail is drawn through at most this many points (evenly decimated).
MAX_TRAIL_POINTS = 600
#: Frames beyond which a progress bar is shown.
_PROGRESS_FRAMES = 50


def frame_indices(num_frames: int, dt: float, fps: float, every: int | None = None) -> np.ndarray:
    """Indices [F] of the recording frames drawn (see the module docstring for ``every``)."""
    if every is None:
        every = max(1, round(1.0 / (fps * dt))) if dt > 0 else 1
    indices = np.arange(0, num_frames, every)
    if indices[-1] != num_frames - 1:
        indices = np.append(indices, num_frames - 1)
    return indices


def bank_angles(rec: Recording) -> np.ndarray:
    """Bank (roll) angles [T, E] rad: ``euler[..., 0]`` when recorded, else from ``quaternion``."""
    if rec.has("euler"):
        return np.asarray(rec["euler"][..., 0], dtype=np.float64)
    return quaternion_euler(rec["quaternion"])[..., 0]


def auto_scale(rec: Recording, spans: Sequence[float]) -> float:
    """Glyph scale for a recording: 1 for one aircraft (the chase camera frames it), else large enough
    that the largest glyph spans 8% of the largest distance between the aircraft (at least 1)."""
    position = np.asarray(rec["position_ned"], dtype=np.float64)
    if position.shape[1] < 2:
        return 1.0
    spread = np.linalg.norm(position - position.mean(1, keepdims=True), axis=2).max()
    return float(max(1.0, 0.08 * 2 * spread / max(spans)))


def write_animation(rec: Recording, path: str | Path, fps: float = 20.0, every: int | None = None,
                    width: int = 480, height: int = 360, envs: Sequence[int] | None = None,
                    scale: float | None = None, camera_azimuth_deg: float | None = None,
                    progress: bool | None = None) -> Path:
    """Write an animation of ``rec`` (a :class:`Recording`) to ``path``; the suffix (``.gif`` or
    ``.mp4``) picks the format. Returns the path.

    ``fps``: frames per second of the file; ``every``: draw every n-th recorded frame (None: real time,
    see the module docstring); ``width`` x ``height``: pixels (even numbers for MP4); ``envs``: indices
    of the aircraft to show (None: all); ``scale``: glyph scale (None: :func:`auto_scale`);
    ``camera_azimuth_deg``: None for the chase view, else a fixed camera direction (deg from north);
    ``progress``: show a tqdm bar (None: when more than 50 frames)."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in ANIMATION_SUFFIXES:
        raise ValueError(f"{path}: unknown animation format {path.suffix!r}; use .gif or .mp4")
    if not isinstance(rec, Recording):
        raise ValueError(f"rec must be a Recording, got {type(rec).__name__}")
    if not (isinstance(fps, (int, float)) and math.isfinite(fps) and 0 < fps <= 120):
        raise ValueError(f"fps must be in (0, 120], got {fps!r}")
    if every is not None and (isinstance(every, bool) or not isinstance(every, int) or every < 1):
        raise ValueError(f"every must be a positive integer or None, got {every!r}")
    if suffix == ".mp4" and (width % 2 or height % 2):
        raise ValueError(f"MP4 needs an even width and height, got {width}x{height}")
    if envs is not None:
        index = list(envs)
        if not index or any(not 0 <= e < rec.num_envs for e in index):
            raise ValueError(f"envs must be indices in [0, {rec.num_envs}), got {index}")
        rec = rec.select(index)
    airframe = rec.meta.get("airframe")
    if not airframe:
        raise ValueError("the recording's meta names no airframe")
    renderer = FrameRenderer(airframe, width=width, height=height, labels=rec.meta.get("labels"),
                             camera_azimuth_deg=camera_azimuth_deg)
    if scale is None:
        scale = auto_scale(rec, [g.span for g in renderer.glyphs])
    if scale != 1.0:
        renderer = FrameRenderer(airframe, width=width, height=height, labels=rec.meta.get("labels"),
                                 camera_azimuth_deg=camera_azimuth_deg, scale=scale)
    position = np.asarray(rec["position_ned"], dtype=np.float64)
    quaternion = np.asarray(rec["quaternion"], dtype=np.float64)
    bank = bank_angles(rec)
    indices = frame_indices(rec.num_frames, rec.dt, fps, every)
    show = progress if progress is not None else len(indices) > _PROGRESS_FRAMES
    frames = indices
    if show:
        from tqdm.auto import tqdm
        frames = tqdm(indices, desc=f"rendering {path.name}", unit="frame")

    path.parent.mkdir(parents=True, exist_ok=True)
    writer = _open_writer(path, suffix, fps)
    try:
        for t in frames:
            stride = max(1, math.ceil((t + 1) / MAX_TRAIL_POINTS))
            points = np.arange(t, -1, -stride)[::-1]
            trails = [position[points, e] for e in range(rec.num_envs)]
            banks = [bank[points, e] for e in range(rec.num_envs)]
            sea = scene_sea(rec, int(t))
            writer.append(renderer.render(position[t], quaternion[t], trails, banks, time=float(rec.time[t]),
                                          sea=None if sea is None else sea[0],
                                          sea_time=None if sea is None else sea[1]))
    finally:
        writer.close()
        renderer.close()
    return path


class _Writer:
    """append(frame [H, W, 3] uint8) and close() over the imageio GIF or MP4 writers."""

    def __init__(self, append: Callable[[np.ndarray], object], close: Callable[[], object]) -> None:
        self.append, self.close = append, close


def _open_writer(path: Path, suffix: str, fps: float) -> _Writer:
    if suffix == ".gif":
        import imageio.v3 as iio

        handle = iio.imopen(path, "w", plugin="pillow")
        duration = round(1000.0 / fps)
        return _Writer(lambda frame: handle.write(frame, is_batch=False, duration=duration, loop=0),
                       handle.close)
    try:
        import imageio.v2 as iio2
        import imageio_ffmpeg  # noqa: F401
    except ImportError:
        raise ValueError(f"{path}: MP4 needs the imageio-ffmpeg package") from None
    handle = iio2.get_writer(path, format="FFMPEG", mode="I", fps=fps, codec="libx264", quality=7,
                             pixelformat="yuv420p", macro_block_size=2)
    return _Writer(handle.append_data, handle.close)
