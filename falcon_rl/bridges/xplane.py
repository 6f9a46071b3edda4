"""The X-Plane bridge: fly a falcon-rl controller (LQR, MPPI, trim, a PPO policy) around X-Plane's aircraft
over X-Plane's native UDP interface (port 49000): read the state by RREF subscriptions, write elevator,
aileron, rudder and throttle by DREF each control step.

    with XPlaneBridge(port=49000, task="altitude", airframe="volantex_ranger", controller="lqr") as bridge:
        result = bridge.fly()            # BridgeResult: recording, metrics, packet counts
    result.recording.save("xplane.npz")

How the controller sees X-Plane: the bridge keeps a one-env :class:`~falcon_rl.envs.FixedWingEnv` of the
task as a *shadow*. Its reset draws the episode (e.g. the commanded altitude) and the initial condition,
which the bridge gives X-Plane (VEHS placement, then DREF writes of ``local_vx/vy/vz`` and ``P/Q/R``).
Each control step then runs what the env's step runs, with X-Plane in place of the physics:

1. the controller reads the shadow's output (observation, ("state", ...), ("task", ...)) and acts;
2. the task turns the action into the [4] command (trim in the channels it does not drive), written to
   X-Plane as yoke ratios and throttle (below);
3. the shadow's simulator steps the same command for ``decimation`` physics steps: its actuator states
   (surface deflections, throttle lag) are the bridge's model of the surfaces, which X-Plane does not
   publish uniformly;
4. the next X-Plane state is read (RREF) and written over the shadow's rigid-body state (position,
   attitude, velocity, body rates) in the simulator's buffer ``Simulator.x``, so that the air data, the
   task's observation, reward and terminations are computed from X-Plane's aircraft exactly as the env
   computes them from its own (``Simulator.state``, ``Task.step``).

Frames and units: position NED about ``reference`` (:class:`~falcon_rl.viz.geodesy.ReferencePoint`,
exact WGS-84): down from latitude, longitude and elevation (m MSL; the height is the elevation above the
reference altitude), north and east from X-Plane's ``local_z`` (south) and ``local_x`` (east), which
RREF's float32 carries to millimetres where latitude and longitude resolve only ~0.4 m, anchored at the
placement; attitude from phi, theta, psi (deg, ZYX); velocity from ``local_vx`` (east), ``local_vy``
(up), ``local_vz`` (south), m/s, rotated into the body frame; body rates from P, Q, R (deg/s).

Controls: falcon-rl's normalised command c in [-1, 1] (positive elevator pitches the nose down, positive
aileron rolls right, positive rudder yaws left, as every shipped airframe's derivatives have it) maps to
``yoke_pitch_ratio = -c_e`` (+1 pulls), ``yoke_roll_ratio = c_a``, ``yoke_heading_ratio = -c_r`` and
``throttle_ratio_all = (c_t + 1) / 2``; ``override_joystick`` is set while the bridge flies and cleared
when it closes. The ratios move X-Plane's own aircraft through its own throws: load an aircraft in
X-Plane whose size and speed match ``airframe`` (the controller is tuned for falcon-rl's model of it).

Pacing: ``"lockstep"`` waits after each command for a state whose ``sim/time/total_running_time_sec``
has advanced (the stand-in's lockstep mode steps one control period per command: deterministic and as
fast as the CPU); ``"wallclock"`` runs a control step every ``control_dt`` of wall-clock time on the
newest state (real X-Plane, or the stand-in's realtime mode).

Robustness: packets that are short, long, garbage, of another protocol or from another address are
dropped and counted (:class:`PacketCounts`), never raised; no state within ``timeout`` seconds raises
:class:`XPlaneTimeout` before the flight starts, and ends the flight with status "timeout" during it (the
result keeps what was flown). The socket binds to loopback unless ``bind`` says otherwise; it is closed,
and the subscriptions and the joystick override are released, on exit.
"""

from __future__ import annotations

import math
import socket
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch
from tensordict import TensorDict, TensorDictBase

