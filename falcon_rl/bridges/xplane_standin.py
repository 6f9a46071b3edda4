"""A loopback stand-in for X-Plane: a UDP server that speaks X-Plane's native packets (RREF, DREF, VEHS)
and flies falcon-rl's own :class:`~falcon_rl.physics.Simulator` (one aircraft) in its own thread, so
that the X-Plane bridge can be tried and tested without X-Plane.

    with XPlaneStandIn("volantex_ranger", mode="lockstep") as standin:   # ephemeral loopback port
        with XPlaneBridge(port=standin.port, ...) as bridge:
            result = bridge.fly(30.0)

What it does, as X-Plane does:

- RREF requests subscribe (frequency > 0) or unsubscribe (0) a dataref under an index; the replies go
  to the address the request came from, all of a client's due subscriptions in one packet (split at
  ``MAX_RREF_PAIRS``). Datarefs it does not publish are answered with 0.0 and listed in
  ``unknown_datarefs``.
- DREF writes of the yoke ratios (``sim/joystick/yoke_pitch_ratio``, ``yoke_roll_ratio``,
  ``yoke_heading_ratio``) and of the throttle (``sim/cockpit2/engine/actuators/throttle_ratio_all`` or
  ``sim/flightmodel/engine/ENGN_thro[0]``) set the command (see :mod:`.xplane` for the mapping);
  ``sim/operation/override/override_joystick`` is kept in :attr:`override_joystick`; writes of
  ``local_vx/vy/vz`` (m/s, OpenGL frame) and ``P/Q/R`` (deg/s) set the velocity and body rates.
- VEHS / VEHX for aircraft 0 place the aircraft (latitude, longitude, elevation, heading, pitch, roll),
  keeping its velocity over the ground; the placement is a ``Simulator.reset`` of the integrated state.
- Anything else (short, long, garbage, another protocol, another aircraft index, a non-finite value)
  is dropped and counted in :attr:`counts`; the server never stops on a packet.

Clock (``mode``):

- ``"lockstep"`` (deterministic, as fast as the client): the simulation advances ``frame_seconds``
  (``round(frame_seconds / dt)`` physics steps) each time every control dataref (pitch, roll and
  heading ratios and a throttle) has been written since the previous frame, then every subscription
  is answered once with the new state. A placement or a velocity/rate write is answered at once
  (without a step). Set ``frame_seconds`` to the client's control period.
- ``"realtime"``: one physics step of ``dt`` per ``dt`` of wall-clock time under the latest
  command, and each subscription answered at its own frequency, as X-Plane does.

Positions: the NED origin is pinned to ``reference`` (a :class:`~falcon_rl.viz.geodesy.ReferencePoint`,
exact WGS-84 conversion); the height above the simulator's flat ground is the elevation above the
reference point's altitude. ``local_x, local_y, local_z`` are east, elevation and south in metres.
"""

from __future__ import annotations

import math
import socket
import threading
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch

from ..airframe import Airframe, load_airframe
from ..constants import KT
from ..defaults import DEFAULT_AIRFRAME, DEFAULT_BACKEND
from ..physics import Simulator
from ..physics import state as S
from ..physics.atmosphere import isa_density
from ..physics.rotations import body_to_ned, euler_to_quaternion, ned_to_body
from ..viz.geodesy import DEFAULT_REFERENCE, ReferencePoint, geodetic_to_ned, ned_to_geodetic
from . import xplane_protocol as P
from .xplane import CONTROL_SIGNS, LOOPBACK, PacketCounts

#: How long the server waits on its socket before checking for shutdown, s.
_POLL_SECONDS = 0.05
#: Largest datagram read.
_MAX_DATAGRAM = 65_535


@dataclass
class _Subscription:
    frequency: int
    dataref: str
    next_due: float = 0.0


@dataclass
class _Client:
    subscriptions: dict[int, _Subscription] = field(default_factory=dict)


