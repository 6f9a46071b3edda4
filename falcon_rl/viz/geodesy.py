"""Local north-east-down offsets <-> geodetic latitude, longitude and altitude on the WGS-84 ellipsoid.

The simulator flies in a flat NED frame about a local origin. Viewers (Tacview, FlightGear) want
geodetic coordinates, so the origin is pinned to a :class:`ReferencePoint` and offsets are converted
exactly, without a flat-earth approximation:

1. the reference point (geodetic) -> ECEF,
2. the NED offset is rotated into ECEF with the reference point's local-level rotation and added,
3. ECEF -> geodetic with Heikkinen's closed form (Zhu 1993), polished by one fixed-point step of
   Bowring's latitude iteration, the altitude taken from the stable formula
   ``h = p cos(lat) + z sin(lat) - a sqrt(1 - e^2 sin^2(lat))``.

Accuracy: the conversion is exact up to float64 round-off. Round trips NED -> geodetic -> NED agree to
better than 1e-6 m for offsets up to 100 km and heights up to 100 km (the tests check 1 mm over
10 km). Altitudes are heights above the ellipsoid; the geoid (mean sea level) is not modelled, so set
``altitude_m`` of the reference point to the ground elevation that the viewer uses at that place.
The NED ``down`` axis is the ellipsoid normal at the reference point, so over a few km the altitude
of a point at constant ``z`` rises by about d^2 / (2 R) (8 cm at 1 km, 7.8 m at 10 km): the earth
curves away below the flat simulated world.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: WGS-84 semi-major axis, m.
WGS84_A = 6_378_137.0
#: WGS-84 flattening.
WGS84_F = 1.0 / 298.257223563
#: WGS-84 semi-minor axis, m.
WGS84_B = WGS84_A * (1.0 - WGS84_F)
#: First eccentricity squared.
WGS84_E2 = WGS84_F * (2.0 - WGS84_F)
#: Second eccentricity squared.
WGS84_EP2 = WGS84_E2 / (1.0 - WGS84_E2)


@dataclass(frozen=True)
class ReferencePoint:
    """The geodetic position of the NED origin: latitude and longitude in degrees (north and east
    positive), altitude in metres above the WGS-84 ellipsoid (used as mean sea level by the viewers).

    The default is San Francisco International airport (KSFO, aerodrome reference point, 4 m): it is
    FlightGear's default airport, whose scenery every FlightGear installation carries, and Tacview
    shows it on its built-in globe. Pass another point for any other place."""

    latitude_deg: float = 37.618889
    longitude_deg: float = -122.375
    altitude_m: float = 4.0
    name: str = "KSFO"

    def __post_init__(self) -> None:
        for label in ("latitude_deg", "longitude_deg", "altitude_m"):
            value = getattr(self, label)
            if not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ValueError(f"ReferencePoint.{label} must be a finite number, got {value!r}")
        if not -90.0 < self.latitude_deg < 90.0:
            raise ValueError(f"ReferencePoint.latitude_deg must be in (-90, 90), got {self.latitude_deg}")
        if not -180.0 <= self.longitude_deg <= 180.0:
            raise ValueError(f"ReferencePoint.longitude_deg must be in [-180, 180], got {self.longitude_deg}")
        if not -1.0e4 < self.altitude_m < 1.0e5:
            raise ValueError(f"ReferencePoint.altitude_m must be in (-1e4, 1e5) m, got {self.altitude_m}")


#: The reference point used when none is given.
DEFAULT_REFERENCE = ReferencePoint()


def _check_points(name: str, array: np.ndarray) -> np.ndarray:
    array = np.asarray(array, dtype=np.float64)
    if array.ndim < 1 or array.shape[-1] != 3:
        raise ValueError(f"{name} must have shape [..., 3], got {array.shape}")
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{name} has non-finite values")
    return array


def _ned_to_ecef_rotation(lat_rad: float, lon_rad: float) -> np.ndarray:
    """[3, 3] rotation whose columns are the north, east and down unit vectors in ECEF."""
    sl, cl = math.sin(lat_rad), math.cos(lat_rad)
    so, co = math.sin(lon_rad), math.cos(lon_rad)
    return np.array([[-sl * co, -so, -cl * co],
                     [-sl * so, co, -cl * so],
                     [cl, 0.0, -sl]])


def geodetic_to_ecef(lat_deg: np.ndarray | float, lon_deg: np.ndarray | float,
                     alt_m: np.ndarray | float) -> np.ndarray:
    """Geodetic (deg, deg, m above the ellipsoid), broadcast to [...] -> ECEF [..., 3] m."""
    lat, lon = np.radians(np.asarray(lat_deg, np.float64)), np.radians(np.asarray(lon_deg, np.float64))
    alt = np.asarray(alt_m, np.float64)
    sin_lat = np.sin(lat)
    n = WGS84_A / np.sqrt(1.0 - WGS84_E2 * sin_lat**2)
    x = (n + alt) * np.cos(lat) * np.cos(lon)
    y = (n + alt) * np.cos(lat) * np.sin(lon)
    z = (n * (1.0 - WGS84_E2) + alt) * sin_lat
    return np.stack(np.broadcast_arrays(x, y, z), axis=-1)


def ecef_to_geodetic(ecef: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """ECEF [..., 3] m -> (lat_deg [...], lon_deg [...], alt_m [...]) on WGS-84 (Heikkinen / Zhu closed
    form plus one Bowring refinement; exact to float64 round-off away from the earth's centre)."""
    ecef = _check_points("ecef", ecef)
    x, y, z = ecef[..., 0], ecef[..., 1], ecef[..., 2]
    a, b, e2, ep2 = WGS84_A, WGS84_B, WGS84_E2, WGS84_EP2
    p = np.hypot(x, y)
    if np.any(p**2 + z**2 < 1.0e10):
        raise ValueError("ecef points within 100 km of the earth's centre have no useful geodetic position")
    f = 54.0 * b**2 * z**2
    g = p**2 + (1.0 - e2) * z**2 - e2 * (a**2 - b**2)
    c = e2**2 * f * p**2 / g**3
    s = np.cbrt(1.0 + c + np.sqrt(c**2 + 2.0 * c))
    k = s + 1.0 + 1.0 / s
    pp = f / (3.0 * k**2 * g**2)
    q = np.sqrt(1.0 + 2.0 * e2**2 * pp)
    r0 = -(pp * e2 * p) / (1.0 + q) + np.sqrt(np.maximum(
        0.5 * a**2 * (1.0 + 1.0 / q) - pp * (1.0 - e2) * z**2 / (q * (1.0 + q)) - 0.5 * pp * p**2, 0.0))
    v = np.sqrt((p - e2 * r0) ** 2 + (1.0 - e2) * z**2)
    z0 = b**2 * z / (a * v)
    lat = np.arctan2(z + ep2 * z0, p)
    # one Bowring step: lat = atan2(z, p (1 - e^2 N / (N + h))) with the stable altitude formula
    sin_lat, cos_lat = np.sin(lat), np.cos(lat)
    n = a / np.sqrt(1.0 - e2 * sin_lat**2)
    h = p * cos_lat + z * sin_lat - a * np.sqrt(1.0 - e2 * sin_lat**2)
    lat = np.arctan2(z, p * (1.0 - e2 * n / (n + h)))
    sin_lat, cos_lat = np.sin(lat), np.cos(lat)
    alt = p * cos_lat + z * sin_lat - a * np.sqrt(1.0 - e2 * sin_lat**2)
    lon = np.arctan2(y, x)
    return np.degrees(lat), np.degrees(lon), alt


def ned_to_geodetic(reference: ReferencePoint | None, ned: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """NED offsets [..., 3] m about ``reference`` (None: :data:`DEFAULT_REFERENCE`) ->
    (lat_deg [...], lon_deg [...], alt_m [...]), exact on WGS-84 (see the module docstring)."""
    ref = reference or DEFAULT_REFERENCE
    ned = _check_points("ned", ned)
    origin = geodetic_to_ecef(ref.latitude_deg, ref.longitude_deg, ref.altitude_m)
    rotation = _ned_to_ecef_rotation(math.radians(ref.latitude_deg), math.radians(ref.longitude_deg))
    return ecef_to_geodetic(origin + ned @ rotation.T)


def geodetic_to_ned(reference: ReferencePoint | None, lat_deg: np.ndarray | float,
                    lon_deg: np.ndarray | float, alt_m: np.ndarray | float) -> np.ndarray:
    """Geodetic (deg, deg, m; broadcast to [...]) -> NED offsets [..., 3] m about ``reference``
    (None: :data:`DEFAULT_REFERENCE`); the inverse of :func:`ned_to_geodetic`."""
    ref = reference or DEFAULT_REFERENCE
    for label, value in (("lat_deg", lat_deg), ("lon_deg", lon_deg), ("alt_m", alt_m)):
        if not np.all(np.isfinite(np.asarray(value, dtype=np.float64))):
            raise ValueError(f"{label} has non-finite values")
    if np.any(np.abs(np.asarray(lat_deg, dtype=np.float64)) > 90.0):
        raise ValueError("lat_deg must be within [-90, 90]")
    origin = geodetic_to_ecef(ref.latitude_deg, ref.longitude_deg, ref.altitude_m)
    rotation = _ned_to_ecef_rotation(math.radians(ref.latitude_deg), math.radians(ref.longitude_deg))
    return (geodetic_to_ecef(lat_deg, lon_deg, alt_m) - origin) @ rotation


__all__ = ["DEFAULT_REFERENCE", "WGS84_A", "WGS84_E2", "WGS84_F", "ReferencePoint", "ecef_to_geodetic",
           "geodetic_to_ecef", "geodetic_to_ned", "ned_to_geodetic"]


def euler_to_dcm(euler: np.ndarray) -> np.ndarray:
    """Aerospace ZYX Euler angles [..., 3] rad (roll, pitch, yaw) -> body-to-level DCM [..., 3, 3]."""
    euler = np.asarray(euler, dtype=np.float64)
    cr, sr = np.cos(euler[..., 0]), np.sin(euler[..., 0])
    cp, sp = np.cos(euler[..., 1]), np.sin(euler[..., 1])
    cy, sy = np.cos(euler[..., 2]), np.sin(euler[..., 2])
    rows = [[cp * cy, sr * sp * cy - cr * sy, cr * sp * cy + sr * sy],
            [cp * sy, sr * sp * sy + cr * cy, cr * sp * sy - sr * cy],
            [-sp, sr * cp, cr * cp]]
    return np.stack([np.stack(row, axis=-1) for row in rows], axis=-2)


def dcm_to_euler(dcm: np.ndarray) -> np.ndarray:
    """Body-to-level DCM [..., 3, 3] -> aerospace ZYX Euler angles [..., 3] rad (yaw in (-pi, pi])."""
    roll = np.arctan2(dcm[..., 2, 1], dcm[..., 2, 2])
    pitch = np.arcsin(np.clip(-dcm[..., 2, 0], -1.0, 1.0))
    yaw = np.arctan2(dcm[..., 1, 0], dcm[..., 0, 0])
    return np.stack([roll, pitch, yaw], axis=-1)


def _level_change(reference: ReferencePoint | None, ned: np.ndarray) -> np.ndarray:
    """[..., 3, 3] rotation from the reference point's NED axes to the local NED axes at ``ned``."""
    ref = reference or DEFAULT_REFERENCE
    lat, lon, _ = ned_to_geodetic(ref, ned)
    lat, lon = np.radians(lat), np.radians(lon)
    sl, cl, so, co = np.sin(lat), np.cos(lat), np.sin(lon), np.cos(lon)
    zero = np.zeros_like(lat)
    local = np.stack([np.stack([-sl * co, -so, -cl * co], -1), np.stack([-sl * so, co, -cl * so], -1),
                      np.stack([cl, zero, -sl], -1)], axis=-2)  # columns: local N, E, D in ECEF
    origin = _ned_to_ecef_rotation(math.radians(ref.latitude_deg), math.radians(ref.longitude_deg))
    return np.swapaxes(local, -1, -2) @ origin


def euler_to_local_level(reference: ReferencePoint | None, ned: np.ndarray, euler: np.ndarray) -> np.ndarray:
    """Attitude [..., 3] rad about the reference point's NED axes -> about the local north-east-down axes
    at the aircraft's position ``ned`` [..., 3] m (what viewers call roll, pitch and true heading). The
    two differ by the meridian convergence, about 0.007 deg per km east at 37 deg latitude."""
    ned, euler = _check_points("ned", ned), _check_points("euler", euler)
    return dcm_to_euler(_level_change(reference, ned) @ euler_to_dcm(euler))


def euler_from_local_level(reference: ReferencePoint | None, ned: np.ndarray, euler: np.ndarray
                           ) -> np.ndarray:
    """The inverse of :func:`euler_to_local_level`: local-level attitude [..., 3] rad at ``ned`` ->
    attitude about the reference point's NED axes [..., 3] rad."""
    ned, euler = _check_points("ned", ned), _check_points("euler", euler)
    return dcm_to_euler(np.swapaxes(_level_change(reference, ned), -1, -2) @ euler_to_dcm(euler))


__all__ += ["dcm_to_euler", "euler_from_local_level", "euler_to_dcm", "euler_to_local_level"]
