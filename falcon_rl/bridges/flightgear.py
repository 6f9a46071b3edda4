"""FlightGear as a viewer: stream aircraft states as FlightGear "native-fdm" UDP packets.

FlightGear's external flight-model interface reads one ``FGNetFDM`` packet per datagram: version 24
of the structure in FlightGear's ``src/Network/net_fdm.hxx``, all fields in network byte order
(big-endian), 408 bytes (:data:`FDM_FIELDS` lists them in order, with FlightGear's names and units).
FlightGear drops packets whose version is not 24 (it logs "version mismatch").

Launch FlightGear with its own flight model switched off, reading the stream on UDP port 5550::

    fgfs --fdm=null --native-fdm=socket,in,60,,5550,udp --airport=KSFO --aircraft=c172p

(``socket,in,<Hz>,<host>,<port>,udp``: an empty host listens on every interface; the rate is how
often FlightGear reads the socket, so keep it at or above ``rate_hz``.) Then::

    FlightGearStreamer(port=5550).stream(recording)           # paced in real time
    FlightGearStreamer(port=5550).stream(recording, speed=0)  # as fast as possible

The NED origin is placed at a :class:`~falcon_rl.viz.geodesy.ReferencePoint` (default KSFO, in every
FlightGear installation's scenery), converted exactly on WGS-84; the attitude is rotated onto the local
level at the aircraft. Units follow FlightGear's own writer (``native_fdm.cxx``): angles and rates
rad and rad/s, ``vcas`` knots (the equivalent airspeed in the ISA atmosphere, equal to the calibrated
airspeed at these speeds), ``climb_rate`` and velocities ft/s (``v_north/east/down`` in the
reference NED axes; ``v_wind_body_*`` the body-axis velocity relative to the air, u, v, w),
``agl`` m (the recorded ``height``). Surfaces are sent as FlightGear's ``*-pos-norm`` values in
[-1, 1]: the deflection divided by the actuator limit on its side, positive trailing edge down for
the elevator, right aileron trailing edge down for ``left_aileron`` = +aileron and ``right_aileron``
= -aileron, as JSBSim models do. Accelerations, engine rpm and gear are left at zero; every motor is
reported running.
"""

from __future__ import annotations

import math
import socket
import struct
import time
from collections.abc import Mapping
from typing import Any

import numpy as np

from ..constants import FT, KT
from ..recording import Recording, quaternion_euler
from ..viz.acmi import isa_density_ratio
from ..viz.geodesy import DEFAULT_REFERENCE, ReferencePoint, euler_to_local_level, ned_to_geodetic

#: FG_NET_FDM_VERSION of the packet this module writes.
FG_NET_FDM_VERSION = 24
#: (name, struct code) of every field of FGNetFDM version 24, in order (FG_MAX_ENGINES = 4,
#: FG_MAX_WHEELS = 3, FG_MAX_TANKS = 4).
FDM_FIELDS: tuple[tuple[str, str], ...] = (
    ("version", "I"), ("padding", "I"),
    ("longitude", "d"), ("latitude", "d"), ("altitude", "d"),  # rad, rad, m
    ("agl", "f"), ("phi", "f"), ("theta", "f"), ("psi", "f"), ("alpha", "f"), ("beta", "f"),  # m, rad
    ("phidot", "f"), ("thetadot", "f"), ("psidot", "f"),  # rad/s
    ("vcas", "f"), ("climb_rate", "f"),  # kt, ft/s
    ("v_north", "f"), ("v_east", "f"), ("v_down", "f"),  # ft/s
    ("v_wind_body_north", "f"), ("v_wind_body_east", "f"), ("v_wind_body_down", "f"),  # ft/s
    ("A_X_pilot", "f"), ("A_Y_pilot", "f"), ("A_Z_pilot", "f"),  # ft/s^2
    ("stall_warning", "f"), ("slip_deg", "f"),
    ("num_engines", "I"), ("eng_state", "4I"), ("rpm", "4f"), ("fuel_flow", "4f"), ("fuel_px", "4f"),
    ("egt", "4f"), ("cht", "4f"), ("mp_osi", "4f"), ("tit", "4f"), ("oil_temp", "4f"), ("oil_px", "4f"),
    ("num_tanks", "I"), ("fuel_quantity", "4f"),
    ("num_wheels", "I"), ("wow", "3I"), ("gear_pos", "3f"), ("gear_steer", "3f"), ("gear_compression", "3f"),
    ("cur_time", "I"), ("warp", "i"), ("visibility", "f"),  # unix s, s, m
    ("elevator", "f"), ("elevator_trim_tab", "f"), ("left_flap", "f"), ("right_flap", "f"),
    ("left_aileron", "f"), ("right_aileron", "f"), ("rudder", "f"), ("nose_wheel", "f"),
    ("speedbrake", "f"), ("spoilers", "f"),
)
FDM_STRUCT = struct.Struct(">" + "".join(code for _, code in FDM_FIELDS))
#: Bytes of one packet.
FDM_SIZE = 408
assert FDM_STRUCT.size == FDM_SIZE, FDM_STRUCT.size
_LENGTHS = {name: int(code[:-1] or 1) for name, code in FDM_FIELDS}
_ARRAYS = {name for name, code in FDM_FIELDS if len(code) > 1}
_INTEGERS = {name for name, code in FDM_FIELDS if code[-1] in "Ii"}
_LIMITS = {"I": (0, 2**32 - 1), "i": (-(2**31), 2**31 - 1)}


