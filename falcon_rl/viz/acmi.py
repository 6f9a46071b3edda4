"""Tacview ACMI 2.2 flight recordings: :func:`write_acmi` exports a
:class:`~falcon_rl.recording.Recording` and :func:`read_acmi`
parses a file back (for tests and for checking a file without Tacview).

The format (Tacview's public "ACMI flight recordings 2.2" reference) is UTF-8 text::

    FileType=text/acmi/tacview
    FileVersion=2.2
    0,ReferenceTime=2024-01-01T12:00:00Z
    0,ReferenceLongitude=-122.375
    0,ReferenceLatitude=37.618889
    0,Title=...
    #0
    101,T=0.000012|-0.000003|104|1.5|2.1|270|,Name=Ranger 0,Type=Air+FixedWing,Color=Blue,TAS=18
    #0.02
    101,T=0.000021||104.2|||270.5,TAS=18.1
    ...

Lines are global properties (object ``0``), frame times ``#<seconds after ReferenceTime>`` and object
lines ``<hex id>,<property>=<value>,...``. ``T=lon|lat|alt|roll|pitch|yaw`` gives the position in
degrees and metres and the attitude in degrees (roll positive right wing down, pitch positive nose
up, yaw clockwise from true north); longitude and latitude are offsets from ``ReferenceLongitude`` and
``ReferenceLatitude``. An empty component keeps its previous value, so later lines carry only what
changed. Commas in text values are escaped as ``\\,``. A ``.zip.acmi`` file is a zip archive holding
one text ``.txt.acmi`` file.

The exporter places the NED origin at a :class:`~falcon_rl.viz.geodesy.ReferencePoint` (exact WGS-84
conversion) and rotates each attitude onto the local level at the aircraft (meridian convergence).
Numbers are written with 1e-9 deg (0.1 mm) in position, 1 mm in altitude and 1e-4 deg in attitude.
Besides ``T`` it writes, where recorded, ``TAS`` (m/s, the recorded airspeed), ``IAS`` (m/s, the
equivalent airspeed in the ISA atmosphere, equal to the indicated airspeed at these low speeds),
``AOA`` and ``AOS`` (deg), ``AGL`` (m, the CG height above the surface under it: the ground, or the
water of a sea, ``surface_clearance`` where recorded, else ``height``) and ``Throttle`` (0..1, mean
over motors). A recording over the sea also names its sea in the global ``Comments`` and writes a marker
riding the water under each aircraft that carries the wave field (:mod:`.acmi_sea`). Files are written
whole or not at all (:func:`falcon_rl.atomic_files.write_atomic`).

:func:`read_acmi` streams the file line by line and keeps, per object, only the values its lines set
and the frames where it is alive, so that time and memory grow with the file, not with objects x
frames; the per-frame arrays of an :class:`AcmiTrack` are built when first asked for. A malformed
file is an :class:`AcmiParseError` (a ValueError) of one line naming the file and the line.
"""

from __future__ import annotations

import codecs
import math
import zipfile
import zlib
from array import array
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from datetime import datetime, timezone
from functools import cached_property
from pathlib import Path
from typing import IO

import numpy as np

from ..atomic_files import serialized, write_atomic
from ..constants import G0, LAPSE, R_AIR, T0
from ..recording import Recording, quaternion_euler
from .acmi_sea import FIRST_SEA_ID, SEA_MARKER_TYPE, SeaTrack, sea_comments, sea_tracks, wave_field_text
from .geodesy import DEFAULT_REFERENCE, ReferencePoint, euler_to_local_level, ned_to_geodetic

#: The file type and version lines every ACMI file starts with.
ACMI_HEADER = ("FileType=text/acmi/tacview", "FileVersion=2.2")
#: Colors Tacview knows, used in turn for the aircraft when none are given.
ACMI_COLORS: tuple[str, ...] = ("Blue", "Red", "Green", "Orange", "Yellow", "Cyan", "Violet")
#: Object type of every aircraft.
AIRCRAFT_TYPE = "Air+FixedWing"
#: The id of aircraft ``e`` is ``FIRST_OBJECT_ID + e`` (written in hex).
FIRST_OBJECT_ID = 0x101
# decimals written for each T component: lon, lat (deg offsets), alt (m), roll, pitch, yaw (deg)
_T_DECIMALS = (9, 9, 3, 4, 4, 4)


