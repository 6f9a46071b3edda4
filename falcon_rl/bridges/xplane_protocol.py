"""X-Plane's native UDP packets (the "Exchanging Data with X-Plane" interface, port 49000), little-endian.

    RREF request  b"RREF\\0" + int32 freq + int32 index + char[400] dataref      413 bytes
                  subscribe to ``dataref`` at ``freq`` replies per second (0 unsubscribes); X-Plane
                  answers to the sender's address and port
    RREF reply    b"RREF" + (b"," or b"\\0") + n x (int32 index, float32 value)  5 + 8 n bytes
    DREF write    b"DREF\\0" + float32 value + char[500] dataref                   509 bytes
    VEHS / VEHX   b"VEHS\\0" + int32 aircraft + double lat, lon, ele + float psi, the, phi   45 bytes
                  place aircraft ``aircraft`` (0: the user's) at lat, lon (deg), ele (m above mean
                  sea level), true heading psi, pitch the, roll phi (deg); VEHX is X-Plane 11's name

Strings are ASCII, null-terminated and null-padded to their field. Every decoder raises
:class:`XPlanePacketError` on a packet that is short, long, foreign (another header) or malformed (a
dataref that is not printable ASCII, a non-finite value, a negative index), so that a receiver can drop
and count it.

The datarefs are X-Plane's own names (``sim/flightmodel/position/...``); the frames and units they use:
latitude, longitude deg; elevation m MSL; local_x, local_y, local_z m and local_vx, local_vy, local_vz
m/s in X-Plane's local OpenGL frame (x east, y up, z south); phi, theta, psi deg (roll, pitch, true
heading); P, Q, R deg/s (body roll, pitch, yaw rates); alpha, beta deg; true_airspeed m/s;
indicated_airspeed kt; y_agl m above the terrain. :func:`ned_velocity_from_local` and
:func:`local_velocity_from_ned` convert the OpenGL velocities to and from NED.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass

#: X-Plane's UDP port.
XPLANE_PORT = 49000
#: Bytes of the dataref field of an RREF request and of a DREF write.
RREF_PATH_BYTES = 400
DREF_PATH_BYTES = 500
RREF_REQUEST_BYTES = 5 + 8 + RREF_PATH_BYTES
DREF_BYTES = 5 + 4 + DREF_PATH_BYTES
VEHS_BYTES = 5 + 4 + 24 + 12
#: Most (index, value) pairs X-Plane packs into one RREF reply; longer lists span several packets.
MAX_RREF_PAIRS = 183
#: Highest subscription rate accepted, replies per second.
MAX_RREF_FREQUENCY = 1000

RREF_HEADER = b"RREF\0"
RREF_REPLY_HEADERS = (b"RREF,", b"RREF\0")
DREF_HEADER = b"DREF\0"
VEHS_HEADER = b"VEHS\0"
VEHX_HEADER = b"VEHX\0"

# The datarefs the bridge reads and writes (X-Plane's names).
TIME = "sim/time/total_running_time_sec"
LATITUDE = "sim/flightmodel/position/latitude"
LONGITUDE = "sim/flightmodel/position/longitude"
ELEVATION = "sim/flightmodel/position/elevation"
LOCAL_X = "sim/flightmodel/position/local_x"
LOCAL_Y = "sim/flightmodel/position/local_y"
LOCAL_Z = "sim/flightmodel/position/local_z"
LOCAL_VX = "sim/flightmodel/position/local_vx"
LOCAL_VY = "sim/flightmodel/position/local_vy"
LOCAL_VZ = "sim/flightmodel/position/local_vz"
PHI = "sim/flightmodel/position/phi"
THETA = "sim/flightmodel/position/theta"
PSI = "sim/flightmodel/position/psi"
ROLL_RATE = "sim/flightmodel/position/P"
PITCH_RATE = "sim/flightmodel/position/Q"
YAW_RATE = "sim/flightmodel/position/R"
ALPHA = "sim/flightmodel/position/alpha"
BETA = "sim/flightmodel/position/beta"
TRUE_AIRSPEED = "sim/flightmodel/position/true_airspeed"
INDICATED_AIRSPEED = "sim/flightmodel/position/indicated_airspeed"
HEIGHT_AGL = "sim/flightmodel/position/y_agl"
YOKE_PITCH = "sim/joystick/yoke_pitch_ratio"
YOKE_ROLL = "sim/joystick/yoke_roll_ratio"
YOKE_HEADING = "sim/joystick/yoke_heading_ratio"
THROTTLE_ALL = "sim/cockpit2/engine/actuators/throttle_ratio_all"
THROTTLE_ENGINE0 = "sim/flightmodel/engine/ENGN_thro[0]"
OVERRIDE_JOYSTICK = "sim/operation/override/override_joystick"

#: What the bridge subscribes to, in index order.
STATE_DATAREFS: tuple[str, ...] = (
    TIME, LATITUDE, LONGITUDE, ELEVATION, LOCAL_X, LOCAL_Y, LOCAL_Z, LOCAL_VX, LOCAL_VY, LOCAL_VZ,
    PHI, THETA, PSI, ROLL_RATE, PITCH_RATE, YAW_RATE, ALPHA, BETA, TRUE_AIRSPEED, INDICATED_AIRSPEED,
    HEIGHT_AGL)
#: The control datarefs the bridge writes each control step (elevator, aileron, rudder, throttle).
CONTROL_DATAREFS: tuple[str, ...] = (YOKE_PITCH, YOKE_ROLL, YOKE_HEADING, THROTTLE_ALL)


class XPlanePacketError(ValueError):
    """A packet that is not the expected X-Plane message: short, long, foreign or malformed."""


@dataclass(frozen=True)
class VehiclePlacement:
    """A VEHS placement: ``aircraft`` index (0: the user's), lat, lon deg, ele m MSL, and true heading
    psi, pitch the, roll phi deg."""

    aircraft: int
    latitude_deg: float
    longitude_deg: float
    elevation_m: float
    psi_deg: float
    theta_deg: float
    phi_deg: float


def _path_field(dataref: str, size: int) -> bytes:
    """``dataref`` as a null-terminated, null-padded ASCII field of ``size`` bytes (ValueError if it
    does not fit or is not printable ASCII)."""
    if not dataref or not dataref.isascii() or not dataref.isprintable():
        raise ValueError(f"dataref must be non-empty printable ASCII, got {dataref!r}")
    raw = dataref.encode("ascii")
    if len(raw) >= size:
        raise ValueError(f"dataref {dataref[:40]!r}... is {len(raw)} bytes; the field holds {size - 1}")
    return raw.ljust(size, b"\0")


def _read_path(field: bytes, what: str) -> str:
    """The null-terminated ASCII string at the start of ``field`` (XPlanePacketError otherwise)."""
    end = field.find(b"\0")
    if end <= 0:
        raise XPlanePacketError(f"{what}: dataref field is empty or not null-terminated")
    raw = field[:end]
    if not all(32 <= byte < 127 for byte in raw):
        raise XPlanePacketError(f"{what}: dataref is not printable ASCII")
    return raw.decode("ascii")


def _check_header(packet: bytes, headers: tuple[bytes, ...], what: str) -> None:
    if not isinstance(packet, (bytes, bytearray, memoryview)):
        raise XPlanePacketError(f"{what}: not bytes")
    if bytes(packet[:5]) not in headers:
        raise XPlanePacketError(f"{what}: header {bytes(packet[:5])!r} is not {headers[0]!r}")


def _finite(value: float, what: str) -> float:
    if not math.isfinite(value):
        raise XPlanePacketError(f"{what}: value {value} is not finite")
    return value


# ---------------------------------------------------------------------- RREF
def encode_rref_request(frequency: int, index: int, dataref: str) -> bytes:
    """Subscribe to ``dataref`` at ``frequency`` replies/s (0 unsubscribes) under ``index`` (>= 0)."""
    if not 0 <= frequency <= MAX_RREF_FREQUENCY:
        raise ValueError(f"frequency must be in [0, {MAX_RREF_FREQUENCY}] replies/s, got {frequency}")
    if not 0 <= index < 2**31:
        raise ValueError(f"index must be in [0, 2^31), got {index}")
    return RREF_HEADER + struct.pack("<ii", frequency, index) + _path_field(dataref, RREF_PATH_BYTES)


def decode_rref_request(packet: bytes) -> tuple[int, int, str]:
    """(frequency replies/s, index, dataref) of an RREF request."""
    _check_header(packet, (RREF_HEADER,), "RREF request")
    if len(packet) != RREF_REQUEST_BYTES:
        raise XPlanePacketError(f"RREF request: {len(packet)} bytes, expected {RREF_REQUEST_BYTES}")
    frequency, index = struct.unpack_from("<ii", packet, 5)
    if not 0 <= frequency <= MAX_RREF_FREQUENCY or index < 0:
        raise XPlanePacketError(f"RREF request: frequency {frequency} or index {index} out of range")
    return frequency, index, _read_path(bytes(packet[13:]), "RREF request")


def encode_rref_reply(values: list[tuple[int, float]] | tuple[tuple[int, float], ...]) -> bytes:
    """One RREF reply of (index, value) pairs (X-Plane 11+'s b"RREF," header); at most
    ``MAX_RREF_PAIRS`` pairs (see :func:`encode_rref_replies`)."""
    if len(values) > MAX_RREF_PAIRS:
        raise ValueError(f"{len(values)} pairs; one reply holds at most {MAX_RREF_PAIRS}")
    return RREF_REPLY_HEADERS[0] + b"".join(struct.pack("<if", index, value) for index, value in values)


def encode_rref_replies(values: list[tuple[int, float]]) -> list[bytes]:
    """The RREF replies carrying every (index, value) pair, ``MAX_RREF_PAIRS`` per packet."""
    return [encode_rref_reply(values[i:i + MAX_RREF_PAIRS]) for i in range(0, len(values), MAX_RREF_PAIRS)]


def decode_rref_reply(packet: bytes) -> list[tuple[int, float]]:
    """The (index, value) pairs of an RREF reply; a packet with a non-finite value or a negative index
    is refused whole."""
    _check_header(packet, RREF_REPLY_HEADERS, "RREF reply")
    body = len(packet) - 5
    if body <= 0 or body % 8:
        raise XPlanePacketError(f"RREF reply: {len(packet)} bytes is not 5 + 8 n with n >= 1")
    pairs = list(struct.iter_unpack("<if", bytes(packet[5:])))
    for index, value in pairs:
        if index < 0:
            raise XPlanePacketError(f"RREF reply: negative index {index}")
        _finite(value, "RREF reply")
    return [(int(index), float(value)) for index, value in pairs]


# ---------------------------------------------------------------------- DREF
def encode_dref(dataref: str, value: float) -> bytes:
    """Write ``value`` (sent as float32) to ``dataref``."""
    if not math.isfinite(value):
        raise ValueError(f"DREF value must be finite, got {value}")
    return DREF_HEADER + struct.pack("<f", value) + _path_field(dataref, DREF_PATH_BYTES)


def decode_dref(packet: bytes) -> tuple[str, float]:
    """(dataref, value) of a DREF write."""
    _check_header(packet, (DREF_HEADER,), "DREF")
    if len(packet) != DREF_BYTES:
        raise XPlanePacketError(f"DREF: {len(packet)} bytes, expected {DREF_BYTES}")
    (value,) = struct.unpack_from("<f", packet, 5)
    return _read_path(bytes(packet[9:]), "DREF"), _finite(float(value), "DREF")


# ---------------------------------------------------------------------- VEHS
def encode_vehs(placement: VehiclePlacement, header: bytes = VEHS_HEADER) -> bytes:
    """A VEHS (or, with ``header=VEHX_HEADER``, X-Plane 11's VEHX) placement."""
    if header not in (VEHS_HEADER, VEHX_HEADER):
        raise ValueError(f"header must be {VEHS_HEADER!r} or {VEHX_HEADER!r}")
    p = placement
    numbers = (p.latitude_deg, p.longitude_deg, p.elevation_m, p.psi_deg, p.theta_deg, p.phi_deg)
    if not all(math.isfinite(v) for v in numbers):
        raise ValueError(f"placement must be finite, got {placement}")
    return header + struct.pack("<idddfff", p.aircraft, *numbers)


def decode_vehs(packet: bytes) -> VehiclePlacement:
    """The placement of a VEHS or VEHX packet."""
    _check_header(packet, (VEHS_HEADER, VEHX_HEADER), "VEHS")
    if len(packet) != VEHS_BYTES:
        raise XPlanePacketError(f"VEHS: {len(packet)} bytes, expected {VEHS_BYTES}")
    aircraft, *numbers = struct.unpack_from("<idddfff", packet, 5)
    for value in numbers:
        _finite(value, "VEHS")
    lat, lon = numbers[0], numbers[1]
    if aircraft < 0 or not -90.0 <= lat <= 90.0 or not -180.0 <= lon <= 360.0:
        raise XPlanePacketError(f"VEHS: aircraft {aircraft}, latitude {lat} or longitude {lon} out of range")
    return VehiclePlacement(int(aircraft), *(float(v) for v in numbers))


# ---------------------------------------------------------------------- frames
def ned_velocity_from_local(vx: float, vy: float, vz: float) -> tuple[float, float, float]:
    """X-Plane's OpenGL velocity (x east, y up, z south; m/s) -> (north, east, down) m/s."""
    return -vz, vx, -vy


def local_velocity_from_ned(north: float, east: float, down: float) -> tuple[float, float, float]:
    """(north, east, down) m/s -> X-Plane's OpenGL (local_vx east, local_vy up, local_vz south) m/s."""
    return east, -down, -north


__all__ = [
    "CONTROL_DATAREFS",
    "DREF_BYTES",
    "MAX_RREF_PAIRS",
    "RREF_REQUEST_BYTES",
    "STATE_DATAREFS",
    "VEHS_BYTES",
    "XPLANE_PORT",
    "VehiclePlacement",
    "XPlanePacketError",
    "decode_dref",
    "decode_rref_reply",
    "decode_rref_request",
    "decode_vehs",
    "encode_dref",
    "encode_rref_replies",
    "encode_rref_reply",
    "encode_rref_request",
    "encode_vehs",
    "local_velocity_from_ned",
    "ned_velocity_from_local",
]