def encode_fdm(values: Mapping[str, Any]) -> bytes:
    """One 408-byte FGNetFDM v24 packet from {field name: value} (names of :data:`FDM_FIELDS`; arrays
    as sequences of at most their length; missing fields and array tails are 0, ``version`` 24)."""
    unknown = set(values) - set(_LENGTHS)
    if unknown:
        raise ValueError(f"unknown FGNetFDM fields: {', '.join(sorted(unknown))}")
    flat: list[float | int] = []
    for name, code in FDM_FIELDS:
        default = FG_NET_FDM_VERSION if name == "version" else 0
        value = values.get(name, default)
        items = list(np.ravel(np.asarray(value, dtype=np.float64))) if name in _ARRAYS else [value]
        if name in _ARRAYS and len(items) > _LENGTHS[name]:
            raise ValueError(f"FGNetFDM field {name} holds {_LENGTHS[name]} values, got {len(items)}")
        items += [0] * (_LENGTHS[name] - len(items))
        for item in items:
            item = float(item)
            if not math.isfinite(item):
                raise ValueError(f"FGNetFDM field {name} is not finite ({item})")
            if name in _INTEGERS:
                low, high = _LIMITS[code[-1]]
                if item != int(item) or not low <= item <= high:
                    raise ValueError(f"FGNetFDM field {name} must be an integer in [{low}, {high}], "
                                     f"got {item}")
                flat.append(int(item))
            else:
                flat.append(item)
    return FDM_STRUCT.pack(*flat)


def decode_fdm(data: bytes) -> dict[str, Any]:
    """{field name: value} of one FGNetFDM v24 packet (arrays as lists); the inverse of
    :func:`encode_fdm` up to float32 rounding."""
    if len(data) != FDM_SIZE:
        raise ValueError(f"an FGNetFDM v{FG_NET_FDM_VERSION} packet has {FDM_SIZE} bytes, got {len(data)}")
    flat = list(FDM_STRUCT.unpack(data))
    out: dict[str, Any] = {}
    for name, _ in FDM_FIELDS:
        count = _LENGTHS[name]
        items, flat = flat[:count], flat[count:]
        out[name] = items if name in _ARRAYS else items[0]
    return out


def surface_limits_of(airframe: Any) -> dict[str, tuple[float, float]]:
    """{surface: (min, max) rad} of an :class:`~falcon_rl.airframe.Airframe` (or its name)."""
    if isinstance(airframe, str):
        from ..airframe import load_airframe

        airframe = load_airframe(airframe)
    return {name: tuple(float(x) for x in act.limits) for name, act in airframe.actuators.items()}


def _normalised(value: float, limits: tuple[float, float] | None) -> float:
    if limits is None:
        return 0.0
    low, high = limits
    scale = high if value >= 0 else -low
    return float(np.clip(value / scale, -1.0, 1.0)) if scale > 0 else 0.0


