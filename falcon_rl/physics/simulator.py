"""Simulator: the backend-agnostic facade used by envs, controllers and tools.

    sim = Simulator(load_airframe("navion"), num_envs=1024)
    sim.reset()                      # trimmed level flight at cruise, 100 m
    sim.step(commands)               # commands [N, 4] in [-1, 1]: elevator, aileron, rudder, throttle
    td = sim.state                   # TensorDict of named fields, batch [N]: td["height"], ...

State lives in one preallocated tensor updated in place; ``state`` returns clones.
"""

from __future__ import annotations

from collections.abc import Mapping

import torch
from tensordict import TensorDict

from ..airframe import Airframe, load_airframe
from . import state as S
from .aero import monomial_plan
from .dynamics import AirInputs, derivative, evaluate, ground_contact, project
from .integrators import INTEGRATORS
from .params import build_params
from .rotations import euler_to_quaternion, ned_to_body, quaternion_to_euler
from .trim import trim_level
from .wind import Turbulence, TurbulenceConfig, dryden_step, turbulence_config

BACKENDS = ("torch", "warp", "scipy")
DEFAULT_HEIGHT = 100.0


class Simulator:
    """Batched fixed-wing 6DoF simulator.

    Args:
        airframe: an :class:`Airframe` or a shipped name / JSON path.
        num_envs: N, the batch size.
        backend: "torch" (batched, differentiable), "warp" (fused kernels) or "scipy"
            (one env, float64, ``solve_ivp`` RK45 reference).
        device, dtype: where the state lives (scipy forces cpu/float64).
        dt: step length, s. integrator: "rk4" or "euler" (ignored by scipy).
        ground_effect: True / "induced", "paper" or False / "off" (per-env, see params).
        wind: steady wind in NED, [3] or [N, 3] m/s, or None (per-env, in ``wind_ned``).
        turbulence: None (off), a MIL severity name ("very_light", "light", "moderate", "severe")
            or a :class:`~falcon_rl.physics.wind.TurbulenceConfig`; the Dryden state is ``turbulence``
            (per-env W20 in ``turbulence.w20``), the gusts are published in ``state``.
        seed: seed of this simulator's generator (and of the Warp turbulence streams).
        check_inputs: raise on malformed or non-finite commands (costs a host sync on CUDA).
        warp_cpu_threads: threads that step a warp-backend batch on the CPU (None: one per
            available core, at most one per 512 envs); ignored by the other backends and on CUDA.
        compile: torch backend only: step through ``torch.compile`` of the integration step (one
            fused graph instead of ~1,000 small kernels per RK4 step; the first steps compile it,
            tens of seconds on a CPU).
    """

    def __init__(
        self,
        airframe: Airframe | str,
        num_envs: int = 1,
        backend: str = "torch",
        device: str | torch.device = "cpu",
        dt: float = 0.01,
        integrator: str = "rk4",
        ground_effect: bool | str = True,
        wind: torch.Tensor | list[float] | None = None,
        turbulence: str | TurbulenceConfig | None = None,
        seed: int = 0,
        dtype: torch.dtype = torch.float32,
        check_inputs: bool = True,
        warp_cpu_threads: int | None = None,
        compile: bool = False,
    ):
        if isinstance(airframe, str):
            airframe = load_airframe(airframe)
        if backend not in BACKENDS:
            raise ValueError(f"backend must be one of {BACKENDS}, got {backend!r}")
        if integrator not in INTEGRATORS:
            raise ValueError(f"integrator must be one of {list(INTEGRATORS)}, got {integrator!r}")
        if not num_envs >= 1:
            raise ValueError(f"num_envs must be >= 1, got {num_envs}")
        if not dt > 0:
            raise ValueError(f"dt must be > 0, got {dt}")
        if warp_cpu_threads is not None and not warp_cpu_threads >= 1:
            raise ValueError(f"warp_cpu_threads must be None or >= 1, got {warp_cpu_threads}")
        if backend == "scipy":
            if num_envs != 1:
                raise ValueError("the scipy reference backend runs exactly one env")
            device, dtype = "cpu", torch.float64
        self.airframe = airframe
        self.num_envs = num_envs
        self.backend = backend
        self.device = torch.device(device)
        self.dtype = dtype
        self.dt = float(dt)
        self.integrator = integrator
        self.check_inputs = check_inputs
        self.warp_cpu_threads = warp_cpu_threads
        if compile and backend != "torch":
            raise ValueError(f"compile=True applies to the torch backend, not {backend!r}")
        self.compile = compile
        self.layout = S.StateLayout(airframe.num_motors)
        self.params = build_params(airframe, num_envs, self.device, dtype, ground_effect)
        self.generator = torch.Generator(device=self.device).manual_seed(seed)
        self.x = torch.zeros(num_envs, self.layout.size, device=self.device, dtype=dtype)
        self.command = torch.zeros(num_envs, S.NUM_CONTROLS, device=self.device, dtype=dtype)
        self.wind_ned = torch.zeros(num_envs, 3, device=self.device, dtype=dtype)
        if wind is not None:
            self.wind_ned[:] = torch.as_tensor(wind, dtype=dtype, device=self.device)
        self.gust_velocity_body = torch.zeros(num_envs, 3, device=self.device, dtype=dtype)
        self.gust_rate_body = torch.zeros(num_envs, 3, device=self.device, dtype=dtype)
        self.time = torch.zeros(num_envs, device=self.device, dtype=dtype)
        config = turbulence_config(turbulence)
        self.turbulence: Turbulence | None = (
            None if config is None else Turbulence(config, num_envs, self.device, dtype, seed))
        self._default: torch.Tensor | None = None
        self._default_command: torch.Tensor | None = None
        self._engine = _make_engine(self)
        self.reset()

    # ------------------------------------------------------------------ state
    @property
    def air(self) -> AirInputs:
        return AirInputs(self.wind_ned, self.gust_velocity_body, self.gust_rate_body)

    def default_initial(self) -> tuple[torch.Tensor, torch.Tensor]:
        """(state [S], command [4]) of trimmed level flight at cruise speed and 100 m."""
        if self._default is None:
            ge = int(self.params.ground_effect_mode[0])
            mode = {0: "off", 1: "induced", 2: "paper"}[ge]
            trim = trim_level(self.airframe, self.airframe.envelope.cruise_speed, DEFAULT_HEIGHT,
                              ground_effect=mode)
            self._default = trim.state[0].to(self.device, self.dtype)
            self._default_command = trim.commands[0].to(self.device, self.dtype)
        assert self._default_command is not None
        return self._default, self._default_command

    def reset(self, initial: Mapping[str, torch.Tensor] | torch.Tensor | None = None,
              mask: torch.Tensor | None = None) -> TensorDict:
        """Reset the envs selected by ``mask`` [N] bool (all when None).

        ``initial`` is a full state tensor [N, S] / [S], or a mapping of named fields
        (position_ned, quaternion or euler, velocity_body, angular_rate_body, surface_position,
        throttle, command), each [N, ...] or broadcastable; missing fields come from trimmed
        cruise at 100 m. Rows outside the mask are never touched.
        """
        n = self.num_envs
        base, base_cmd = self.default_initial()
        new_x = base.expand(n, -1).clone()
        new_cmd = base_cmd.expand(n, -1).clone()
        if isinstance(initial, torch.Tensor):
            new_x[:] = initial.to(self.device, self.dtype)
        elif initial is not None:
            new_x, new_cmd = self._compose_initial(initial, new_x, new_cmd)
        new_x = project(new_x, self.params)
        if mask is None:
            self.x.copy_(new_x)
            self.command.copy_(new_cmd)
            self.time.zero_()
            self.gust_velocity_body.zero_()
            self.gust_rate_body.zero_()
        else:
            mask = mask.to(self.device).reshape(n)
            self.x[mask] = new_x[mask]
            self.command[mask] = new_cmd[mask]
            self.time[mask] = 0.0
            self.gust_velocity_body.masked_fill_(mask[:, None], 0.0)
            self.gust_rate_body.masked_fill_(mask[:, None], 0.0)
        if self.turbulence is not None:
            self.turbulence.reset(mask)
        self._engine.after_reset(mask)
        return self.state

    def _compose_initial(self, initial: Mapping[str, torch.Tensor], x: torch.Tensor,
                         cmd: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        allowed = {"position_ned", "quaternion", "euler", "velocity_body", "angular_rate_body",
                   "surface_position", "throttle", "command", "height"}
        unknown = set(initial.keys()) - allowed
        if unknown:
            raise KeyError(f"unknown initial fields {sorted(unknown)}; allowed {sorted(allowed)}")

        def val(key: str) -> torch.Tensor:
            return torch.as_tensor(initial[key], dtype=self.dtype, device=self.device)

        if "position_ned" in initial:
            x[:, S.POSITION] = val("position_ned")
        if "height" in initial:
            x[:, 2] = -val("height")
        if "quaternion" in initial and "euler" in initial:
            raise KeyError("give either 'quaternion' or 'euler', not both")
        if "quaternion" in initial:
            x[:, S.QUATERNION] = val("quaternion")
        if "euler" in initial:
            x[:, S.QUATERNION] = euler_to_quaternion(val("euler").expand(self.num_envs, 3))
        if "velocity_body" in initial:
            x[:, S.VELOCITY] = val("velocity_body")
        if "angular_rate_body" in initial:
            x[:, S.ANGULAR_RATE] = val("angular_rate_body")
        if "surface_position" in initial:
            x[:, S.SURFACE_POSITION] = val("surface_position")
            x[:, S.SURFACE_RATE] = 0.0
        if "throttle" in initial:
            thr = val("throttle")
            x[:, self.layout.throttle] = thr.unsqueeze(-1) if thr.dim() == 1 else thr
        if "command" in initial:
            cmd[:] = val("command")
        if not torch.isfinite(x).all():
            raise ValueError("initial state contains NaN or Inf")
        return x, cmd

    # ------------------------------------------------------------------ stepping
    def step(self, commands: torch.Tensor) -> None:
        """Advance all envs by dt under ``commands`` [N, 4] in [-1, 1] (clipped).

        Read the result from :attr:`state` (kept off the hot path: stepping allocates nothing
        beyond the integrator's temporaries)."""
        commands = torch.as_tensor(commands, device=self.device, dtype=self.dtype)
        if self.check_inputs:
            if commands.shape != (self.num_envs, S.NUM_CONTROLS):
                raise ValueError(f"commands must have shape ({self.num_envs}, {S.NUM_CONTROLS}) "
                                 f"[elevator, aileron, rudder, throttle], got {tuple(commands.shape)}")
            if not torch.isfinite(commands).all():
                bad = (~torch.isfinite(commands)).any(-1).nonzero().flatten().tolist()
                raise ValueError(f"commands contain NaN or Inf for envs {bad[:10]}")
        torch.clamp(commands.detach(), -1.0, 1.0, out=self.command)  # the step is not differentiable
        if self.turbulence is not None and self.backend != "warp":  # warp: inside the step kernel
            self.advance_turbulence()
        self._engine.step()  # advances x and time (on warp both inside the step kernel)

    def advance_turbulence(self) -> None:
        """Advance the Dryden filters once (torch) at the current height and mean-air airspeed and
        write the gusts that act over the coming step into ``gust_velocity_body`` / ``gust_rate_body``."""
        turb = self.turbulence
        assert turb is not None
        if not turb.external_noise:
            turb.noise.normal_(generator=self.generator)
        x = self.x
        v_air = x[:, S.VELOCITY] - ned_to_body(x[:, S.QUATERNION], self.wind_ned)
        airspeed = torch.linalg.vector_norm(v_air, dim=-1)
        filt, gust_v, gust_w = dryden_step(turb.filter, turb.noise, self.gust_velocity_body, turb.w20,
                                           -x[:, 2], airspeed, self.params.span, self.dt)
        turb.filter.copy_(filt)
        self.gust_velocity_body.copy_(gust_v)
        self.gust_rate_body.copy_(gust_w)

    def reseed(self, seed: int) -> None:
        """Reseed the generator and the Warp turbulence streams."""
        self.generator.manual_seed(int(seed))
        if self.turbulence is not None:
            self.turbulence.reseed(int(seed))

    def advance_torch(self, x: torch.Tensor, command: torch.Tensor) -> torch.Tensor:
        """One torch integration step of x [N, S] (not in place); used by engines and MPPI."""
        air = self.air

        def f(xx: torch.Tensor) -> torch.Tensor:
            return derivative(xx, command, self.params, air)

        return project(INTEGRATORS[self.integrator](f, x, self.dt), self.params)

    @property
    def state(self) -> TensorDict:
        """Named fields of the current state (clones), batch [N]. On the warp backend the derived
        quantities (air data, forces' coefficients, thrust, contact) come from one kernel launch."""
        x = self.x
        q = x[:, S.QUATERNION]
        derived = self._engine.derived_state() if self.backend == "warp" else self._torch_derived()
        euler = derived.pop("euler") if "euler" in derived else quaternion_to_euler(q)
        return TensorDict(
            {
                "position_ned": x[:, S.POSITION].clone(),
                "quaternion": q.clone(),
                "euler": euler,
                "velocity_body": x[:, S.VELOCITY].clone(),
                "angular_rate_body": x[:, S.ANGULAR_RATE].clone(),
                "surface_rate": x[:, S.SURFACE_RATE].clone(),
                "throttle": x[:, self.layout.throttle].clone(),
                "command": self.command.clone(),
                "time": self.time.clone(),
                "gust_velocity_body": self.gust_velocity_body.clone(),
                "gust_rate_body": self.gust_rate_body.clone(),
                **derived,
            },
            batch_size=[self.num_envs],
            device=self.device,
        )

    def _torch_derived(self) -> dict[str, torch.Tensor]:
        ev = evaluate(self.x, self.params, self.air)
        return {
            "velocity_ned": (ev.rotation @ self.x[:, S.VELOCITY].unsqueeze(-1)).squeeze(-1),
            "airspeed": ev.airspeed,
            "alpha": ev.alpha,
            "beta": ev.beta,
            "height": ev.height,
            "wing_height": ev.wing_height,
            "surface_position": ev.surfaces,
            "thrust": ev.thrust.sum(-1),
            "aero_coefficients": ev.coefficients,
            "ground_contact": ground_contact(ev, self.params),
        }


class _TorchEngine:
    """Steps ``sim.x`` with the torch model; ``step`` advances the state and the clock by dt."""

    def __init__(self, sim: Simulator):
        self.sim = sim

    def step(self) -> None:
        self.advance()
        self.sim.time += self.sim.dt

    def advance(self) -> None:
        sim = self.sim
        sim.x.copy_(sim.advance_torch(sim.x, sim.command))

    def after_reset(self, mask: torch.Tensor | None) -> None:
        pass


class _CompiledTorchEngine(_TorchEngine):
    """The torch step through ``torch.compile`` (graph re-traced when dt or the integrator change)."""

    def __init__(self, sim: Simulator):
        super().__init__(sim)
        monomial_plan(sim.params.aero_exponents)  # warm the plan cache outside the graph
        self._compiled = torch.compile(sim.advance_torch, dynamic=False)

    def advance(self) -> None:
        sim = self.sim
        sim.x.copy_(self._compiled(sim.x, sim.command))


class _ScipyEngine(_TorchEngine):
    """Reference: ``solve_ivp`` (RK45, rtol 1e-10, atol 1e-10) over each step, float64."""

    def advance(self) -> None:
        import numpy as np
        from scipy.integrate import solve_ivp

        sim = self.sim
        command = sim.command.clone()
        air = sim.air

        def f(_t: float, y: np.ndarray) -> np.ndarray:
            xx = torch.from_numpy(y).reshape(1, -1)
            return derivative(xx, command, sim.params, air).reshape(-1).numpy()

        sol = solve_ivp(f, (0.0, sim.dt), sim.x[0].numpy(), method="RK45", rtol=1e-10, atol=1e-10)
        if not sol.success:
            raise RuntimeError(f"solve_ivp failed: {sol.message}")
        y = torch.from_numpy(sol.y[:, -1]).reshape(1, -1)
        sim.x.copy_(project(y, sim.params))


def _make_engine(sim: Simulator) -> _TorchEngine:
    if sim.backend == "scipy":
        return _ScipyEngine(sim)
    if sim.backend == "warp":
        from .warp_backend import WarpEngine

        return WarpEngine(sim)
    return _CompiledTorchEngine(sim) if sim.compile else _TorchEngine(sim)
