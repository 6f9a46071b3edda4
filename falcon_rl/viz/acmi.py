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
``AOA`` and ``AOS`` (deg), ``AGL`` (m, the CG height above the ground) and ``Throttle`` (0..1, mean
over motors).
"""

from __future__ import annotations

import io
import math
import zipfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path

import numpy as np

from ..constants import G0, LAPSE, R_AIR, T0
from ..recording import Recording, quaternion_euler
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
    if rec.has("height"):
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
    lines = acmi_header(ref, reference_time, title=title or f"falcon-rl recording ({airframe or 'aircraft'})",
                        author=author, comments=comments)
    encoders = [AcmiObjectEncoder(FIRST_OBJECT_ID + e, names[e], colors[e],
                                  extra={"ShortName": str(airframe)} if airframe else None)
                for e in range(envs)]
    for k in range(rec.num_frames):
        lines.append("#" + format_number(float(time[k]), 6))
        for e, encoder in enumerate(encoders):
            line = encoder.line(float(lon[k, e] - ref.longitude_deg), float(lat[k, e] - ref.latitude_deg),
                                float(alt[k, e]), *(float(a) for a in attitude[k, e]),
                                properties={key: float(value[k, e]) for key, value in props.items()},
                                decimals=decimals)
            if line is not None:
                lines.append(line)
    text = "\n".join(lines) + "\n"
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.name.endswith(".zip.acmi"):
        member = path.name[: -len(".zip.acmi")] + ".txt.acmi"
        with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED) as archive:
            archive.writestr(member, text.encode("utf-8"))
    else:
        path.write_text(text, encoding="utf-8")
    return path


# ------------------------------------------------------------------------------------------- reading
@dataclass
class AcmiTrack:
    """One object of a parsed file: its last text ``properties`` and, at every frame from its first
    appearance to its removal, ``time`` [K] s, absolute ``longitude``/``latitude`` [K] deg, ``altitude``
    [K] m, ``roll``/``pitch``/``yaw`` [K] deg and the numeric properties ``values`` {name: [K]} (NaN
    before a property's first value)."""

    object_id: str
    properties: dict[str, str] = field(default_factory=dict)
    time: np.ndarray = field(default_factory=lambda: np.zeros(0))
    longitude: np.ndarray = field(default_factory=lambda: np.zeros(0))
    latitude: np.ndarray = field(default_factory=lambda: np.zeros(0))
    altitude: np.ndarray = field(default_factory=lambda: np.zeros(0))
    roll: np.ndarray = field(default_factory=lambda: np.zeros(0))
    pitch: np.ndarray = field(default_factory=lambda: np.zeros(0))
    yaw: np.ndarray = field(default_factory=lambda: np.zeros(0))
    values: dict[str, np.ndarray] = field(default_factory=dict)


@dataclass
class AcmiFile:
    """A parsed ACMI file: ``header`` (FileType, FileVersion and the global object's properties),
    ``frames`` [F] s (every ``#`` line, in order) and ``objects`` {hex id: :class:`AcmiTrack`}."""

    header: dict[str, str]
    frames: np.ndarray
    objects: dict[str, AcmiTrack]


def _split_unescaped(text: str, separator: str) -> list[str]:
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


def _logical_lines(text: str) -> list[str]:
    """Physical lines joined where a line ends in an odd number of backslashes (a continued value)."""
    out: list[str] = []
    pending: str | None = None
    for raw in text.splitlines():
        line = raw if pending is None else pending + "\n" + raw
        trailing = len(raw) - len(raw.rstrip("\\"))
        if trailing % 2 == 1:
            pending = line[:-1]
            continue
        pending = None
        out.append(line)
    if pending is not None:
        out.append(pending)
    return out


_COORD_LAYOUT = {3: ("lon", "lat", "alt"), 5: ("lon", "lat", "alt", "u", "v"),
                 6: ("lon", "lat", "alt", "roll", "pitch", "yaw"),
                 9: ("lon", "lat", "alt", "roll", "pitch", "yaw", "u", "v", "heading")}


def _read_text(path: Path) -> str:
    data = path.read_bytes()
    if data[:2] == b"PK":
        with zipfile.ZipFile(io.BytesIO(data)) as archive:
            members = [m for m in archive.namelist() if not m.endswith("/")]
            if len(members) != 1:
                raise ValueError(f"{path}: a .zip.acmi archive must hold one file, found {len(members)}")
            data = archive.read(members[0])
    return data.decode("utf-8-sig")


def parse_acmi(text: str) -> AcmiFile:
    """Parse ACMI 2.x text (see :func:`read_acmi`)."""
    lines = _logical_lines(text.lstrip("\ufeff"))
    if len(lines) < 2 or not lines[0].startswith("FileType=") or not lines[1].startswith("FileVersion="):
        raise ValueError("not an ACMI file: the first lines must be FileType= and FileVersion=")
    header = dict(line.split("=", 1) for line in lines[:2])
    objects: dict[str, dict] = {}
    alive: set[str] = set()
    frames: list[float] = []
    current = 0.0

    def snapshot() -> None:
        for oid in alive:
            state = objects[oid]
            state["rows"].append((current, *(state["coord"][k] for k in
                                             ("lon", "lat", "alt", "roll", "pitch", "yaw")),
                                  dict(state["numeric"])))

    started = False
    for number, line in enumerate(lines[2:], start=3):
        if not line.strip() or line.startswith("//"):
            continue
        if line.startswith("#"):
            if started:
                snapshot()
            started = True
            try:
                current = float(line[1:])
            except ValueError:
                raise ValueError(f"line {number}: bad frame time {line!r}") from None
            frames.append(current)
            continue
        if line.startswith("-"):
            alive.discard(line[1:].strip().lower())
            continue
        fields = _split_unescaped(line, ",")
        oid = fields[0].strip().lower()
        properties = [f.split("=", 1) for f in fields[1:] if "=" in f]
        if oid == "0":
            header.update({k: v for k, v in properties})
            continue
        try:
            int(oid, 16)
        except ValueError:
            raise ValueError(f"line {number}: bad object id {fields[0]!r}") from None
        state = objects.setdefault(oid, {"coord": dict.fromkeys(("lon", "lat", "alt", "roll", "pitch",
                                                                  "yaw"), math.nan),
                                         "text": {}, "numeric": {}, "rows": []})
        alive.add(oid)
        for key, value in properties:
            if key == "T":
                components = value.split("|")
                layout = _COORD_LAYOUT.get(len(components))
                if layout is None:
                    raise ValueError(f"line {number}: T has {len(components)} components, "
                                     "expected 3, 5, 6 or 9")
                for name, component in zip(layout, components, strict=True):
                    if component.strip() and name in state["coord"]:
                        state["coord"][name] = float(component)
                continue
            state["text"][key] = value
            try:
                state["numeric"][key] = float(value)
            except ValueError:
                state["numeric"].pop(key, None)
    if started:
        snapshot()
    ref_lon = float(header.get("ReferenceLongitude", 0.0))
    ref_lat = float(header.get("ReferenceLatitude", 0.0))
    tracks: dict[str, AcmiTrack] = {}
    for oid, state in objects.items():
        rows = state["rows"]
        columns = [np.array([row[i] for row in rows], dtype=np.float64) for i in range(7)]
        keys = sorted({k for row in rows for k in row[7]})
        values = {k: np.array([row[7].get(k, math.nan) for row in rows]) for k in keys}
        tracks[oid] = AcmiTrack(oid, dict(state["text"]), columns[0], columns[1] + ref_lon,
                                columns[2] + ref_lat, columns[3], columns[4], columns[5], columns[6], values)
    return AcmiFile(header, np.asarray(frames, dtype=np.float64), tracks)


def read_acmi(path: str | Path) -> AcmiFile:
    """Parse a text (``.txt.acmi``/``.acmi``) or zipped (``.zip.acmi``) ACMI 2.x file.

    Handles escaped commas, continued lines, removed objects (``-id``), the 3, 5, 6 and 9 component
    forms of ``T=`` and empty components (the previous value is kept). Longitudes and latitudes are
    returned absolute (``ReferenceLongitude``/``ReferenceLatitude`` added)."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{path}: no such file")
    return parse_acmi(_read_text(path))


__all__ = ["ACMI_COLORS", "ACMI_HEADER", "AIRCRAFT_TYPE", "FIRST_OBJECT_ID", "AcmiFile", "AcmiObjectEncoder",
           "AcmiTrack", "acmi_header", "escape_text", "format_number", "format_reference_time",
           "isa_density_ratio", "parse_acmi", "read_acmi", "recording_geodetic", "write_acmi"]