def fdm_values(frame: Mapping[str, Any], reference: ReferencePoint | None = None,
               surface_limits: Mapping[str, tuple[float, float]] | None = None,
               unix_time: float | None = None) -> dict[str, Any]:
    """The FGNetFDM fields of one aircraft's state ``frame`` {name: value} (the recording schema
    without the [T, E] axes: ``position_ned`` [3] m and ``euler`` [3] rad or ``quaternion`` [4] are
    needed; ``velocity_ned``, ``angular_rate_body``, ``airspeed``, ``alpha``, ``beta``, ``height``,
    ``surface_position`` [3] rad and ``throttle`` [M] are used when present)."""
    def get(name: str, size: int) -> np.ndarray | None:
        if name not in frame:
            return None
        value = np.asarray(frame[name], dtype=np.float64).reshape(-1)
        if value.size != size:
            raise ValueError(f"frame field {name} must have {size} values, got {value.size}")
        if not np.all(np.isfinite(value)):
            raise ValueError(f"frame field {name} has non-finite values")
        return value

    ned = get("position_ned", 3)
    if ned is None:
        raise ValueError("frame needs position_ned")
    euler = get("euler", 3)
    if euler is None:
        quaternion = get("quaternion", 4)
        if quaternion is None:
            raise ValueError("frame needs euler or quaternion")
        euler = quaternion_euler(quaternion)
    ref = reference or DEFAULT_REFERENCE
    lat, lon, alt = (float(v) for v in ned_to_geodetic(ref, ned))
    phi, theta, psi = (float(v) for v in euler_to_local_level(ref, ned, euler))
    values: dict[str, Any] = {
        "longitude": math.radians(lon), "latitude": math.radians(lat), "altitude": alt,
        "phi": phi, "theta": theta, "psi": psi,
        "cur_time": int(time.time() if unix_time is None else unix_time), "visibility": 20_000.0,
    }
    height = get("height", 1)
    values["agl"] = float(height[0]) if height is not None else float(-ned[2])
    for name in ("alpha", "beta"):
        scalar = get(name, 1)
        if scalar is not None:
            values[name] = float(scalar[0])
    rates = get("angular_rate_body", 3)
    if rates is not None:  # body rates -> Euler angle rates (of the reference-frame angles)
        p, q, r = rates
        roll, pitch = float(euler[0]), float(euler[1])
        cos_pitch = math.cos(pitch) if abs(math.cos(pitch)) > 1e-6 else math.copysign(1e-6, math.cos(pitch))
        turn = q * math.sin(roll) + r * math.cos(roll)
        values.update(phidot=p + turn * math.tan(pitch), thetadot=q * math.cos(roll) - r * math.sin(roll),
                      psidot=turn / cos_pitch)
    velocity = get("velocity_ned", 3)
    if velocity is not None:
        values.update(v_north=velocity[0] / FT, v_east=velocity[1] / FT, v_down=velocity[2] / FT,
                      climb_rate=-velocity[2] / FT)
    airspeed = get("airspeed", 1)
    if airspeed is not None:
        speed = float(airspeed[0])
        values["vcas"] = speed * math.sqrt(float(isa_density_ratio(alt))) / KT
        a, b = values.get("alpha", 0.0), values.get("beta", 0.0)
        values.update(v_wind_body_north=speed * math.cos(a) * math.cos(b) / FT,
                      v_wind_body_east=speed * math.sin(b) / FT,
                      v_wind_body_down=speed * math.sin(a) * math.cos(b) / FT)
    surfaces = get("surface_position", 3)
    if surfaces is not None:
        limits = surface_limits or {}
        aileron = _normalised(float(surfaces[1]), limits.get("aileron"))
        values.update(elevator=_normalised(float(surfaces[0]), limits.get("elevator")),
                      left_aileron=aileron, right_aileron=-aileron,
                      rudder=_normalised(float(surfaces[2]), limits.get("rudder")))
    if "throttle" in frame:
        motors = min(int(np.asarray(frame["throttle"]).size), 4)
        values.update(num_engines=motors, eng_state=[2] * motors)
    return values


def _check_port(port: int) -> int:
    if not isinstance(port, int) or isinstance(port, bool) or not 1 <= port <= 65535:
        raise ValueError(f"port must be an int in [1, 65535], got {port!r}")
    return port