from ..defaults import DEFAULT_AIRFRAME, DEFAULT_BACKEND
from ..envs import STATE_KEYS, FixedWingEnv, make_env
from ..envs.layout import column
from ..envs.tasks import TERMINATION_REASONS
from ..evaluation.controllers import make_controller
from ..evaluation.metrics import altitude_metrics, attitude_metrics, summarize
from ..evaluation.tracking_metrics import climb_descend_metrics, path_following_metrics, trajectory_metrics
from ..physics import state as S
from ..physics.rotations import euler_to_quaternion, ned_to_body
from ..recording import Recording, RecordingBuilder, state_frame
from ..viz.geodesy import DEFAULT_REFERENCE, ReferencePoint, geodetic_to_ned, ned_to_geodetic
from . import xplane_protocol as P

#: The loopback address every socket binds to by default.
LOOPBACK = "127.0.0.1"
#: X-Plane yoke ratio = sign x falcon-rl command, for elevator, aileron, rudder (see the module docstring).
CONTROL_SIGNS: tuple[float, float, float] = (-1.0, 1.0, -1.0)
#: Placement confirmed once X-Plane's elevation is this close to the commanded one, m.
PLACEMENT_TOLERANCE_M = 0.5
#: Per-task episode metrics {name: [N]} of a rollout [N, T] (the protocols' own functions).
TASK_METRICS: dict[str, Callable[[TensorDictBase], dict[str, torch.Tensor]]] = {
    "altitude": altitude_metrics, "climb_descend": climb_descend_metrics, "attitude": attitude_metrics,
    "path_following": path_following_metrics, "trajectory": trajectory_metrics}
_MAX_DATAGRAM = 65_535


class XPlaneTimeout(TimeoutError):  # noqa: N818 (a TimeoutError, named for what it is)
    """No usable X-Plane state arrived in time (the message names the address and what was awaited)."""


@dataclass
class PacketCounts:
    """UDP packets: received, accepted, dropped as malformed (short, long, garbage, non-finite) or
    foreign (another protocol, message, aircraft or sender), and sent."""

    received: int = 0
    accepted: int = 0
    malformed: int = 0
    foreign: int = 0
    sent: int = 0

    @property
    def dropped(self) -> int:
        """Packets dropped, malformed or foreign."""
        return self.malformed + self.foreign

    def as_dict(self) -> dict[str, int]:
        """The counts as a JSON-able dict (with ``dropped``)."""
        return {"received": self.received, "accepted": self.accepted, "malformed": self.malformed,
                "foreign": self.foreign, "dropped": self.dropped, "sent": self.sent}


@dataclass
class BridgeResult:
    """What one flight through X-Plane gave: the log, the task's metrics and how the link behaved."""

    #: time [T] s (the shadow's task clock), the state read from X-Plane, commands, actions, references;
    #: ``xplane/values`` [T, 1, K] holds the raw dataref values (``meta["xplane_datarefs"]``).
    recording: Recording
    #: The task's protocol metrics over the flight (e.g. altitude: survival, acquisition, rmse m,
    #: time_in_band, settling_time s, overshoot m); angles in rad.
    metrics: dict[str, float]
    #: "completed" (the horizon), "terminated" (a termination reason) or "timeout".
    status: str
    termination_reason: str
    steps: int
    seconds_flown: float
    control_dt: float
    packets: dict[str, int]
    wall_seconds: float = 0.0
    settings: dict[str, Any] = field(default_factory=dict)

    def document(self) -> dict[str, Any]:
        """A JSON-able summary (no arrays)."""
        return {"status": self.status, "termination_reason": self.termination_reason, "steps": self.steps,
                "seconds_flown": self.seconds_flown, "control_dt": self.control_dt,
                "wall_seconds": self.wall_seconds, "metrics": self.metrics, "packets": self.packets,
                "settings": self.settings}


