"""``render()`` for the Gymnasium envs: ``render_mode="rgb_array"`` returns the current frame
[H, W, 3] uint8 (a chase view of the aircraft with its trail coloured by bank); ``"human"`` shows it
in a matplotlib window at every step (it needs a display, so an env lists it in its ``metadata``
only where a window can open: :func:`available_render_modes`; Gymnasium's ``check_env`` makes an env in
every listed mode, and passes on a headless machine). The frames come from the same renderer as
``falcon-rl fly --gif`` (:class:`falcon_rl.viz.live.FlightView`, a higher layer, named here by
reference and imported the first time an env renders). An env made without ``render_mode`` builds
nothing and reads nothing for rendering.
"""

from __future__ import annotations

import os
import sys
from typing import Any

import numpy as np

from ...physics import state as S
from ..tasks.registry import Ref, resolve

#: The live view the renders draw with.
FLIGHT_VIEW: Ref = "falcon_rl.viz.live:FlightView"
#: The wave field and clock of each rendered env over its sea (None over the ground).
SIMULATOR_SEA: Ref = "falcon_rl.viz.live:simulator_sea"
#: Gymnasium render modes of the falcon_rl envs.
RENDER_MODES: tuple[str, ...] = ("rgb_array", "human")


def display_available() -> bool:
    """Whether a window can open here (always on macOS and Windows; X11 or Wayland on Linux)."""
    if not sys.platform.startswith("linux"):
        return True
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def available_render_modes() -> list[str]:
    """The render modes that work here: :data:`RENDER_MODES` less "human" without a display."""
    return [mode for mode in RENDER_MODES if mode != "human" or display_available()]


def check_render_mode(mode: str | None) -> None:
    """ValueError unless ``mode`` is None or one of :data:`RENDER_MODES` (human: with a display)."""
    if mode is not None and mode not in RENDER_MODES:
        raise ValueError(f"render_mode must be None or one of {RENDER_MODES}, got {mode!r}")
    if mode == "human" and not display_available():
        raise ValueError("render_mode='human' needs a display (DISPLAY is unset); use 'rgb_array'")


class GymRenderer:
    """The view of aircraft ``rows`` of a flight env (``base.sim``) and, in human mode, its window."""

    def __init__(self, mode: str, base: Any, rows: list[int], fps: float,
                 width: int = 480, height: int = 360) -> None:
        check_render_mode(mode)
        self.mode, self.base, self.rows, self.fps = mode, base, list(rows), fps
        self.view = resolve(FLIGHT_VIEW)(base.sim.airframe, num_aircraft=len(self.rows), width=width,
                                         height=height, labels=[f"env {e}" for e in self.rows])
        self._window: Any = None

    def observe(self, reset_rows: np.ndarray | None = None) -> None:
        """After a reset (``reset_rows``: which aircraft restarted, all when empty) or a step: read where
        the aircraft are and the sea under them; in human mode, show the frame."""
        if reset_rows is not None:
            self.view.reset(None if reset_rows.size == 0 else np.flatnonzero(reset_rows[self.rows]))
        sim = self.base.sim
        x = sim.x[self.rows].detach().cpu().numpy()
        seas = resolve(SIMULATOR_SEA)(sim, self.rows)
        sea = next((s for s in seas if s is not None), None)  # the sea of the first aircraft over one
        self.view.observe(x[:, S.POSITION], x[:, S.QUATERNION], float(sim.time[self.rows[0]]), sea=sea)
        if self.mode == "human":
            self.show()

    def frame(self) -> np.ndarray:
        """The current frame [H, W, 3] uint8."""
        return self.view.frame()

    def show(self) -> None:
        """Draw the frame in the window (opened on first use) and wait one control period."""
        import matplotlib.pyplot as plt

        image = self.frame()
        if self._window is None:
            figure, axes = plt.subplots(figsize=(image.shape[1] / 100, image.shape[0] / 100), dpi=100)
            axes.set_axis_off()
            figure.subplots_adjust(0, 0, 1, 1)
            self._window = (figure, axes.imshow(image))
            plt.show(block=False)
        else:
            self._window[1].set_data(image)
        plt.pause(1.0 / self.fps)

    def close(self) -> None:
        """Close the window and release the canvas."""
        if self._window is not None:
            import matplotlib.pyplot as plt

            plt.close(self._window[0])
            self._window = None
        self.view.close()
