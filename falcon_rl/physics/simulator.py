"""Simulator: the backend-agnostic facade used by envs, controllers and tools.

    sim = Simulator(load_airframe("navion"), num_envs=1024)
    sim.reset()                      # trimmed level flight at cruise, 100 m
    sim.step(commands)               # commands [N, 4] in [-1, 1]: elevator, aileron, rudder, throttle
    sim.step(commands, substeps=5)   # five steps of dt under the same commands, inside the engine
    td = sim.state                   # TensorDict of named fields, batch [N]: td["height"], ...

The facade checks inputs, composes initial states and names the outputs; an engine
(``engine.ENGINES[backend]``) owns the buffers and does the stepping. State lives in the engine's
preallocated tensors updated in place; ``state`` returns clones.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import torch
from tensordict import TensorDict

from ..airframe import Airframe, load_airframe
from . import state as S
from .backends import ENGINES, engine_class
from .derived import split_derived
from .dynamics import AirInputs
from .engine import Engine, EngineSetup
from .ground_effect import GE_MODES
from .integrators import INTEGRATORS
from .params import ModelParams, build_params
from .rotations import euler_to_quaternion
from .sea import SeaState, SeaSurface
from .state import MAX_RESET_POSITION, MAX_RESET_RATE, MAX_RESET_SPEED, MIN_QUATERNION_NORM
from .switches import ModelSwitches, switch_flags
from .trim import trim_level
from .wind import Turbulence, TurbulenceConfig, steady_wind, turbulence_config

BACKENDS = tuple(ENGINES)
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
        stop_at_ground: crash state: an env whose centre of gravity goes below the ground stops
            there (height 0, zero velocity and body rates) and stays stopped, flagged in
            ``crashed`` / ``state["crashed"]``, until its next reset; nothing flies underground.
            Off (False) lets the state integrate through the ground (e.g. for a planner's model).
        check_inputs: raise on malformed or non-finite commands (costs a host sync on CUDA).
        warp_cpu_threads: threads that step a warp-backend batch on the CPU (None: one per
            available core, at most one per 512 envs); ignored by the other backends and on CUDA.
        model: which form of each phenomenon to simulate: None (the full model), a
            :class:`~falcon_rl.physics.switches.ModelSwitches` or a mapping of its fields, e.g.
            ``{"actuators": "ideal", "rate_damping": False}``; per env (rows of ``params``), change
            a subset with :meth:`set_model`.
        compile: torch backend only: step through ``torch.compile`` of the integration step (one
            fused graph instead of ~1,000 small kernels per RK4 step; the first steps compile it,
            tens of seconds on a CPU).
        sea: fly every env over a sea: a WMO sea-state code 0-6 or a :class:`~falcon_rl.physics.sea.SeaState`
            (a wave field per env drawn from this simulator's generator, ``set_sea``; the model switch
            ``surface="sea"``), or None (the flat ground, unless ``model`` says ``surface="sea"``: a calm
            sea).
        sea_components: Airy components of each env's wave field (>= 64).
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
        model: ModelSwitches | Mapping[str, Any] | None = None,
        stop_at_ground: bool = True,
        sea: int | SeaState | None = None,
        sea_components: int = 64,
    ):
        if isinstance(airframe, str):
            airframe = load_airframe(airframe)
        if integrator not in INTEGRATORS:
            raise ValueError(f"integrator must be one of {list(INTEGRATORS)}, got {integrator!r}")
        if not num_envs >= 1:
            raise ValueError(f"num_envs must be >= 1, got {num_envs}")
        if not dt > 0:
            raise ValueError(f"dt must be > 0, got {dt}")
        if not (isinstance(sea_components, int) and sea_components >= 64):
            raise ValueError(f"sea_components must be an int >= 64, got {sea_components!r}")
        if warp_cpu_threads is not None and not warp_cpu_threads >= 1:
            raise ValueError(f"warp_cpu_threads must be None or >= 1, got {warp_cpu_threads}")
        engine_cls = engine_class(backend)
        options = {"compile": compile or None, "cpu_threads": warp_cpu_threads}
        options = {name: value for name, value in options.items() if value is not None}
        if compile and "compile" not in engine_cls.OPTIONS:
            raise ValueError(f"compile=True applies to the torch backend, not {backend!r}")
        device, dtype = engine_cls.placement(num_envs, torch.device(device), dtype)
        self.airframe = airframe
        self.num_envs = num_envs
        self.backend = backend
        self.device = device
        self.dtype = dtype
        self.check_inputs = check_inputs
        self.layout = S.StateLayout(airframe.num_motors)
        params = build_params(airframe, num_envs, device, dtype, ground_effect,
                              switches=ModelSwitches.from_spec(model))
        self.engine: Engine = engine_cls(EngineSetup(
            airframe=airframe, params=params, num_envs=num_envs, device=device, dtype=dtype, dt=float(dt),
            integrator=integrator, turbulence=turbulence_config(turbulence), seed=seed,
            options={k: v for k, v in options.items() if k in engine_cls.OPTIONS},
            sea_components=sea_components))
        if wind is not None:
            self.wind_ned[:] = steady_wind(wind, num_envs, dtype, device)
        self.stop_at_ground = bool(stop_at_ground)
        self._default: torch.Tensor | None = None
        self._default_command: torch.Tensor | None = None
        if sea is not None:
            self.set_sea(sea)
        self.reset()

    # ------------------------------------------------------------------ the engine's buffers
    @property
    def x(self) -> torch.Tensor:
        """[N, S] integrated state (the engine's buffer, in place)."""
        return self.engine.x

    @property
    def command(self) -> torch.Tensor:
        """[N, 4] command held over the current step."""
        return self.engine.command

    @property
    def crashed(self) -> torch.Tensor:
        """[N] bool: envs stopped at the ground since their last reset (see ``stop_at_ground``)."""
        return self.engine.crashed

    @property
    def time(self) -> torch.Tensor:
        """[N] s since each env's reset."""
        return self.engine.time

    @property
    def wind_ned(self) -> torch.Tensor:
        """[N, 3] m/s steady wind (write in place)."""
        return self.engine.wind_ned

    @property
    def gust_velocity_body(self) -> torch.Tensor:
        """[N, 3] m/s Dryden gusts over the current step."""
        return self.engine.gust_velocity_body

    @property
    def gust_rate_body(self) -> torch.Tensor:
        """[N, 3] rad/s Dryden angular gusts over the current step."""
        return self.engine.gust_rate_body

    @property
    def params(self) -> ModelParams:
        """Per-env model parameters [N, ...] (write with ``params.assign``)."""
        return self.engine.params

    @params.setter
    def params(self, value: ModelParams) -> None:
        self.engine.params = value

    @property
    def turbulence(self) -> Turbulence | None:
        """The Dryden state (``filter`` [N, 8], ``w20`` [N], ...), or None when off."""
        return self.engine.turbulence

    @property
    def generator(self) -> torch.Generator:
        """This simulator's generator (torch Dryden noise)."""
        return self.engine.generator

    @property
    def dt(self) -> float:
        """Step length, s (settable: the engine re-binds on its next step)."""
        return self.engine.dt

    @dt.setter
    def dt(self, value: float) -> None:
        if not value > 0:
            raise ValueError(f"dt must be > 0, got {value}")
        self.engine.dt = float(value)

    @property
    def integrator(self) -> str:
        """"rk4" or "euler" (the scipy backend integrates with solve_ivp)."""
        return self.engine.integrator

    @integrator.setter
    def integrator(self, value: str) -> None:
        if value not in INTEGRATORS:
            raise ValueError(f"integrator must be one of {list(INTEGRATORS)}, got {value!r}")
        self.engine.integrator = value

    def set_model(self, mask: torch.Tensor | None = None, **switches: Any) -> None:
        """Set the named model switches (fields of ``ModelSwitches``, e.g. ``actuators="ideal"``) in
        the envs where ``mask`` [N] bool is True (all when None); the others keep theirs. Takes
        effect from the next step (the actuator states of newly ideal envs jump to the command then)."""
        mask = self._switch(mask, switches)
        if "surface" in switches:
            self.engine.sample_surface(mask)

    def _switch(self, mask: torch.Tensor | None, switches: dict[str, Any]) -> torch.Tensor:
        """Write the switches' parameter rows where ``mask`` [N] bool is True (all when None), sampling
        nothing; the mask as a [N] bool tensor."""
        flags = switch_flags(switches, switches)
        mask = torch.ones(self.num_envs, dtype=torch.bool, device=self.device) if mask is None else (
            torch.as_tensor(mask, device=self.device).reshape(self.num_envs).bool())
        self.params.assign(mask, **{name: torch.tensor(value) for name, value in flags.items()})
        return mask

    def set_sea(self, sea: int | SeaState | None, mask: torch.Tensor | None = None) -> None:
        """Fly the envs of ``mask`` [N] bool (all when None) over a new wave field of ``sea`` (a sea-state
        code 0-6 or a :class:`~falcon_rl.physics.sea.SeaState`), drawn from this simulator's generator (the
        same draws whatever the mask), or over the flat ground (None); their surface is sampled at once.
        Other envs keep theirs."""
        if mask is not None:
            mask = torch.as_tensor(mask, device=self.device).reshape(self.num_envs).bool()
        if sea is None:
            self.set_model(mask, surface="flat")
            return
        state = sea if isinstance(sea, SeaState) else SeaState.from_code(sea)
        self._switch(mask, {"surface": "sea"})
        self.engine.draw_sea(state, self.generator, mask)  # samples the rows' surface once

    def set_sea_field(self, field: SeaSurface, mask: torch.Tensor | None = None) -> None:
        """Fly the envs of ``mask`` [N] bool (all when None) over the given wave fields (``field``, [N, K]
        each, K this simulator's ``sea_components``; e.g. another simulator's rows, for a planner), their
        surface sampled at once. Other envs keep theirs."""
        if mask is not None:
            mask = torch.as_tensor(mask, device=self.device).reshape(self.num_envs).bool()
        self._switch(mask, {"surface": "sea"})
        self.engine.copy_sea(field, mask)  # samples the rows' surface once

    def sample_surface(self, mask: torch.Tensor | None = None) -> None:
        """Sample the surface under the envs of ``mask`` [N] bool (all when None) at their current state and
        clock into :attr:`surface`: for a host that wrote :attr:`x` or :attr:`time` itself (a reset and a
        step sample it already)."""
        self.engine.sample_surface(mask)

    def ensure_sea(self) -> SeaSurface:
        """The envs' wave fields, allocated calm (zero amplitudes, nothing drawn) when none exist yet; the
        tensors stay in place from then on (for a reader that binds them before the first sea is drawn)."""
        return self.engine.ensure_sea()

    @property
    def sea(self) -> SeaSurface | None:
        """The envs' wave fields (``SeaSurface``, [N, K] each; rows of envs over the ground unused), or None
        before any sea was drawn."""
        return self.engine.sea

    @property
    def surface(self) -> torch.Tensor:
        """[N, SURFACE_WIDTH] the surface under each aircraft (``surface.SURFACE_FIELDS``; the engine's
        buffer)."""
        return self.engine.surface

    # ------------------------------------------------------------------ state
    @property
    def air(self) -> AirInputs:
        """Wind and gusts as the dynamics sees them (views of the engine's buffers)."""
        return self.engine.air

    def default_initial(self) -> tuple[torch.Tensor, torch.Tensor]:
        """(state [S], command [4]) of trimmed level flight at cruise speed and 100 m."""
        if self._default is None:
            ge = int(self.params.ground_effect_mode[0])
            mode = {code: name for name, code in GE_MODES.items()}[ge]
            trim = trim_level(self.airframe, self.airframe.envelope.cruise_speed, DEFAULT_HEIGHT,
                              ground_effect=mode)
            self._default = trim.state[0].to(self.device, self.dtype)
            self._default_command = trim.commands[0].to(self.device, self.dtype)
        assert self._default_command is not None
        return self._default, self._default_command

    def reset(self, initial: Mapping[str, torch.Tensor] | torch.Tensor | None = None,
              mask: torch.Tensor | None = None, publish: bool = True) -> TensorDict | None:
        """Reset the envs selected by ``mask`` [N] bool (all when None); returns :attr:`state`, or None
        with ``publish=False`` (a caller that reads the buffers instead: the state is not built).

        ``initial`` is a full state tensor [N, S] / [S], or a mapping of named fields
        (position_ned, quaternion or euler, velocity_body, angular_rate_body, surface_position,
        throttle, command), each [N, ...] or broadcastable; missing fields come from trimmed
        cruise at 100 m. Rows outside the mask are never touched.
        """
        n = self.num_envs
        base, base_cmd = self.default_initial()
        new_x = base.expand(n, -1).clone()
        new_cmd = base_cmd.expand(n, -1).clone()
        if mask is not None:
            mask = torch.as_tensor(mask, device=self.device)
            if mask.numel() != n:
                raise ValueError(f"reset mask must have {n} entries, got shape {list(mask.shape)}")
            mask = mask.reshape(n).bool()
        if isinstance(initial, torch.Tensor):
            if initial.shape not in ((n, self.layout.size), (self.layout.size,)):
                raise ValueError(f"initial state must have shape [{n}, {self.layout.size}] or "
                                 f"[{self.layout.size}], got {list(initial.shape)}")
            new_x[:] = initial.to(self.device, self.dtype)
        elif initial is not None:
            new_x, new_cmd = self._compose_initial(initial, new_x, new_cmd)
        derived = self.engine.start(new_x, new_cmd, mask,
                                    check=lambda: self._check_initial(new_x, new_cmd, mask), derive=publish)
        return self.state_and_derived(derived)[0] if publish else None

    def _check_initial(self, x: torch.Tensor, command: torch.Tensor, mask: torch.Tensor | None) -> None:
        """ValueError (one line) unless the reset rows of ``x`` [N, S] and ``command`` [N, 4] are
        finite, have a quaternion that normalises into an attitude, lie in the physical ranges
        (``MAX_RESET_*``, height above the ground or the water under it) and command within [-1, 1]. Rows
        outside ``mask`` are not read."""
        rows = torch.arange(self.num_envs, device=self.device) if mask is None else mask.nonzero().flatten()
        floor = self._water_under(x)[rows]
        x, command = x[rows], command[rows]
        speed = torch.linalg.vector_norm(x[:, S.VELOCITY], dim=-1)
        checks = (
            ("state contains NaN or Inf", ~torch.isfinite(x).all(-1)),
            ("command contains NaN or Inf", ~torch.isfinite(command).all(-1)),
            ("command outside [-1, 1]", (command.abs() > 1.0).any(-1)),
            (f"quaternion has norm below {MIN_QUATERNION_NORM} (no attitude)",
             torch.linalg.vector_norm(x[:, S.QUATERNION], dim=-1) < MIN_QUATERNION_NORM),
            (f"position beyond {MAX_RESET_POSITION:g} m",
             (x[:, S.POSITION].abs() > MAX_RESET_POSITION).any(-1)),
            ("height below the surface (the ground at 0 m, or the water under it)", S.height(x) < floor),
            (f"speed above {MAX_RESET_SPEED:g} m/s", speed > MAX_RESET_SPEED),
            (f"body rate above {MAX_RESET_RATE:g} rad/s",
             (x[:, S.ANGULAR_RATE].abs() > MAX_RESET_RATE).any(-1)),
        )
        if not bool(torch.stack([bad for _, bad in checks]).any()):  # one host sync when all is well
            return
        for what, bad in checks:
            if bool(bad.any()):
                envs = rows[bad].tolist()
                raise ValueError(f"initial {what} for envs {envs[:10]}{' ...' if len(envs) > 10 else ''}")

    def _water_under(self, x: torch.Tensor) -> torch.Tensor:
        """[N] the elevation (m) at a reset (clock 0) of the water under the CG of state x [N, S] of the envs
        over their sea, 0 over the ground (non-finite positions give 0: the finiteness check names them)."""
        sea, flags = self.sea, self.params.sea_surface != 0
        if sea is None or not bool(flags.any()):
            return torch.zeros(x.shape[0], device=x.device, dtype=x.dtype)
        position = torch.nan_to_num(x[:, S.POSITION], nan=0.0, posinf=0.0, neginf=0.0)
        north, east = (position[:, k].to(sea.amplitude.dtype) for k in (0, 1))
        eta = sea.elevation(north, east, 0.0)
        return torch.where(flags, eta.to(x.dtype), 0.0)

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
            x[:, S.DOWN_INDEX] = -val("height")
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
            x[:, self.layout.throttle] = self._throttle_rows(val("throttle"))
        if "command" in initial:
            cmd[:] = val("command")
        return x, cmd

    def _throttle_rows(self, throttle: torch.Tensor) -> torch.Tensor:
        """Initial throttle states as [N, M]: from [M] (one row for all envs), [N, M], or, with one
        motor only, [N] (one value per env) or a scalar."""
        n, m = self.num_envs, self.airframe.num_motors
        if throttle.dim() == 0:
            throttle = throttle.expand(m)
        if throttle.dim() == 1 and throttle.shape[0] == m:
            return throttle.expand(n, m)
        if throttle.dim() == 1 and m == 1 and throttle.shape[0] == n:
            return throttle.unsqueeze(-1)
        if throttle.dim() == 2 and throttle.shape[-1] == m and throttle.shape[0] in (1, n):
            return throttle.expand(n, m)
        raise ValueError(f"initial throttle must be [{m}] or [{n}, {m}] for {self.airframe.name!r} "
                         f"({m} motor{'s' if m > 1 else ''}), got {list(throttle.shape)}")

    # ------------------------------------------------------------------ stepping
    def step(self, commands: torch.Tensor, substeps: int = 1) -> None:
        """Advance all envs by ``substeps`` x dt under ``commands`` [N, 4] in [-1, 1] (clipped, held
        over the sub-steps, which run inside the engine).

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
            if not (isinstance(substeps, int) and substeps >= 1):
                raise ValueError(f"substeps must be an int >= 1, got {substeps!r}")
        self.engine.step(commands, substeps, self.stop_at_ground)

    def reseed(self, seed: int) -> None:
        """Reseed the generator and the turbulence noise streams."""
        self.engine.reseed(seed)

    @property
    def state(self) -> TensorDict:
        """Named fields of the current state (clones), batch [N]; the derived quantities (air data,
        coefficients, thrust, contact, Euler angles) and the diagnostics (aero force and moment, thrust
        per motor [N, M], ground-effect h/b and factors) come from the engine
        (``derived.DERIVED_FIELDS``, on warp one kernel launch)."""
        return self.state_and_derived()[0]

    def state_and_derived(self, derived: torch.Tensor | None = None) -> tuple[TensorDict, torch.Tensor]:
        """(:attr:`state`, the [N, DERIVED_WIDTH] derived columns its derived fields are views of);
        ``derived``: the engine's derived state of the current x when the caller has it already
        (``Engine.start``), else it is evaluated."""
        x = self.x.clone()  # one copy; the fields are views of it (and of one copy of the derived state)
        columns = (self.engine.derived() if derived is None else derived).clone()
        derived = split_derived(columns, copy=False)
        # Every entry is an [N, ...] tensor of this simulator's device by construction: the unchecked
        # constructor skips TensorDict's per-entry validation (~0.15 ms of a one-env state).
        return TensorDict._new_unsafe(
            {
                "position_ned": x[:, S.POSITION],
                "quaternion": x[:, S.QUATERNION],
                "velocity_body": x[:, S.VELOCITY],
                "angular_rate_body": x[:, S.ANGULAR_RATE],
                "surface_rate": x[:, S.SURFACE_RATE],
                "throttle": x[:, self.layout.throttle],
                "command": self.command.clone(),
                "time": self.time.clone(),
                "gust_velocity_body": self.gust_velocity_body.clone(),
                "gust_rate_body": self.gust_rate_body.clone(),
                "crashed": self.crashed.clone(),
                **derived,
                "motor_thrust": derived["motor_thrust"][:, :self.airframe.num_motors],
            },
            batch_size=[self.num_envs],
            device=self.device,
        ), columns
