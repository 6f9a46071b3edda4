"""Live views of running envs: :class:`FlightView` keeps the recent trails of E aircraft and draws
frames with :class:`~falcon_rl.viz.scene.FrameRenderer`. It is what Gymnasium's ``render()``
(``render_mode="rgb_array"`` / ``"human"``) and the TorchRL :class:`~falcon_rl.transforms.FlightPixels`
transform draw with; an env never builds one unless it is asked to render, so an unrendered env pays
nothing. Over the sea a view draws the wave field it is given at each :meth:`FlightView.observe`
(:func:`simulator_sea` reads it from a simulator)."""

from __future__ import annotations

from collections import deque
from typing import Any

import numpy as np

from ..physics.surface import OVER_WATER
from ..recording import quaternion_euler, sea_snapshot
from .scene import FrameRenderer
from .sea import SeaField


def simulator_sea(sim: Any, rows: list[int] | np.ndarray) -> list[tuple[SeaField, float] | None]:
    """Per row of ``rows`` (env indices of the simulator ``sim``): its wave field and clock (s) when it flies
    over its sea (``sim.sea``, ``sim.surface``), else None."""
    rows = list(rows)
    over_water = sim.surface[:, OVER_WATER]
    fields = sea_snapshot(getattr(sim, "sea", None), over_water, rows)  # [6, E, K] of these rows only
    if fields is None:
        return [None] * len(rows)
    water = over_water[rows].detach().cpu().numpy() != 0
    clock = sim.time[rows].detach().cpu().numpy()
    return [(SeaField.from_components(fields[:, j]), float(clock[j])) if water[j] else None
            for j in range(len(rows))]


class FlightView:
    """Frames [height, width, 3] uint8 of E aircraft of one airframe with their last ``trail_frames``
    positions drawn as a trail coloured by bank.

    ``observe(position [E, 3], quaternion [E, 4], time, sea)`` after each reset and step; ``reset(rows)``
    clears the trails of the aircraft ``rows`` (all when None); ``frame()`` draws."""

    def __init__(self, airframe: Any, num_aircraft: int = 1, width: int = 480, height: int = 360,
                 trail_frames: int = 400, labels: list[str] | None = None) -> None:
        if trail_frames < 1:
            raise ValueError(f"trail_frames must be at least 1, got {trail_frames}")
        self.renderer = FrameRenderer(airframe, width=width, height=height, labels=labels)
        self.num_aircraft = int(num_aircraft)
        self.trails: list[deque[tuple[np.ndarray, float]]] = [deque(maxlen=trail_frames)
                                                              for _ in range(self.num_aircraft)]
        self.position = np.zeros((self.num_aircraft, 3))
        self.quaternion = np.tile([1.0, 0.0, 0.0, 0.0], (self.num_aircraft, 1))
        self.time = 0.0
        self.sea: tuple[SeaField, float] | None = None

    def reset(self, rows: np.ndarray | list[int] | None = None) -> None:
        """Forget the trails of ``rows`` (all aircraft when None)."""
        for e in range(self.num_aircraft) if rows is None else rows:
            self.trails[int(e)].clear()

    def observe(self, position_ned: Any, quaternion: Any, time: float = 0.0,
                sea: tuple[SeaField, float] | None = None) -> None:
        """Record where the aircraft are: ``position_ned`` [E, 3] m, ``quaternion`` [E, 4], ``time`` s, and
        the sea they fly over (its wave field and clock, s; None: the ground)."""
        self.position = np.asarray(position_ned, dtype=np.float64).reshape(self.num_aircraft, 3)
        self.quaternion = np.asarray(quaternion, dtype=np.float64).reshape(self.num_aircraft, 4)
        self.time = float(time)
        self.sea = sea
        bank = quaternion_euler(self.quaternion)[:, 0]
        for e, trail in enumerate(self.trails):
            trail.append((self.position[e].copy(), float(bank[e])))

    def frame(self) -> np.ndarray:
        """The current frame [height, width, 3] uint8."""
        trails = [np.array([p for p, _ in trail]).reshape(-1, 3) for trail in self.trails]
        banks = [np.array([b for _, b in trail]) for trail in self.trails]
        sea, clock = self.sea if self.sea is not None else (None, None)
        return self.renderer.render(self.position, self.quaternion, trails, banks, time=self.time, sea=sea,
                                    sea_time=clock)

    def close(self) -> None:
        """Release the renderer's canvas."""
        self.renderer.close()