def escape_text(value: str) -> str:
    """A text property value with backslashes and commas escaped (``\\\\``, ``\\,``) and line breaks
    replaced by spaces."""
    return str(value).replace("\\", "\\\\").replace("\r", " ").replace("\n", " ").replace(",", "\\,")


def format_number(value: float, decimals: int) -> str:
    """``value`` with ``decimals`` decimals, trailing zeros dropped (``-0`` written ``0``)."""
    text = f"{value:.{decimals}f}"
    if "." in text:
        text = text.rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


def format_reference_time(when: datetime) -> str:
    """ISO 8601 UTC with a ``Z`` suffix, e.g. ``2024-01-01T12:00:00Z`` (naive datetimes are UTC)."""
    if when.tzinfo is not None:
        when = when.astimezone(timezone.utc).replace(tzinfo=None)
    text = when.isoformat(timespec="milliseconds" if when.microsecond else "seconds")
    return text + "Z"


def acmi_header(reference: ReferencePoint | None = None, reference_time: datetime | None = None,
                title: str | None = None, author: str | None = None, comments: str | None = None,
                data_source: str = "falcon-rl") -> list[str]:
    """The header lines (file type, version, then the global object ``0``'s properties)."""
    ref = reference or DEFAULT_REFERENCE
    when = reference_time or datetime.now(timezone.utc).replace(microsecond=0)
    lines = [*ACMI_HEADER, f"0,ReferenceTime={format_reference_time(when)}",
             f"0,ReferenceLongitude={ref.longitude_deg!r}", f"0,ReferenceLatitude={ref.latitude_deg!r}",
             f"0,DataSource={escape_text(data_source)}"]
    for key, value in (("Title", title), ("Author", author), ("Comments", comments)):
        if value:
            lines.append(f"0,{key}={escape_text(value)}")
    return lines


class AcmiObjectEncoder:
    """Writes the lines of one object: the first carries every ``T`` component and the static text
    properties; later ones only the components and properties whose written text changed."""

    def __init__(self, object_id: int, name: str, color: str | None = None, kind: str = AIRCRAFT_TYPE,
                 extra: Mapping[str, str] | None = None) -> None:
        if not isinstance(object_id, int) or object_id <= 0:
            raise ValueError(f"object_id must be a positive int, got {object_id!r}")
        self.object_id = object_id
        self.static: dict[str, str] = {"Name": escape_text(name), "Type": kind}
        if color:
            self.static["Color"] = escape_text(color)
        self.static.update({k: escape_text(v) for k, v in (extra or {}).items()})
        self._last_t: list[str] | None = None
        self._last_props: dict[str, str] = {}

    @property
    def hex_id(self) -> str:
        """The id as written in the file (lowercase hex, no prefix)."""
        return format(self.object_id, "x")

    def line(self, lon_offset_deg: float, lat_offset_deg: float, alt_m: float, roll_deg: float,
             pitch_deg: float, yaw_deg: float, properties: Mapping[str, float] | None = None,
             decimals: Mapping[str, int] | None = None) -> str | None:
        """The object's line for one frame (None when nothing changed). ``properties`` are numeric
        (written with ``decimals[name]`` decimals, default 2); non-finite ones are left out."""
        values = (lon_offset_deg, lat_offset_deg, alt_m, roll_deg, pitch_deg, yaw_deg)
        if not all(math.isfinite(v) for v in values):
            raise ValueError(f"object {self.hex_id}: non-finite position or attitude {values}")
        texts = [format_number(v, d) for v, d in zip(values, _T_DECIMALS, strict=True)]
        parts: list[str] = []
        if self._last_t is None:
            parts.append("T=" + "|".join(texts))
        elif texts != self._last_t:
            parts.append("T=" + "|".join("" if new == old else new
                                         for new, old in zip(texts, self._last_t, strict=True)))
        first = self._last_t is None
        self._last_t = texts
        for key, value in (properties or {}).items():
            if not math.isfinite(float(value)):
                continue
            text = format_number(float(value), (decimals or {}).get(key, 2))
            if self._last_props.get(key) != text:
                parts.append(f"{key}={text}")
                self._last_props[key] = text
        if first:
            parts.extend(f"{k}={v}" for k, v in self.static.items())
        return f"{self.hex_id}," + ",".join(parts) if parts else None