class FlightGearStreamer:
    """Sends native-fdm packets of one aircraft to FlightGear at ``host:port`` (UDP).

    ``rate_hz`` caps the packet rate; with ``realtime`` :meth:`send` waits so that packets are at
    least 1/``rate_hz`` s apart (for live loops faster than real time), otherwise it sends at once.
    ``reference`` places the NED origin; ``surface_limits`` {surface: (min, max) rad} normalise the
    surfaces (default: the recording's airframe in :meth:`stream`, else surfaces are sent as 0)."""

    def __init__(self, host: str = "127.0.0.1", port: int = 5550, rate_hz: float = 60.0,
                 realtime: bool = True, reference: ReferencePoint | None = None,
                 surface_limits: Mapping[str, tuple[float, float]] | None = None) -> None:
        _check_port(port)
        if not (isinstance(rate_hz, (int, float)) and math.isfinite(rate_hz) and rate_hz > 0):
            raise ValueError(f"rate_hz must be a finite number > 0, got {rate_hz!r}")
        self.address = (host, port)
        self.rate_hz = float(rate_hz)
        self.realtime = bool(realtime)
        self.reference = reference or DEFAULT_REFERENCE
        self.surface_limits = dict(surface_limits) if surface_limits is not None else None
        self.packets_sent = 0
        self._last_send = -math.inf
        self._socket = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)

    def _send_packet(self, packet: bytes) -> None:
        try:
            self._socket.sendto(packet, self.address)
        except ConnectionRefusedError:  # nobody listening yet (ICMP port unreachable): keep going
            pass
        except OSError as error:
            raise ValueError(f"cannot send to {self.address[0]}:{self.address[1]} ({error})") from None
        self.packets_sent += 1

    def send(self, state_frame: Mapping[str, Any], env: int = 0) -> bytes:
        """Send aircraft ``env`` of ``state_frame`` ({name: [E, ...]}, e.g. ``recording.state_frame``
        of a simulator, or one aircraft's {name: [...]}) and return the packet."""
        frame = _select_env(state_frame, env)
        packet = encode_fdm(fdm_values(frame, self.reference, self.surface_limits))
        if self.realtime:
            wait = self._last_send + 1.0 / self.rate_hz - time.perf_counter()
            if wait > 0:
                time.sleep(wait)
        self._send_packet(packet)
        self._last_send = time.perf_counter()
        return packet

    def stream(self, rec: Recording, speed: float = 1.0, env: int = 0) -> int:
        """Play aircraft ``env`` of ``rec``: frames are sent at ``speed`` times real time, skipping frames
        so that packets are no closer than 1/``rate_hz`` s of wall time; ``speed=0`` sends every frame
        as fast as possible. Returns the number of packets sent."""
        if not (isinstance(speed, (int, float)) and math.isfinite(speed) and speed >= 0):
            raise ValueError(f"speed must be a finite number >= 0, got {speed!r}")
        if not isinstance(env, int) or not 0 <= env < rec.num_envs:
            raise ValueError(f"env must be in [0, {rec.num_envs}), got {env!r}")
        limits = self.surface_limits
        if limits is None and rec.meta.get("airframe"):
            try:
                limits = surface_limits_of(str(rec.meta["airframe"]))
            except ValueError:
                limits = None
        fields = {name: value[:, env] for name, value in rec.fields.items()
                  if name in _FRAME_FIELDS}
        start, sent, last = time.perf_counter(), 0, -math.inf
        for k in range(rec.num_frames):
            playback = (rec.time[k] - rec.time[0]) / speed if speed > 0 else 0.0
            if speed > 0:
                if playback - last < 1.0 / self.rate_hz - 1e-9 and k != rec.num_frames - 1:
                    continue
                wait = start + playback - time.perf_counter()
                if wait > 0:
                    time.sleep(wait)
                last = playback
            frame = {name: value[k] for name, value in fields.items()}
            self._send_packet(encode_fdm(fdm_values(frame, self.reference, limits)))
            sent += 1
        self._last_send = time.perf_counter()
        return sent

    def close(self) -> None:
        """Close the socket."""
        self._socket.close()

    def __enter__(self) -> FlightGearStreamer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


_FRAME_FIELDS = frozenset({"position_ned", "euler", "quaternion", "velocity_ned", "angular_rate_body",
                           "airspeed", "alpha", "beta", "height", "surface_position", "throttle"})


def _select_env(state_frame: Mapping[str, Any], env: int) -> dict[str, np.ndarray]:
    if "position_ned" not in state_frame:
        raise ValueError("state_frame needs position_ned")
    position = np.asarray(state_frame["position_ned"])
    if position.ndim == 1:
        return {k: np.asarray(v) for k, v in state_frame.items() if k in _FRAME_FIELDS}
    if position.ndim != 2 or position.shape[1] != 3:
        raise ValueError(f"state_frame position_ned must be [3] or [E, 3], got {position.shape}")
    if not isinstance(env, int) or not 0 <= env < position.shape[0]:
        raise ValueError(f"env must be in [0, {position.shape[0]}), got {env!r}")
    return {k: _row(v, env) for k, v in state_frame.items() if k in _FRAME_FIELDS}


def _row(value: Any, env: int) -> np.ndarray:
    if hasattr(value, "detach"):
        value = value.detach().cpu().numpy()
    return np.asarray(value)[env]


__all__ = ["FDM_FIELDS", "FDM_SIZE", "FDM_STRUCT", "FG_NET_FDM_VERSION", "FlightGearStreamer", "decode_fdm",
           "encode_fdm", "fdm_values", "surface_limits_of"]