def controls_to_xplane(command: torch.Tensor | list[float]) -> tuple[float, float, float, float]:
    """Normalised command [4] (elevator, aileron, rudder, throttle in [-1, 1]) -> X-Plane's (yoke pitch,
    roll, heading ratios in [-1, 1], throttle ratio in [0, 1])."""
    c = [max(-1.0, min(1.0, float(v))) for v in command]
    return (CONTROL_SIGNS[0] * c[0], CONTROL_SIGNS[1] * c[1], CONTROL_SIGNS[2] * c[2], 0.5 * (c[3] + 1.0))


class XPlaneBridge:
    """Fly ``controller`` on ``task`` around the aircraft of the X-Plane at ``host:port`` (see the module
    docstring).

    Args:
        host, port: X-Plane's address (its UDP port, 49000 by default).
        task, airframe, controller: the shadow env's task and airframe, and the controller
            (``make_controller``: a baseline of the task, "ppo" or a policy file).
        seconds: flight length, s (None: the task's episode horizon).
        seed: the shadow env's seed (draws the episode).
        backend: the shadow simulator's backend. decimation: physics steps of 10 ms per control step
            (None: the task's default, 5: 20 Hz).
        pacing: "lockstep" or "wallclock". timeout: s to wait for a state.
        bind: local address of the socket (loopback by default; "0.0.0.0" to reach another machine).
        reference: geodetic position of the NED origin. frequency: RREF replies/s asked of X-Plane
            (None: twice the control rate).
        env_options: further ``make_env`` options of the shadow (task config fields, ground_effect...).
    """

    def __init__(self, host: str = LOOPBACK, port: int = P.XPLANE_PORT, *, task: str = "altitude",
                 airframe: str = DEFAULT_AIRFRAME, controller: str = "lqr", seconds: float | None = None,
                 seed: int = 0, backend: str = DEFAULT_BACKEND, decimation: int | None = None,
                 pacing: str = "lockstep",
                 timeout: float = 2.0, bind: str = LOOPBACK, reference: ReferencePoint | None = None,
                 frequency: int | None = None, env_options: dict[str, Any] | None = None) -> None:
        if pacing not in ("lockstep", "wallclock"):
            raise ValueError(f"pacing must be 'lockstep' or 'wallclock', got {pacing!r}")
        if not 0 < port < 65536:
            raise ValueError(f"port must be in [1, 65535], got {port}")
        if not (timeout > 0 and math.isfinite(timeout)):
            raise ValueError(f"timeout must be > 0 s, got {timeout}")
        self.pacing = pacing
        self.timeout = float(timeout)
        self.reference = reference or DEFAULT_REFERENCE
        options = dict(env_options or {})
        if decimation is not None:
            options["decimation"] = decimation
        if seconds is not None:
            options["episode_seconds"] = float(seconds)
        env = make_env(task, airframe, num_envs=1, backend=backend, seed=seed, **options)
        if not isinstance(env, FixedWingEnv):
            raise ValueError("the bridge's shadow env takes no transforms (sensors, delays, randomisation)")
        self.env = env
        self.task_name = task
        self.controller_name = controller
        self.policy = make_controller(controller, env)
        self.control_dt = float(env.control_dt)
        self.frequency = int(frequency or min(P.MAX_RREF_FREQUENCY, max(1, math.ceil(2.0 / self.control_dt))))
        self.counts = PacketCounts()
        self._values: dict[int, float] = {}
        self._anchor: tuple[np.ndarray, float, float] | None = None
        target = socket.getaddrinfo(host, port, socket.AF_INET, socket.SOCK_DGRAM)[0][4]
        self.address: tuple[str, int] = (str(target[0]), int(target[1]))
        self._socket = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            self._socket.bind((bind, 0))
        except OSError:
            self._socket.close()
            raise
        self._open = True

    # ------------------------------------------------------------------ lifetime
    def close(self) -> None:
        """Release the joystick override and the subscriptions, then close the socket; idempotent."""
        if not self._open:
            return
        self._open = False
        try:
            self._send(P.encode_dref(P.OVERRIDE_JOYSTICK, 0.0))
            for index, dataref in enumerate(P.STATE_DATAREFS):
                self._send(P.encode_rref_request(0, index, dataref))
        finally:
            self._socket.close()

    def __enter__(self) -> XPlaneBridge:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------------ packets
    def _send(self, packet: bytes) -> None:
        try:
            self._socket.sendto(packet, self.address)
            self.counts.sent += 1
        except OSError:  # nobody listening yet (ICMP port unreachable): the timeout reports it
            pass

    def _receive(self, deadline: float) -> bool:
        """Read one packet before ``deadline`` (perf_counter s) into the latest values; True when one
        was accepted."""
        remaining = deadline - time.perf_counter()
        if remaining <= 0:
            return False
        self._socket.settimeout(remaining)
        try:
            packet, sender = self._socket.recvfrom(_MAX_DATAGRAM)
        except TimeoutError:
            return False
        except OSError:  # e.g. ICMP port unreachable surfacing on Linux: nobody at the address yet
            time.sleep(min(0.01, max(0.0, deadline - time.perf_counter())))
            return False
        self.counts.received += 1
        if (str(sender[0]), int(sender[1])) != self.address or packet[:4] != b"RREF":
            self.counts.foreign += 1
            return False
        try:
            pairs = P.decode_rref_reply(packet)
        except P.XPlanePacketError:
            self.counts.malformed += 1
            return False
        self.counts.accepted += 1
        for index, value in pairs:
            if index < len(P.STATE_DATAREFS):
                self._values[index] = value
        return True

    def _wait(self, ready: Callable[[dict[str, float]], bool], what: str, deadline: float | None = None
              ) -> dict[str, float]:
        """Read packets until ``ready(values)`` holds for a complete set of values; XPlaneTimeout after
        ``timeout`` s (or at ``deadline``)."""
        deadline = time.perf_counter() + self.timeout if deadline is None else deadline
        while True:
            values = self._named()
            if values is not None and ready(values):
                return values
            if not self._receive(deadline) and time.perf_counter() >= deadline:
                raise XPlaneTimeout(f"no {what} from X-Plane at {self.address[0]}:{self.address[1]} within "
                                    f"{self.timeout:g} s (is it running, with its UDP port there?)")

    def _named(self) -> dict[str, float] | None:
        if len(self._values) < len(P.STATE_DATAREFS):
            return None
        return {dataref: self._values[i] for i, dataref in enumerate(P.STATE_DATAREFS)}

    # ------------------------------------------------------------------ frames
    def _ned(self, values: dict[str, float]) -> np.ndarray:
        """NED position [3] m of X-Plane's aircraft (see the module docstring)."""
        geodetic = np.asarray(geodetic_to_ned(self.reference, values[P.LATITUDE], values[P.LONGITUDE],
                                              values[P.ELEVATION]), dtype=np.float64).reshape(3)
        if self._anchor is None:
            return geodetic
        origin, x0, z0 = self._anchor
        return np.array([origin[0] - (values[P.LOCAL_Z] - z0), origin[1] + (values[P.LOCAL_X] - x0),
                         geodetic[2]])

    def _write_state(self, values: dict[str, float]) -> None:
        """Overwrite the shadow simulator's rigid-body state with X-Plane's."""
        sim = self.env.sim
        dtype, device = sim.dtype, sim.device
        euler = torch.tensor([[math.radians(values[P.PHI]), math.radians(values[P.THETA]),
                               math.radians(values[P.PSI])]], dtype=torch.float64)
        q = euler_to_quaternion(euler)
        v_ned = torch.tensor([P.ned_velocity_from_local(values[P.LOCAL_VX], values[P.LOCAL_VY],
                                                        values[P.LOCAL_VZ])], dtype=torch.float64)
        rates = torch.tensor([[math.radians(values[P.ROLL_RATE]), math.radians(values[P.PITCH_RATE]),
                               math.radians(values[P.YAW_RATE])]], dtype=torch.float64)
        x = sim.x
        x[:, S.POSITION] = torch.as_tensor(self._ned(values), dtype=dtype, device=device).reshape(1, 3)
        x[:, S.QUATERNION] = q.to(device, dtype)
        x[:, S.VELOCITY] = ned_to_body(q, v_ned).to(device, dtype)
        x[:, S.ANGULAR_RATE] = rates.to(device, dtype)

    def _output(self, observation: torch.Tensor, state: TensorDictBase, reason: int, truncated: bool
                ) -> TensorDict:
        """The env's output layout for the controller and the metrics (batch [1])."""
        terminated = reason > 0
        flags = {"terminated": terminated, "truncated": truncated and not terminated,
                 "done": terminated or truncated}
        return TensorDict({
            "observation": observation,
            "termination_reason": torch.tensor([[reason]], dtype=torch.long),
            "state": {key: column(state[key]) for key in STATE_KEYS},
            "task": {key: column(value) for key, value in self.env.task.info().items()},
            **{key: torch.tensor([[value]], dtype=torch.bool) for key, value in flags.items()},
        }, batch_size=[1])

    # ------------------------------------------------------------------ placement
    def _place(self, state: TensorDictBase) -> dict[str, float]:
        """Put X-Plane's aircraft at the shadow's reset state; returns the confirmed X-Plane state."""
        ned = state["position_ned"][0].double().numpy()
        lat, lon, ele = (float(v) for v in ned_to_geodetic(self.reference, ned))
        roll, pitch, yaw = (math.degrees(v) for v in state["euler"][0].tolist())
        vx, vy, vz = P.local_velocity_from_ned(*state["velocity_ned"][0].tolist())
        p, q, r = (math.degrees(v) for v in state["angular_rate_body"][0].tolist())
        self._send(P.encode_dref(P.OVERRIDE_JOYSTICK, 1.0))
        for index, dataref in enumerate(P.STATE_DATAREFS):
            self._send(P.encode_rref_request(self.frequency, index, dataref))
        self._send(P.encode_vehs(P.VehiclePlacement(0, lat, lon, ele, yaw % 360.0, pitch, roll)))
        for dataref, value in ((P.LOCAL_VX, vx), (P.LOCAL_VY, vy), (P.LOCAL_VZ, vz), (P.ROLL_RATE, p),
                               (P.PITCH_RATE, q), (P.YAW_RATE, r)):
            self._send(P.encode_dref(dataref, value))
        speed = math.sqrt(vx * vx + vy * vy + vz * vz)

        def placed(values: dict[str, float]) -> bool:
            moved = math.sqrt(sum(values[k] ** 2 for k in (P.LOCAL_VX, P.LOCAL_VY, P.LOCAL_VZ)))
            return abs(values[P.ELEVATION] - ele) < PLACEMENT_TOLERANCE_M and abs(moved - speed) < 1.0

        values = self._wait(placed, "state at the placement")
        if self.pacing == "lockstep":  # the state is the placement: anchor on the commanded position
            self._anchor = (ned, values[P.LOCAL_X], values[P.LOCAL_Z])
        else:
            self._anchor = (self._ned(values), values[P.LOCAL_X], values[P.LOCAL_Z])
        return values

    # ------------------------------------------------------------------ flight
    def fly(self) -> BridgeResult:
        """Place the aircraft, then fly the shadow's episode (its horizon) through X-Plane."""
        if not self._open:
            raise ValueError("the bridge is closed")
        env, task, sim = self.env, self.env.task, self.env.sim
        decimation = int(env.config.decimation)
        started = time.perf_counter()
        with torch.no_grad():
            observation, state = env.reset_tensors()
            values = self._place(state)
            self._write_state(values)
            state = sim.state
            observation = task.observe(state)
            td = self._output(observation, state, 0, False)
            builder = RecordingBuilder({
                "airframe": env.airframe.name, "dt": self.control_dt, "task": self.task_name,
                "controller": self.controller_name, "labels": ["X-Plane"], "source": "xplane",
                "termination_reasons": list(TERMINATION_REASONS), "xplane_datarefs": list(P.STATE_DATAREFS)})
            action = torch.zeros(1, task.action_dim, dtype=sim.dtype)
            self._record(builder, state, action, task.command_buffer, 0.0, 0, values)
            frames: list[TensorDict] = []
            last_time, status, reason = values[P.TIME], "completed", 0
            tick = time.perf_counter()
            for step in range(env.max_episode_steps):
                td = self.policy(td)
                action = td["action"].reshape(1, task.action_dim).to(sim.dtype)
                if not bool(torch.isfinite(action).all()):
                    status, reason = "terminated", TERMINATION_REASONS.index("non_finite")
                    break
                action = action.clamp(-1.0, 1.0)
                command = task.command(action)
                for dataref, value in zip(P.CONTROL_DATAREFS, controls_to_xplane(command[0].tolist()),
                                          strict=True):
                    self._send(P.encode_dref(dataref, value))
                sim.step(command, substeps=decimation)
                tick += self.control_dt
                deadline = None
                if self.pacing == "wallclock":
                    while time.perf_counter() < tick:  # keep the newest state until the tick
                        self._receive(tick)
                try:
                    values = self._wait(lambda v, t=last_time: v[P.TIME] > t, "new state", deadline)
                except XPlaneTimeout:
                    status = "timeout"
                    break
                last_time = values[P.TIME]
                self._write_state(values)
                state = sim.state
                observation, reward, reasons = task.step(action)  # on the state X-Plane flew to
                observation = observation.to(sim.dtype, copy=True)
                reason = int(reasons[0])
                truncated = step + 1 >= env.max_episode_steps
                td = self._output(observation, state, reason, truncated)
                frames.append(td.exclude("observation"))
                self._record(builder, state, action, command, float(reward[0]), reason, values)
                if reason:
                    status = "terminated"
                    break
        metrics = self._metrics(frames)
        steps = len(frames)
        return BridgeResult(
            recording=builder.build(), metrics=metrics, status=status,
            termination_reason=TERMINATION_REASONS[reason], steps=steps,
            seconds_flown=steps * self.control_dt,
            control_dt=self.control_dt, packets=self.counts.as_dict(),
            wall_seconds=time.perf_counter() - started,
            settings={"task": self.task_name, "airframe": env.airframe.name,
                      "controller": self.controller_name,
                      "pacing": self.pacing, "address": f"{self.address[0]}:{self.address[1]}",
                      "seed": env.config.seed, "decimation": decimation, "frequency": self.frequency,
                      "reference": {"latitude_deg": self.reference.latitude_deg,
                                    "longitude_deg": self.reference.longitude_deg,
                                    "altitude_m": self.reference.altitude_m}})

    def _record(self, builder: RecordingBuilder, state: TensorDictBase, action: torch.Tensor,
                command: torch.Tensor, reward: float, reason: int, values: dict[str, float]) -> None:
        frame = state_frame(state, num_motors=self.env.airframe.num_motors)
        frame.update({"action": action.cpu().numpy().copy(), "command": command.cpu().numpy().copy(),
                      "reward": np.array([reward], dtype=np.float32),
                      "termination_reason": np.array([reason], dtype=np.int64),
                      "xplane/values": np.array([[values[d] for d in P.STATE_DATAREFS]], dtype=np.float64)})
        for name, value in self.env.task.info().items():
            frame[f"reference/{name}"] = value.cpu().numpy().copy()
        builder.add(float(state["time"][0]), frame)

    def _metrics(self, frames: list[TensorDict]) -> dict[str, float]:
        """The task's protocol metrics over the flown steps (NaN-free where defined; {} with no steps)."""
        function = TASK_METRICS.get(self.task_name)
        if not frames or function is None:
            return {}
        rollout = TensorDict({"next": torch.stack(frames, dim=1)}, batch_size=[1, len(frames)])
        episode = function(rollout)
        return summarize(episode, episode["survival"])


__all__ = ["CONTROL_SIGNS", "LOOPBACK", "TASK_METRICS", "BridgeResult", "PacketCounts", "XPlaneBridge",
           "XPlaneTimeout", "controls_to_xplane"]