def isa_density_ratio(altitude_m: np.ndarray) -> np.ndarray:
    """rho / rho0 of the ISA troposphere at ``altitude_m`` [...] m."""
    temperature = T0 + LAPSE * np.clip(np.asarray(altitude_m, np.float64), -1000.0, 11000.0)
    return (temperature / T0) ** (-G0 / (LAPSE * R_AIR) - 1.0)


def recording_geodetic(rec: Recording, reference: ReferencePoint | None = None
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(lat_deg, lon_deg, alt_m) [T, E] and the local-level attitude [T, E, 3] rad of every frame of
    ``rec`` (attitude from ``euler``, else from ``quaternion``)."""
    ned = np.asarray(rec["position_ned"], dtype=np.float64)
    if not np.all(np.isfinite(ned)):
        raise ValueError("recording position_ned has non-finite values")
    euler = (np.asarray(rec["euler"], np.float64) if rec.has("euler")
             else quaternion_euler(np.asarray(rec["quaternion"])))
    if euler.shape != ned.shape or not np.all(np.isfinite(euler)):
        raise ValueError(f"recording attitude must be finite with shape {ned.shape}, got {euler.shape}")
    lat, lon, alt = ned_to_geodetic(reference, ned)
    return lat, lon, alt, euler_to_local_level(reference, ned, euler)


def _numeric_properties(rec: Recording, alt: np.ndarray) -> tuple[dict[str, np.ndarray], dict[str, int]]:
    props: dict[str, np.ndarray] = {}
    if rec.has("airspeed"):
        tas = np.asarray(rec["airspeed"], np.float64)
        props["TAS"] = tas
        props["IAS"] = tas * np.sqrt(isa_density_ratio(alt))
    if rec.has("alpha"):
        props["AOA"] = np.degrees(np.asarray(rec["alpha"], np.float64))
    if rec.has("beta"):
        props["AOS"] = np.degrees(np.asarray(rec["beta"], np.float64))
    if rec.has("surface_clearance"):
        props["AGL"] = np.asarray(rec["surface_clearance"], np.float64)
    elif rec.has("height"):
        props["AGL"] = np.asarray(rec["height"], np.float64)
    if rec.has("throttle"):
        props["Throttle"] = np.asarray(rec["throttle"], np.float64).reshape(rec.num_frames, rec.num_envs,
                                                                            -1).mean(axis=-1)
    return props, {"Throttle": 3}


def _check_names(kind: str, values: Sequence[str] | None, count: int) -> list[str] | None:
    if values is None:
        return None
    values = list(values)
    if len(values) != count:
        raise ValueError(f"{kind} must have one entry per aircraft ({count}), got {len(values)}")
    return [str(v) for v in values]


def write_acmi(rec: Recording, path: str | Path, reference: ReferencePoint | None = None,
               names: Sequence[str] | None = None, colors: Sequence[str] | None = None, *,
               reference_time: datetime | None = None, title: str | None = None,
               author: str | None = None, comments: str | None = None) -> Path:
    """Write ``rec`` (all E aircraft) as a Tacview ACMI 2.2 file and return its path.

    ``path`` ending in ``.zip.acmi`` gives a zip archive holding one ``.txt.acmi`` file; any other
    ``.acmi`` path a text file. ``reference`` places the NED origin (default
    :data:`~falcon_rl.viz.geodesy.DEFAULT_REFERENCE`); ``names`` [E] default to ``meta["labels"]``,
    ``colors`` [E] to :data:`ACMI_COLORS` in turn; ``reference_time`` (default now, UTC) is the
    wall-clock time of simulated time 0 and the frames are ``#<rec.time>`` seconds after it (shifted
    to start at 0 when the recording starts at a negative time)."""
    path = Path(path)
    if not path.name.endswith(".acmi"):
        raise ValueError(f"path must end with .acmi or .zip.acmi, got {path.name!r}")
    envs = rec.num_envs
    names = _check_names("names", names, envs) or [str(x) for x in rec.meta.get("labels", [])]
    if len(names) != envs:
        names = [f"aircraft {e}" for e in range(envs)]
    colors = _check_names("colors", colors, envs) or [ACMI_COLORS[e % len(ACMI_COLORS)] for e in range(envs)]
    ref = reference or DEFAULT_REFERENCE
    airframe = rec.meta.get("airframe")
    lat, lon, alt, attitude = recording_geodetic(rec, ref)
    attitude = np.degrees(attitude)
    yaw = np.mod(attitude[..., 2], 360.0)
    attitude[..., 2] = np.where(yaw >= 360.0 - 5e-5, yaw - 360.0, yaw)  # never written as 360
    props, decimals = _numeric_properties(rec, alt)
    time = rec.time - min(0.0, float(rec.time[0]))
    if not np.all(np.isfinite(time)):
        raise ValueError("recording time has non-finite values")
    sea = sea_comments(rec)
    comments = " | ".join(text for text in (comments, sea) if text) or None
    lines = acmi_header(ref, reference_time, title=title or f"falcon-rl recording ({airframe or 'aircraft'})",
                        author=author, comments=comments)
    encoders = [AcmiObjectEncoder(FIRST_OBJECT_ID + e, names[e], colors[e],
                                  extra={"ShortName": str(airframe)} if airframe else None)
                for e in range(envs)]
    markers = [_SeaMarker(track, encoders[track.env], names[track.env], colors[track.env], ref)
               for track in sea_tracks(rec, ref, time)]
    for k in range(rec.num_frames):
        lines.append("#" + format_number(float(time[k]), 6))
        for e, encoder in enumerate(encoders):
            line = encoder.line(float(lon[k, e] - ref.longitude_deg), float(lat[k, e] - ref.latitude_deg),
                                float(alt[k, e]), *(float(a) for a in attitude[k, e]),
                                properties={key: float(value[k, e]) for key, value in props.items()},
                                decimals=decimals)
            if line is not None:
                lines.append(line)
        for marker in markers:
            lines.extend(marker.lines(k))
    text = "\n".join(lines) + "\n"
    if path.name.endswith(".zip.acmi"):
        member = path.name[: -len(".zip.acmi")] + ".txt.acmi"
        return write_atomic(path, serialized(lambda stream: _zip_one(stream, member, text)))
    return write_atomic(path, text)


class _SeaMarker:
    """The lines of the marker riding the water under one aircraft (:mod:`.acmi_sea`): written while the
    aircraft is over its sea, removed while it is not, written anew with its properties when the field
    changes."""

    def __init__(self, track: SeaTrack, aircraft: AcmiObjectEncoder, name: str, color: str,
                 reference: ReferencePoint) -> None:
        self.track, self.aircraft, self.name, self.color = track, aircraft, name, color
        self.reference = reference
        self.encoder: AcmiObjectEncoder | None = None
        self.field = -1

    def lines(self, frame: int) -> list[str]:
        index = int(self.track.field[frame])
        if index < 0:
            removed = [f"-{self.encoder.hex_id}"] if self.encoder is not None else []
            self.encoder, self.field = None, -1
            return removed
        if self.encoder is None or index != self.field:
            field = self.track.fields[index]
            self.encoder = AcmiObjectEncoder(
                FIRST_SEA_ID + self.track.env, f"sea under {self.name}", self.color, kind=SEA_MARKER_TYPE,
                extra={"Parent": self.aircraft.hex_id, "SeaState": str(field.sea_state),
                       "WaveHeight": format_number(field.significant_height, 3),
                       "WaveField": wave_field_text(field)})
            self.field = index
        clock = {} if self.track.clock is None else {"WaveClock": float(self.track.clock[frame])}
        line = self.encoder.line(float(self.track.lon[frame] - self.reference.longitude_deg),
                                 float(self.track.lat[frame] - self.reference.latitude_deg),
                                 float(self.track.alt[frame]), 0.0, 0.0, 0.0, clock, {"WaveClock": 3})
        return [line] if line is not None else []


def _zip_one(stream: IO[bytes], member: str, text: str) -> None:
    """Write a zip archive holding ``text`` as the one file ``member`` to ``stream``."""
    with zipfile.ZipFile(stream, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        archive.writestr(member, text.encode("utf-8"))


# ------------------------------------------------------------------------------------------- reading
#: The ``T=`` component names of each form (by number of components).
_COORD_LAYOUT = {3: ("lon", "lat", "alt"), 5: ("lon", "lat", "alt", "u", "v"),
                 6: ("lon", "lat", "alt", "roll", "pitch", "yaw"),
                 9: ("lon", "lat", "alt", "roll", "pitch", "yaw", "u", "v", "heading")}
#: The ``T=`` components an :class:`AcmiTrack` keeps, in order.
_TRACK_COORDS = ("lon", "lat", "alt", "roll", "pitch", "yaw")
#: Global properties that must be numbers.
_NUMERIC_HEADER = ("ReferenceLongitude", "ReferenceLatitude")


class AcmiParseError(ValueError):
    """A file that breaks the ACMI format; the one-line message names the file and the line."""


class _Steps:
    """A piecewise-constant series of ``width`` values, set at frame indices (the last set in a frame
    wins) and kept in between: storage proportional to the number of sets, not of frames."""

    def __init__(self, width: int) -> None:
        self.width = width
        self.frames = array("q")
        self.values = array("d")

    def set(self, frame: int, values: Sequence[float]) -> None:
        if self.frames and self.frames[-1] == frame:
            self.values[-self.width:] = array("d", values)
        else:
            self.frames.append(frame)
            self.values.extend(values)

    def at(self, frames: np.ndarray) -> np.ndarray:
        """The values [K, width] at the frame indices ``frames`` [K] (NaN before the first set)."""
        known = np.array(self.frames, dtype=np.int64)
        values = np.array(self.values, dtype=np.float64).reshape(-1, self.width)
        index = np.searchsorted(known, frames, side="right") - 1
        out = np.full((len(frames), self.width), math.nan)
        out[index >= 0] = values[index[index >= 0]]
        return out


@dataclass
class _ObjectState:
    """What the reader knows of one object: the frame spans [start, end) where it is alive (end None:
    still alive), its coordinates and numeric properties where lines set them, its last text
    properties and the last value of each coordinate."""

    alive: list[list[int | None]] = field(default_factory=list)
    coords: _Steps = field(default_factory=lambda: _Steps(len(_TRACK_COORDS)))
    numeric: dict[str, _Steps] = field(default_factory=dict)
    text: dict[str, str] = field(default_factory=dict)
    last: list[float] = field(default_factory=lambda: [math.nan] * len(_TRACK_COORDS))

    def appear(self, frame: int) -> None:
        """Alive from ``frame`` on (a span ended in this very frame is reopened)."""
        if self.alive and self.alive[-1][1] is None:
            return
        if self.alive and self.alive[-1][1] == frame:
            self.alive[-1][1] = None
        else:
            self.alive.append([frame, None])

    def remove(self, frame: int) -> None:
        """Removed in ``frame`` (not alive at its end); an empty span is dropped."""
        if self.alive and self.alive[-1][1] is None:
            if self.alive[-1][0] == frame:
                self.alive.pop()
            else:
                self.alive[-1][1] = frame

    def spans(self, num_frames: int) -> list[tuple[int, int]]:
        """The spans [start, end) of a file of ``num_frames`` frames."""
        return [(int(start), num_frames if end is None else int(end)) for start, end in self.alive]


class AcmiTrack:
    """One object of a parsed file: ``object_id`` (hex, lowercase), its last text ``properties`` and,
    at every frame from its first appearance to its removal (again from a reappearance), ``time`` [K]
    s, absolute ``longitude``/``latitude`` [K] deg, ``altitude`` [K] m, ``roll``/``pitch``/``yaw`` [K]
    deg and the numeric properties ``values`` {name: [K]} (NaN before a property's first value or
    after a non-numeric one).

    The parser stores only what the file holds (each value where a line sets it, and the frames the
    object is alive); these per-frame arrays are built on first access."""

    def __init__(self, object_id: str, properties: dict[str, str], frame_times: np.ndarray,
                 alive: Sequence[tuple[int, int]], coords: _Steps, numeric: Mapping[str, _Steps],
                 reference: tuple[float, float]) -> None:
        self.object_id = object_id
        self.properties = properties
        self._frame_times = frame_times
        self._alive = list(alive)
        self._coords = coords
        self._numeric = dict(numeric)
        self._reference = reference

    @cached_property
    def frame_index(self) -> np.ndarray:
        """Indices [K] into :attr:`AcmiFile.frames` of the frames where the object is alive."""
        spans = [np.arange(start, end, dtype=np.int64) for start, end in self._alive]
        return np.concatenate(spans) if spans else np.zeros(0, np.int64)

    @property
    def num_frames(self) -> int:
        """K, the frames where the object is alive (without building them)."""
        return sum(end - start for start, end in self._alive)

    @cached_property
    def time(self) -> np.ndarray:
        """[K] s."""
        return self._frame_times[self.frame_index]

    @cached_property
    def _coordinates(self) -> np.ndarray:
        return self._coords.at(self.frame_index)

    @property
    def longitude(self) -> np.ndarray:
        """[K] deg, absolute."""
        return self._coordinates[:, 0] + self._reference[0]

    @property
    def latitude(self) -> np.ndarray:
        """[K] deg, absolute."""
        return self._coordinates[:, 1] + self._reference[1]

    @property
    def altitude(self) -> np.ndarray:
        """[K] m."""
        return self._coordinates[:, 2]

    @property
    def roll(self) -> np.ndarray:
        """[K] deg."""
        return self._coordinates[:, 3]

    @property
    def pitch(self) -> np.ndarray:
        """[K] deg."""
        return self._coordinates[:, 4]

    @property
    def yaw(self) -> np.ndarray:
        """[K] deg."""
        return self._coordinates[:, 5]

    @cached_property
    def values(self) -> dict[str, np.ndarray]:
        """The numeric properties {name: [K]}."""
        return {name: steps.at(self.frame_index)[:, 0] for name, steps in sorted(self._numeric.items())}


@dataclass
class AcmiFile:
    """A parsed ACMI file: ``header`` (FileType, FileVersion and the global object's properties),
    ``frames`` [F] s (every ``#`` line, in order) and ``objects`` {hex id: :class:`AcmiTrack`}."""

    header: dict[str, str]
    frames: np.ndarray
    objects: dict[str, AcmiTrack]


def _split_unescaped(text: str, separator: str) -> list[str]:
    """``text`` split at the separators not escaped by a backslash, escapes of the separator and of
    the backslash removed."""
    if "\\" not in text:
        return text.split(separator)
    parts, current, escaped = [], [], False
    for char in text:
        if escaped:
            current.append(char if char in (separator, "\\", "\n") else "\\" + char)
            escaped = False
        elif char == "\\":
            escaped = True
        elif char == separator:
            parts.append("".join(current))
            current = []
        else:
            current.append(char)
    if escaped:
        current.append("\\")
    parts.append("".join(current))
    return parts


def _logical_lines(lines: Iterable[str]) -> Iterator[tuple[int, str]]:
    """(number of its first physical line, text) of each logical line of the physical ``lines``
    (line breaks removed): lines are joined where one ends in an odd number of backslashes."""
    pending: str | None = None
    start = 0
    for number, raw in enumerate(lines, start=1):
        if pending is None:
            start, line = number, raw
        else:
            line = pending + "\n" + raw
        if (len(raw) - len(raw.rstrip("\\"))) % 2 == 1:
            pending = line[:-1]
            continue
        pending = None
        yield start, line
    if pending is not None:
        yield start, pending


class _AcmiReader:
    """Parses ACMI lines one at a time into per-object sparse series (memory and time linear in what
    the file holds); :meth:`result` builds the :class:`AcmiFile`."""

    def __init__(self, source: str) -> None:
        self.source = source
        self.header: dict[str, str] = {}
        self.frames: list[float] = []
        self.objects: dict[str, _ObjectState] = {}

    def fail(self, number: int, what: str) -> AcmiParseError:
        return AcmiParseError(f"{self.source}, line {number}: {what}")

    def read(self, lines: Iterable[tuple[int, str]]) -> AcmiFile:
        lines = iter(lines)
        for key in ("FileType", "FileVersion"):
            number, line = next(lines, (len(self.header) + 1, ""))
            if not line.startswith(key + "="):
                raise self.fail(number, "not an ACMI file: the first lines must be FileType= and "
                                        "FileVersion=")
            self.header[key] = line.split("=", 1)[1]
        for number, line in lines:
            self.line(number, line)
        return self.result()

    @property
    def frame(self) -> int:
        """Index of the frame the lines now read belong to (lines before the first ``#`` go to frame 0)."""
        return max(len(self.frames) - 1, 0)

    def line(self, number: int, line: str) -> None:
        if not line.strip() or line.startswith("//"):
            return
        if line.startswith("#"):
            self.frames.append(self.number(number, "frame time", line[1:]))
        elif line.startswith("-"):
            state = self.objects.get(line[1:].strip().lower())
            if state is not None:
                state.remove(self.frame)
        else:
            fields = _split_unescaped(line, ",")
            pairs = [item.split("=", 1) for item in fields[1:] if "=" in item]
            self.properties(number, fields[0].strip().lower(), pairs)

    def number(self, number: int, what: str, text: str) -> float:
        try:
            return float(text)
        except ValueError:
            raise self.fail(number, f"bad {what} {text[:40]!r} (expected a number)") from None

    def properties(self, number: int, oid: str, properties: list[list[str]]) -> None:
        if oid == "0":
            for key, value in properties:
                if key in _NUMERIC_HEADER:
                    self.number(number, key, value)
                self.header[key] = value
            return
        try:
            int(oid, 16)
        except ValueError:
            raise self.fail(number, f"bad object id {oid[:40]!r} (expected hexadecimal)") from None
        state = self.objects.setdefault(oid, _ObjectState())
        state.appear(self.frame)
        for key, value in properties:
            if key == "T":
                self.coordinates(number, state, value)
            else:
                self.property(state, key, value)

    def coordinates(self, number: int, state: _ObjectState, value: str) -> None:
        components = value.split("|")
        layout = _COORD_LAYOUT.get(len(components))
        if layout is None:
            raise self.fail(number, f"T has {len(components)} components, expected 3, 5, 6 or 9")
        for name, component in zip(layout, components, strict=True):
            if component.strip():
                parsed = self.number(number, f"T component {name}", component)
                if name in _TRACK_COORDS:
                    state.last[_TRACK_COORDS.index(name)] = parsed
        state.coords.set(self.frame, state.last)

    def property(self, state: _ObjectState, key: str, value: str) -> None:
        state.text[key] = value
        try:
            parsed = float(value)
        except ValueError:
            parsed = None
        numeric = state.numeric
        if parsed is not None:
            numeric.setdefault(key, _Steps(1)).set(self.frame, (parsed,))
        elif key in numeric:
            numeric[key].set(self.frame, (math.nan,))

    def result(self) -> AcmiFile:
        frames = np.asarray(self.frames, dtype=np.float64)
        reference = (float(self.header.get("ReferenceLongitude", 0.0)),
                     float(self.header.get("ReferenceLatitude", 0.0)))
        tracks = {oid: AcmiTrack(oid, state.text, frames, state.spans(len(frames)), state.coords,
                                 state.numeric, reference)
                  for oid, state in self.objects.items()}
        return AcmiFile(self.header, frames, tracks)


def _physical_lines(stream: IO[bytes], source: str) -> Iterator[str]:
    """The decoded lines of a binary stream (UTF-8, a leading BOM dropped, ``\\n`` or ``\\r\\n``
    breaks removed); an undecodable line is an :class:`AcmiParseError` naming it."""
    for number, raw in enumerate(stream, start=1):
        if number == 1 and raw.startswith(codecs.BOM_UTF8):
            raw = raw[len(codecs.BOM_UTF8):]
        try:
            line = raw.decode("utf-8")
        except UnicodeDecodeError as error:
            raise AcmiParseError(f"{source}, line {number}: not UTF-8 text ({error.reason} at byte "
                                 f"{error.start})") from None
        yield line[:-1].removesuffix("\r") if line.endswith("\n") else line.removesuffix("\r")


def parse_acmi(text: str, source: str = "<text>") -> AcmiFile:
    """Parse ACMI 2.x text (see :func:`read_acmi`); errors name ``source`` and the line."""
    reader = _AcmiReader(source)
    lines = (line.removesuffix("\r") for line in text.removeprefix("\ufeff").split("\n"))
    return reader.read(_logical_lines(lines))


def read_acmi(path: str | Path) -> AcmiFile:
    """Parse a text (``.txt.acmi``/``.acmi``) or zipped (``.zip.acmi``) ACMI 2.x file, streaming: time
    and memory grow with what the file holds (values are stored where lines set them, see
    :class:`AcmiTrack`), not with objects x frames.

    Handles escaped commas, continued lines, removed objects (``-id``), the 3, 5, 6 and 9 component
    forms of ``T=`` and empty components (the previous value is kept). Longitudes and latitudes are
    returned absolute (``ReferenceLongitude``/``ReferenceLatitude`` added). A file that breaks the
    format raises :class:`AcmiParseError` (a ValueError) of one line naming the file and the line; a
    zip archive that is damaged or does not hold exactly one file, a ValueError naming the file."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{path}: no such file")
    with path.open("rb") as stream:
        if stream.read(2) != b"PK":
            stream.seek(0)
            return _AcmiReader(str(path)).read(_logical_lines(_physical_lines(stream, str(path))))
    try:
        with zipfile.ZipFile(path) as archive:
            members = [m for m in archive.infolist() if not m.is_dir()]
            if len(members) != 1:
                raise ValueError(f"{path}: a .zip.acmi archive must hold one file, found {len(members)}")
            with archive.open(members[0]) as stream:
                source = f"{path}[{members[0].filename}]"
                return _AcmiReader(source).read(_logical_lines(_physical_lines(stream, source)))
    except (zipfile.BadZipFile, zlib.error, EOFError, NotImplementedError, RuntimeError) as error:
        raise ValueError(f"{path}: not a readable zip archive ({error})") from None


__all__ = ["ACMI_COLORS", "ACMI_HEADER", "AIRCRAFT_TYPE", "FIRST_OBJECT_ID", "AcmiFile", "AcmiObjectEncoder",
           "AcmiParseError", "AcmiTrack", "acmi_header", "escape_text", "format_number",
           "format_reference_time", "isa_density_ratio", "parse_acmi", "read_acmi", "recording_geodetic",
           "write_acmi"]
