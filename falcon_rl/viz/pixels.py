"""TorchRL pixels of the flight: :class:`FlightPixels` adds a "pixels" entry [N, H, W, 3] uint8 (a chase
view of each aircraft with its trail coloured by bank, from the renderer of the animations and of
Gymnasium's ``render()``) to a flight env's output, for TorchRL's pixel pipelines and video
recorders::

    env = TransformedEnv(make_env("attitude", "volantex_ranger", num_envs=2), FlightPixels(160, 120))
    td = env.rollout(100)                 # td["next", "pixels"]: [2, 100, 120, 160, 3] uint8

Each env is drawn at every reset and step (about 10-20 ms per frame and env on a CPU core; an env over
its sea is drawn over its waves, a few ms more), so it is meant for a few envs (at most
``MAX_PIXEL_ENVS``): evaluation and videos, not training batches.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch
from tensordict import TensorDictBase
from torchrl.data import Bounded, Composite
from torchrl.envs import Transform

from ..physics import state as S
from ..transforms import flight_env
from .live import FlightView, simulator_sea

#: The most envs a FlightPixels transform draws.
MAX_PIXEL_ENVS = 16


class FlightPixels(Transform):
    """Adds ``out_key`` [N, height, width, 3] uint8 to the reset and step outputs."""

    def __init__(self, width: int = 240, height: int = 180, out_key: str = "pixels", trail_frames: int = 400):
        super().__init__(in_keys=[], out_keys=[out_key])
        self.width, self.height, self.out_key, self.trail_frames = width, height, out_key, trail_frames
        self._views: list[FlightView] = []

    def _base(self) -> Any:
        base = flight_env(self, "control_dt")
        if not hasattr(base, "sim"):
            raise TypeError(f"FlightPixels needs a flight env with a simulator (sim), "
                            f"got {type(base).__name__}")
        return base

    def transform_observation_spec(self, observation_spec: Composite) -> Composite:
        batch = observation_spec.shape
        observation_spec[self.out_key] = Bounded(0, 255, shape=(*batch, self.height, self.width, 3),
                                                 dtype=torch.uint8, device=observation_spec.device)
        return observation_spec

    def _draw(self, td: TensorDictBase, reset: torch.Tensor | None) -> TensorDictBase:
        base = self._base()
        sim = base.sim
        if not self._views:
            if sim.num_envs > MAX_PIXEL_ENVS:
                raise ValueError(f"FlightPixels draws at most {MAX_PIXEL_ENVS} envs, this env has "
                                 f"{sim.num_envs} (record the flight with FlightRecorder and animate the "
                                 "recording instead)")
            self._views = [FlightView(sim.airframe, 1, self.width, self.height, self.trail_frames,
                                      labels=[f"env {e}"]) for e in range(sim.num_envs)]
        x = sim.x.detach().cpu().numpy()
        time = sim.time.detach().cpu().numpy()
        restarted = None if reset is None else reset.reshape(-1).cpu().numpy()
        frames = []
        seas = simulator_sea(sim, list(range(sim.num_envs)))
        for e, view in enumerate(self._views):
            if restarted is not None and restarted[e]:
                view.reset()
            view.observe(x[e:e + 1, S.POSITION], x[e:e + 1, S.QUATERNION], float(time[e]), seas[e])
            frames.append(view.frame())
        td.set(self.out_key, torch.as_tensor(np.stack(frames), device=td.device))
        return td

    def _reset(self, tensordict: TensorDictBase, tensordict_reset: TensorDictBase) -> TensorDictBase:
        mask = tensordict.get("_reset", None) if tensordict is not None else None
        if mask is None:
            mask = torch.ones(tensordict_reset.batch_size, dtype=torch.bool)
        return self._draw(tensordict_reset, mask)

    def _step(self, tensordict: TensorDictBase, next_tensordict: TensorDictBase) -> TensorDictBase:
        return self._draw(next_tensordict, None)

    def close(self) -> None:
        for view in self._views:
            view.close()
        self._views = []
        super().close()