class XPlaneStandIn:
    """A loopback UDP server speaking X-Plane's native packets, flown by a one-env :class:`Simulator`
    (see the module docstring).

    Args:
        airframe: an :class:`Airframe` or a shipped name / JSON path.
        host, port: where to listen (``port=0``: an ephemeral port, read it from :attr:`port`).
        mode: "lockstep" or "realtime" (see the module docstring).
        frame_seconds: lockstep: simulated seconds per control frame (the client's control period).
        dt: physics step, s. backend: the simulator's backend ("warp" or "torch").
        reference: the geodetic position of the NED origin.
        ground_effect: as the simulator's.
    """

    def __init__(self, airframe: Airframe | str = DEFAULT_AIRFRAME, host: str = LOOPBACK, port: int = 0, *,
                 mode: str = "lockstep", frame_seconds: float = 0.05, dt: float = 0.01,
                 backend: str = DEFAULT_BACKEND,
                 reference: ReferencePoint | None = None, ground_effect: bool | str = True) -> None:
        if mode not in ("lockstep", "realtime"):
            raise ValueError(f"mode must be 'lockstep' or 'realtime', got {mode!r}")
        if not (frame_seconds > 0 and dt > 0 and math.isfinite(frame_seconds)):
            raise ValueError(f"frame_seconds and dt must be > 0, got {frame_seconds}, {dt}")
        self.airframe = airframe if isinstance(airframe, Airframe) else load_airframe(airframe)
        self.mode = mode
        self.dt = float(dt)
        self.frame_steps = max(1, round(frame_seconds / dt))
        self.reference = reference or DEFAULT_REFERENCE
        self.sim = Simulator(self.airframe, num_envs=1, backend=backend, dt=dt, ground_effect=ground_effect)
        #: [1, 4] normalised command held over the steps (elevator, aileron, rudder, throttle).
        self.command = self.sim.default_initial()[1].reshape(1, 4).clone()
        #: Simulated seconds since the stand-in started (``sim/time/total_running_time_sec``).
        self.sim_time = 0.0
        #: The value last written to ``sim/operation/override/override_joystick``.
        self.override_joystick = 0.0
        #: Packets received, accepted, dropped (by kind) and sent.
        self.counts = PacketCounts()
        #: Datarefs subscribed or written that the stand-in does not know.
        self.unknown_datarefs: set[str] = set()
        #: Lockstep frames flown.
        self.frames = 0
        self._written: set[int] = set()
        self._clients: dict[tuple[str, int], _Client] = {}
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._socket = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            self._socket.bind((host, port))
            self._socket.settimeout(_POLL_SECONDS)
        except OSError:
            self._socket.close()
            raise
        self._thread = threading.Thread(target=self._serve, name="xplane-standin", daemon=True)
        self._thread.start()

    # ------------------------------------------------------------------ lifetime
    @property
    def address(self) -> tuple[str, int]:
        """(host, port) the stand-in listens on."""
        host, port = self._socket.getsockname()[:2]
        return str(host), int(port)

    @property
    def port(self) -> int:
        """The UDP port the stand-in listens on."""
        return self.address[1]

    def close(self) -> None:
        """Stop the server thread (joined) and close the socket; idempotent."""
        self._stop.set()
        if self._thread.is_alive() and threading.current_thread() is not self._thread:
            self._thread.join(timeout=5.0)
        self._socket.close()

    def __enter__(self) -> XPlaneStandIn:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------------ server loop
    def _serve(self) -> None:
        next_tick = time.perf_counter()
        while not self._stop.is_set():
            if self.mode == "realtime":
                now = time.perf_counter()
                while now >= next_tick:  # catch up with the wall clock, one physics step per dt
                    with self._lock:
                        self._advance(1)
                    next_tick += self.dt
                    now = time.perf_counter()
                self._send_due(now)
                self._socket.settimeout(max(1e-4, min(_POLL_SECONDS, next_tick - now)))
            try:
                packet, sender = self._socket.recvfrom(_MAX_DATAGRAM)
            except TimeoutError:
                continue
            except OSError:
                if self._stop.is_set():
                    return
                continue
            self.counts.received += 1
            try:
                with self._lock:
                    answer = self._handle(packet, (str(sender[0]), int(sender[1])))
            except P.XPlanePacketError:
                self.counts.malformed += 1
                continue
            except _Foreign:
                self.counts.foreign += 1
                continue
            self.counts.accepted += 1
            if answer:
                self._send_all()

    def _handle(self, packet: bytes, sender: tuple[str, int]) -> bool:
        """Apply one packet; True when every client should get the state now (lockstep)."""
        head = packet[:5]
        if head == P.RREF_HEADER:
            frequency, index, dataref = P.decode_rref_request(packet)
            client = self._clients.setdefault(sender, _Client())
            if frequency == 0:
                client.subscriptions.pop(index, None)
                return False
            if dataref not in _PUBLISHED:
                self.unknown_datarefs.add(dataref)
            client.subscriptions[index] = _Subscription(frequency, dataref, time.perf_counter())
            return self.mode == "lockstep"
        if head == P.DREF_HEADER:
            return self._write(*P.decode_dref(packet))
        if head in (P.VEHS_HEADER, P.VEHX_HEADER):
            placement = P.decode_vehs(packet)
            if placement.aircraft != 0:
                raise _Foreign()
            self._place(placement)
            return self.mode == "lockstep"
        raise _Foreign()

    # ------------------------------------------------------------------ writes
    def _write(self, dataref: str, value: float) -> bool:
        channel = _CONTROL_CHANNEL.get(dataref)
        if channel is not None:
            ratio = max(-1.0, min(1.0, value))
            if channel == S.THROTTLE:
                self.command[0, S.THROTTLE] = 2.0 * max(0.0, min(1.0, value)) - 1.0
            else:
                self.command[0, channel] = CONTROL_SIGNS[channel] * ratio
            self._written.add(channel)
            if self.mode == "lockstep" and len(self._written) == 4:
                self._written.clear()
                self._advance(self.frame_steps)
                self.frames += 1
                return True
            return False
        if dataref == P.OVERRIDE_JOYSTICK:
            self.override_joystick = value
            return False
        if dataref in _VELOCITY_INDEX or dataref in _RATE_INDEX:
            self._set_motion(dataref, value)
            return self.mode == "lockstep"
        self.unknown_datarefs.add(dataref)
        return False

    def _set_motion(self, dataref: str, value: float) -> None:
        """Velocity (OpenGL m/s) or body rate (deg/s) write: a reset of the integrated state."""
        x = self.sim.x.clone()
        q = x[:, S.QUATERNION]
        if dataref in _VELOCITY_INDEX:
            local = list(P.local_velocity_from_ned(*body_to_ned(q, x[:, S.VELOCITY])[0].tolist()))
            local[_VELOCITY_INDEX[dataref]] = value
            ned = torch.tensor([P.ned_velocity_from_local(*local)], dtype=x.dtype)
            x[:, S.VELOCITY] = ned_to_body(q, ned)
        else:
            x[0, S.ANGULAR_RATE.start + _RATE_INDEX[dataref]] = math.radians(value)
        self._reset(x)

    def _place(self, placement: P.VehiclePlacement) -> None:
        """VEHS: new position and attitude, the same velocity over the ground (NED)."""
        x = self.sim.x.clone()
        v_ned = body_to_ned(x[:, S.QUATERNION], x[:, S.VELOCITY])
        ned = geodetic_to_ned(self.reference, placement.latitude_deg, placement.longitude_deg,
                              placement.elevation_m)
        euler = torch.tensor([[math.radians(placement.phi_deg), math.radians(placement.theta_deg),
                               math.radians(placement.psi_deg)]], dtype=x.dtype)
        q = euler_to_quaternion(euler)
        x[:, S.POSITION] = torch.as_tensor(np.asarray(ned), dtype=x.dtype).reshape(1, 3)
        x[:, S.QUATERNION] = q
        x[:, S.VELOCITY] = ned_to_body(q, v_ned)
        self._reset(x)

    def _reset(self, x: torch.Tensor) -> None:
        try:
            self.sim.reset(x)
        except ValueError as error:  # below the ground, too fast, ...: refused as X-Plane would clamp
            raise P.XPlanePacketError(f"placement refused: {error}") from None

    # ------------------------------------------------------------------ physics and replies
    def _advance(self, steps: int) -> None:
        self.sim.step(self.command, substeps=steps)
        self.sim_time += steps * self.dt

    def values(self) -> dict[str, float]:
        """Every published dataref's current value, in X-Plane's units and frames."""
        state = self.sim.state
        ned = state["position_ned"][0].double().numpy()
        lat, lon, ele = (float(v) for v in ned_to_geodetic(self.reference, ned))
        v_ned = state["velocity_ned"][0].tolist()
        vx, vy, vz = P.local_velocity_from_ned(*v_ned)
        roll, pitch, yaw = (math.degrees(v) for v in state["euler"][0].tolist())
        p, q, r = (math.degrees(v) for v in state["angular_rate_body"][0].tolist())
        airspeed, height = float(state["airspeed"][0]), float(state["height"][0])
        sigma = float(isa_density(torch.tensor(self.reference.altitude_m + height))) / 1.225
        command = self.command[0].tolist()
        return {
            P.TIME: self.sim_time, P.LATITUDE: lat, P.LONGITUDE: lon, P.ELEVATION: ele,
            P.LOCAL_X: float(ned[1]), P.LOCAL_Y: ele, P.LOCAL_Z: -float(ned[0]),
            P.LOCAL_VX: vx, P.LOCAL_VY: vy, P.LOCAL_VZ: vz,
            P.PHI: roll, P.THETA: pitch, P.PSI: yaw % 360.0, P.ROLL_RATE: p, P.PITCH_RATE: q, P.YAW_RATE: r,
            P.ALPHA: math.degrees(float(state["alpha"][0])), P.BETA: math.degrees(float(state["beta"][0])),
            P.TRUE_AIRSPEED: airspeed, P.INDICATED_AIRSPEED: airspeed * math.sqrt(sigma) / KT,
            P.HEIGHT_AGL: height,
            P.YOKE_PITCH: CONTROL_SIGNS[S.ELEVATOR] * command[S.ELEVATOR],
            P.YOKE_ROLL: CONTROL_SIGNS[S.AILERON] * command[S.AILERON],
            P.YOKE_HEADING: CONTROL_SIGNS[S.RUDDER] * command[S.RUDDER],
            P.THROTTLE_ALL: 0.5 * (command[S.THROTTLE] + 1.0),
            P.THROTTLE_ENGINE0: 0.5 * (command[S.THROTTLE] + 1.0),
            P.OVERRIDE_JOYSTICK: self.override_joystick,
        }

    def _send(self, client: tuple[str, int], indices: list[tuple[int, str]], values: dict[str, float]
              ) -> None:
        pairs = [(index, values.get(dataref, 0.0)) for index, dataref in indices]
        for packet in P.encode_rref_replies(pairs):
            try:
                self._socket.sendto(packet, client)
                self.counts.sent += 1
            except OSError:  # the client went away: its subscriptions stay until it unsubscribes
                pass

    def _send_all(self) -> None:
        """Answer every subscription of every client now (lockstep)."""
        with self._lock:
            values = self.values()
            jobs = [(client, sorted((i, s.dataref) for i, s in c.subscriptions.items()))
                    for client, c in self._clients.items() if c.subscriptions]
        for client, indices in jobs:
            self._send(client, indices, values)

    def _send_due(self, now: float) -> None:
        """Realtime: answer the subscriptions whose period has elapsed."""
        with self._lock:
            jobs = []
            for client, c in self._clients.items():
                due = [(i, s.dataref) for i, s in sorted(c.subscriptions.items()) if now >= s.next_due]
                for i, _ in due:
                    sub = c.subscriptions[i]
                    sub.next_due = max(sub.next_due + 1.0 / sub.frequency, now - 1.0 / sub.frequency)
                if due:
                    jobs.append((client, due))
            values = self.values() if jobs else {}
        for client, indices in jobs:
            self._send(client, indices, values)

    def snapshot(self) -> dict[str, Any]:
        """Counts and state of the stand-in (a JSON-able document)."""
        with self._lock:
            return {"mode": self.mode, "frames": self.frames, "sim_time_s": self.sim_time,
                    "override_joystick": self.override_joystick, "packets": self.counts.as_dict(),
                    "unknown_datarefs": sorted(self.unknown_datarefs)}


class _Foreign(Exception):  # noqa: N818 (a signal, not an error)
    """A well-formed packet of another message or aircraft: dropped and counted as foreign."""


_CONTROL_CHANNEL: dict[str, int] = {P.YOKE_PITCH: S.ELEVATOR, P.YOKE_ROLL: S.AILERON,
                                    P.YOKE_HEADING: S.RUDDER, P.THROTTLE_ALL: S.THROTTLE,
                                    P.THROTTLE_ENGINE0: S.THROTTLE}
_VELOCITY_INDEX: dict[str, int] = {P.LOCAL_VX: 0, P.LOCAL_VY: 1, P.LOCAL_VZ: 2}
_RATE_INDEX: dict[str, int] = {P.ROLL_RATE: 0, P.PITCH_RATE: 1, P.YAW_RATE: 2}
_PUBLISHED: frozenset[str] = frozenset({*P.STATE_DATAREFS, *_CONTROL_CHANNEL, P.OVERRIDE_JOYSTICK})

__all__ = ["XPlaneStandIn"]
