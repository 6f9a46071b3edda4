"""Torch engine (``backend="torch"``): the reference model, batched, any device, differentiable.

One step: the Dryden filters advance once at the current height and airspeed (when turbulence is
on), then ``integrators.INTEGRATORS[integrator]`` integrates ``dynamics.derivative`` over dt with the
command held (ideal actuators put on it first, ``dynamics.hold_command``), and
``dynamics.project`` renormalises the quaternion and saturates the actuators; over a sea the surface
under each aircraft is sampled again (``Engine.sample_surface``), for the next step to hold.
With ``options={"compile": True}`` the integration step runs through ``torch.compile`` (one fused
graph instead of ~1,000 small kernels per RK4 step; the first steps compile it). A pickled engine
leaves the compiled function behind and compiles again in the process that loads it.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import torch

from . import state as S
from ._warp import init_warp, warp_device
from .aero_monomials import monomial_plan
from .derived import DERIVED_WIDTH
from .dynamics import AirInputs, derivative, derived_columns, hold_command, project
from .engine import Engine, EngineSetup
from .integrators import INTEGRATORS
from .params import ModelParams
from .rotations import ned_to_body
from .wind import dryden_step


def integrate(x: torch.Tensor, command: torch.Tensor, params: ModelParams, air: AirInputs, dt: float,
              integrator: str) -> torch.Tensor:
    """One integration step of x [N, S] under command [N, 4] (a new tensor, projected)."""

    def f(xx: torch.Tensor) -> torch.Tensor:
        return derivative(xx, command, params, air)

    return project(INTEGRATORS[integrator](f, hold_command(x, command, params), dt), params)


class TorchEngine(Engine):
    """Steps the batch with the torch model; ``compile`` routes the step through torch.compile. It runs
    a task's Warp kernels over its float32 buffers too (Warp on the same CPU or CUDA device), so a task's
    fused step is the same code on both batch backends."""

    OPTIONS = ("compile",)
    RUNS_TASK_KERNELS = True

    def __init__(self, setup: EngineSetup):
        super().__init__(setup)
        self._integrate = self._step_function()

    def _step_function(self) -> Callable[..., torch.Tensor]:
        """:func:`integrate`, through ``torch.compile`` with the ``compile`` option."""
        if not self.setup.options.get("compile", False):
            return integrate
        monomial_plan(self.params.aero_exponents)  # warm the plan cache outside the graph
        return torch.compile(integrate, dynamic=False)

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        del state["_integrate"]  # a compiled function does not pickle; rebuilt on load
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._integrate = self._step_function()

    def advance(self, substeps: int) -> None:
        for _ in range(substeps):
            if self.turbulence is not None:
                self.advance_turbulence()
            self.x.copy_(self.integrate_step())
            self.time += self.dt
            if self.sea is not None:
                self.sample_surface()

    def integrate_step(self) -> torch.Tensor:
        """x after one dt under the held command (not written back)."""
        return self._integrate(self.x, self.command, self.params, self.air, self.dt, self.integrator)

    def advance_turbulence(self) -> None:
        """Advance the Dryden filters once at the current height and mean-air airspeed and write the
        gusts that act over the coming step into ``gust_velocity_body`` / ``gust_rate_body``."""
        turb = self.turbulence
        assert turb is not None
        if not turb.external_noise:
            turb.noise.normal_(generator=self.generator)
        x = self.x
        v_air = x[:, S.VELOCITY] - ned_to_body(x[:, S.QUATERNION], self.wind_ned)
        airspeed = torch.linalg.vector_norm(v_air, dim=-1)
        filt, gust_v, gust_w = dryden_step(turb.filter, turb.noise, self.gust_velocity_body, turb.w20,
                                           S.height(x), airspeed, self.params.span, self.dt)
        turb.filter.copy_(filt)
        self.gust_velocity_body.copy_(gust_v)
        self.gust_rate_body.copy_(gust_w)

    @property
    def kernel_device(self) -> str:
        return warp_device(self.setup.device)

    def replayer(self, launches: list[Any], threads: int | None = None) -> Callable[[], None]:
        """Replays ``launches`` in order, on torch's current CUDA stream on a GPU."""
        device = self.setup.device
        if device.type != "cuda":
            if len(launches) == 1:
                return launches[0].launch

            def replay_cpu() -> None:
                for launch in launches:
                    launch.launch()

            return replay_cpu
        streams: dict[int, Any] = {}  # torch's stream handle -> its Warp view, made once

        def replay() -> None:
            handle = torch.cuda.current_stream(device).cuda_stream
            if handle not in streams:
                streams[handle] = init_warp().stream_from_torch(device)
            for launch in launches:
                launch.launch(stream=streams[handle])

        return replay

    def derived(self) -> torch.Tensor:
        out = derived_columns(self.x, self.params, self.air)
        assert out.shape[-1] == DERIVED_WIDTH
        return out
