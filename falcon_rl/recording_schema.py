"""The schema of a flight recording (:mod:`falcon_rl.recording`) and the checks of a file read as untrusted.

:func:`read_recording_arrays` checks every ``.npy`` member's header (NumPy format 1.0 or 2.0) before
it reads any array data: a field's dtype (bool, integer or float, never an object), its shape ([T] for
``time``, [T, E, ...] for a field, the trailing sizes of :data:`FIELD_TRAILING_SHAPES`, at least one
frame and one aircraft), that the zip member's size equals what the header declares, and that all
arrays together hold at most ``max_bytes`` and ``meta`` at most :data:`MAX_META_BYTES`; the wave fields
of a recording over the sea (``sea/<component>`` [F, E, K] floats, :data:`SEA_COMPONENTS`, all six or
none, with the field ``sea_field`` [T, E] integer) likewise (:func:`check_sea_layout`). Then ``meta``
is checked field by field (:data:`META_SCHEMA`; nesting at most :data:`MAX_META_DEPTH` deep) and the
sea's values (:func:`check_sea_values`). Anything else is a :class:`RecordingError` of one line naming
the field and the constraint; the same :func:`check_layout`, :func:`check_time`, :func:`check_meta`
and the sea checks hold for recordings built in code.
"""

from __future__ import annotations

import json
import math
import zipfile
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.lib import format as npy_format

#: The ``meta["format"]`` of this version of the file.
RECORDING_FORMAT = "falcon-rl-recording/1"
#: Fields every recording has.
REQUIRED_FIELDS: tuple[str, ...] = ("position_ned", "quaternion")
#: Most bytes of array data :meth:`Recording.load` reads by default (all arrays together, as their
#: headers declare them; checked before any data is read).
MAX_RECORDING_BYTES = 2 * 1024**3
#: Most bytes of the ``meta`` JSON document.
MAX_META_BYTES = 1024**2
#: Deepest nesting of lists and objects in ``meta``.
MAX_META_DEPTH = 32
#: NumPy dtype kinds a field may have: bool, signed and unsigned integer, float.
FIELD_DTYPE_KINDS = "biuf"
#: Sizes after [T, E] of the fields the readers interpret (None: any positive size).
FIELD_TRAILING_SHAPES: dict[str, tuple[int | None, ...]] = {
    "position_ned": (3,), "quaternion": (4,), "euler": (3,), "velocity_body": (3,), "velocity_ned": (3,),
    "angular_rate_body": (3,), "airspeed": (), "alpha": (), "beta": (), "height": (), "wing_height": (),
    "lowest_tip_height": (), "command": (None,), "surface_position": (3,), "throttle": (None,),
    "thrust": (), "aero_coefficients": (6,), "gust_velocity_body": (3,), "gust_rate_body": (3,),
    "crashed": (), "aero_force_body": (3,), "aero_moment_body": (3,), "motor_thrust": (None,),
    "reward": (), "done": (), "termination_reason": (), "sim_time": (), "surface_elevation": (),
    "surface_clearance": (), "lowest_tip_clearance": (), "over_water": (), "wave_velocity_ned": (3,),
    "sea_field": ()}
#: The Airy components of a recorded wave field (``physics.sea.SeaSurface``), each stored [F, E, K].
SEA_COMPONENTS: tuple[str, ...] = ("amplitude", "wavenumber", "frequency", "direction_cos",
                                   "direction_sin", "phase")


class RecordingError(ValueError):
    """A recording file or array that breaks the schema (the message names the file and field)."""


# ------------------------------------------------------------------------------------------ schema
def check_layout(time_shape: tuple[int, ...], shapes: Mapping[str, tuple[int, ...]],
                 dtypes: Mapping[str, np.dtype], min_frames: int = 0) -> None:
    """Check the shapes and dtypes of ``time`` [T] and the fields {name: [T, E, ...]} (arrays or the
    headers of a file's arrays); RecordingError naming the field and the constraint."""
    if len(time_shape) != 1:
        raise RecordingError(f"time must be [T], got shape {time_shape}")
    frames = time_shape[0]
    if frames < min_frames:
        raise RecordingError(f"time has {frames} frames, a recording file needs at least {min_frames}")
    missing = [name for name in REQUIRED_FIELDS if name not in shapes]
    if missing:
        raise RecordingError(f"a recording needs the fields {', '.join(missing)}")
    position = shapes["position_ned"]
    envs = position[1] if len(position) >= 2 else 0
    for name, shape in shapes.items():
        if len(shape) < 2 or shape[:2] != (frames, envs):
            raise RecordingError(f"field {name!r} has shape {shape}, expected [{frames}, {envs}, ...]")
        _check_trailing(name, shape[2:], FIELD_TRAILING_SHAPES.get(name))
        if np.dtype(dtypes[name]).kind not in FIELD_DTYPE_KINDS:
            raise RecordingError(f"field {name!r} has dtype {np.dtype(dtypes[name])}, expected bool, "
                                 "integer or float")
    if min_frames and envs < 1:
        raise RecordingError("field 'position_ned' has no aircraft (E = 0), expected at least one")


def check_time(time: np.ndarray) -> None:
    """``time`` [T] must be finite and increase strictly; RecordingError otherwise."""
    if not np.all(np.isfinite(time)):
        raise RecordingError("time must be finite")
    if time.shape[0] > 1 and not np.all(np.diff(time) > 0):
        raise RecordingError("time must increase strictly from frame to frame")


def _check_trailing(name: str, trailing: tuple[int, ...], expected: tuple[int | None, ...] | None) -> None:
    if expected is not None and (len(trailing) != len(expected) or any(
            size != want for size, want in zip(trailing, expected, strict=True) if want is not None)):
        layout = ", ".join("..." if want is None else str(want) for want in expected)
        raise RecordingError(f"field {name!r} has shape [T, E, {', '.join(map(str, trailing))}], "
                             f"expected [T, E{', ' if expected else ''}{layout}]")
    if any(size < 1 for size in trailing):
        raise RecordingError(f"field {name!r} has an empty axis in shape {trailing}")


def check_sea_layout(shapes: Mapping[str, tuple[int, ...]], dtypes: Mapping[str, np.dtype], envs: int,
                     field_dtype: np.dtype | None) -> None:
    """Check the shapes and dtypes of a recording's wave fields {component: [F, E, K]} (arrays or
    headers; empty: no sea) for ``envs`` aircraft, and that of its ``sea_field`` field (None when
    absent); RecordingError naming the component and the constraint."""
    if not shapes:
        if field_dtype is not None:
            raise RecordingError("field 'sea_field' indexes wave fields, the recording has none (sea/...)")
        return
    missing = [name for name in SEA_COMPONENTS if name not in shapes]
    unknown = sorted(set(shapes) - set(SEA_COMPONENTS))
    if missing or unknown:
        raise RecordingError(f"a recording's sea needs exactly the components {', '.join(SEA_COMPONENTS)}; "
                             f"missing {missing}, unknown {unknown}")
    first = shapes[SEA_COMPONENTS[0]]
    for name in SEA_COMPONENTS:
        shape, dtype = shapes[name], np.dtype(dtypes[name])
        if len(shape) != 3 or shape != first or shape[0] < 1 or shape[1] != envs or shape[2] < 1:
            raise RecordingError(f"sea {name!r} has shape {shape}, expected [F, {envs}, K] (F, K >= 1) like "
                                 f"{SEA_COMPONENTS[0]!r} {first}")
        if dtype.kind != "f":
            raise RecordingError(f"sea {name!r} has dtype {dtype}, expected float")
    if field_dtype is None or np.dtype(field_dtype).kind not in "iu":
        raise RecordingError("a recording with a sea needs the integer field 'sea_field' [T, E], got "
                             f"{'none' if field_dtype is None else np.dtype(field_dtype)}")


def check_sea_values(sea: Mapping[str, np.ndarray], sea_field: np.ndarray | None) -> None:
    """The wave fields {component: [F, E, K]} must be finite, with amplitudes >= 0 and directions of unit
    length, and ``sea_field`` [T, E] must index them (-1: no sea in that frame); RecordingError
    otherwise."""
    if not sea:
        return
    for name in SEA_COMPONENTS:
        if not np.all(np.isfinite(sea[name])):
            raise RecordingError(f"sea {name!r} must be finite")
    if np.any(sea["amplitude"] < 0):
        raise RecordingError("sea 'amplitude' must be >= 0")
    norm = np.hypot(sea["direction_cos"].astype(np.float64), sea["direction_sin"].astype(np.float64))
    if np.any(np.abs(norm - 1.0) > 1e-3):
        raise RecordingError("sea 'direction_cos', 'direction_sin' must be unit vectors")
    count = sea[SEA_COMPONENTS[0]].shape[0]
    if sea_field is not None and sea_field.size and (sea_field.min() < -1 or sea_field.max() >= count):
        raise RecordingError(f"field 'sea_field' must index the {count} wave fields (-1: none), got values "
                             f"in [{sea_field.min()}, {sea_field.max()}]")


def _optional_text(value: Any, envs: int) -> bool:
    return value is None or isinstance(value, str)


def _positive_number(value: Any, envs: int) -> bool:
    return (isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
            and value > 0)


def _integer(value: Any) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _optional_int(value: Any, envs: int) -> bool:
    return value is None or _integer(value)


def _positive_int(value: Any, envs: int) -> bool:
    return _integer(value) and value >= 1


def _texts(value: Any, envs: int) -> bool:
    return isinstance(value, list) and all(isinstance(item, str) for item in value)


def _label_per_aircraft(value: Any, envs: int) -> bool:
    return _texts(value, envs) and len(value) == envs


def _non_negative_ints(value: Any, envs: int) -> bool:
    return isinstance(value, list) and all(_integer(item) and item >= 0 for item in value)


#: The ``meta`` fields with a meaning besides ``format``: {name: (check(value, E), the constraint in
#: words)}. Each may be absent; other keys are kept unchecked (but within :data:`MAX_META_DEPTH`).
META_SCHEMA: dict[str, tuple[Callable[[Any, int], bool], str]] = {
    "airframe": (_optional_text, "must be an airframe name (a string) or null"),
    "dt": (_positive_number, "must be a finite number of seconds > 0"),
    "labels": (_label_per_aircraft, "must be a list of one string per aircraft"),
    "task": (_optional_text, "must be a string or null"),
    "controller": (_optional_text, "must be a string or null"),
    "maneuver": (_optional_text, "must be a string or null"),
    "backend": (_optional_text, "must be a string or null"),
    "source": (_optional_text, "must be a string or null"),
    "seed": (_optional_int, "must be an integer or null"),
    "env_ids": (_non_negative_ints, "must be a list of non-negative integers"),
    "termination_reasons": (_texts, "must be a list of strings"),
    "every": (_positive_int, "must be an integer >= 1"),
    "xplane_datarefs": (_texts, "must be a list of strings"),
}


def check_meta(meta: Any, num_envs: int) -> None:
    """Check ``meta`` against :data:`META_SCHEMA` for a recording of ``num_envs`` aircraft and its
    nesting against :data:`MAX_META_DEPTH`; RecordingError naming the field and the constraint."""
    if not isinstance(meta, dict):
        raise RecordingError(f"meta must be a JSON object, got {type(meta).__name__}")
    if _nesting_depth(meta) > MAX_META_DEPTH:
        raise RecordingError(f"meta is nested more than {MAX_META_DEPTH} levels deep")
    for name, (check, constraint) in META_SCHEMA.items():
        if name in meta and not check(meta[name], num_envs):
            shown = repr(meta[name])
            shown = shown if len(shown) <= 60 else shown[:57] + "..."
            suffix = f" ({num_envs} aircraft)" if name == "labels" else ""
            raise RecordingError(f"meta.{name} {constraint}{suffix}, got {shown}")


def _nesting_depth(document: Any) -> int:
    """How deeply lists and dicts nest in ``document`` (no recursion; stops counting past the limit)."""
    deepest = 0
    pending = [(document, 1)] if isinstance(document, dict | list) else []
    while pending and deepest <= MAX_META_DEPTH:
        value, depth = pending.pop()
        deepest = max(deepest, depth)
        children = value.values() if isinstance(value, dict) else value
        pending.extend((child, depth + 1) for child in children if isinstance(child, dict | list))
    return deepest


# ------------------------------------------------------------------------------------------ reading
@dataclass(frozen=True)
class _ArrayHeader:
    """What a ``.npy`` member declares: its shape, dtype and where the data starts."""

    shape: tuple[int, ...]
    dtype: np.dtype
    data_offset: int

    @property
    def nbytes(self) -> int:
        return math.prod(self.shape) * self.dtype.itemsize


def _member_name(info: zipfile.ZipInfo) -> str | None:
    """The array name of a member of a recording (``time``, ``meta``, ``field/<name>``,
    ``sea/<component>``), else None."""
    name = info.filename[:-len(".npy")] if info.filename.endswith(".npy") else None
    if info.filename.startswith("field/") and (name is None or name == "field/"):
        raise RecordingError(f"member {info.filename!r} is not a field array (field/<name>.npy)")
    if info.filename.startswith("sea/") and (name is None or name[len("sea/"):] not in SEA_COMPONENTS):
        raise RecordingError(f"member {info.filename!r} is not a wave field array (sea/<component>.npy, "
                             f"components {', '.join(SEA_COMPONENTS)})")
    return name if name in ("time", "meta") or (name or "").startswith(("field/", "sea/")) else None


def _read_header(archive: zipfile.ZipFile, info: zipfile.ZipInfo, name: str) -> _ArrayHeader:
    """The header of the ``.npy`` member ``info`` (no array data is read); RecordingError when it is
    not a .npy array of format 1.0 or 2.0 or its size disagrees with the zip member's."""
    with archive.open(info) as stream:
        try:
            version = npy_format.read_magic(stream)
            reader = {(1, 0): npy_format.read_array_header_1_0,
                      (2, 0): npy_format.read_array_header_2_0}.get(version)
            if reader is None:
                raise RecordingError(f"{_label(name)} is a .npy file of version {version}, expected 1.0 "
                                     "or 2.0")
            shape, _, dtype = reader(stream)
        except RecordingError:
            raise
        except (ValueError, TypeError) as error:
            raise RecordingError(f"{_label(name)} is not a .npy array ({error})") from None
        header = _ArrayHeader(tuple(int(size) for size in shape), np.dtype(dtype), stream.tell())
    if any(size < 0 for size in header.shape):
        raise RecordingError(f"{_label(name)} declares the negative shape {header.shape}")
    if dtype.hasobject or dtype.kind not in FIELD_DTYPE_KINDS:
        raise RecordingError(f"{_label(name)} has dtype {dtype}, expected bool, integer or float")
    if info.file_size != header.data_offset + header.nbytes:
        raise RecordingError(f"{_label(name)}: the zip member holds {info.file_size} bytes, its .npy header "
                             f"declares {header.data_offset + header.nbytes} (shape {header.shape}, {dtype})")
    return header


def _label(name: str) -> str:
    if name.startswith("sea/"):
        return f"sea {name[len('sea/'):]!r}"
    return f"field {name[len('field/'):]!r}" if name.startswith("field/") else name


def _check_meta_header(headers: Mapping[str, _ArrayHeader]) -> None:
    """A recording file has ``time`` and a ``meta`` [bytes] uint8 of at most :data:`MAX_META_BYTES`."""
    if "time" not in headers or "meta" not in headers:
        raise RecordingError("not a falcon-rl recording (no 'time' or 'meta' array)")
    meta = headers["meta"]
    if len(meta.shape) != 1 or meta.dtype != np.uint8:
        raise RecordingError(f"meta must be a [bytes] uint8 array, got shape {meta.shape}, {meta.dtype}")
    if meta.nbytes > MAX_META_BYTES:
        raise RecordingError(f"meta holds {meta.nbytes} bytes, at most {MAX_META_BYTES} allowed")


def _check_headers(headers: Mapping[str, _ArrayHeader], max_bytes: int) -> None:
    """The declared layout and size of the arrays of a recording file, before their data is read."""
    if headers["time"].dtype.kind not in "iuf":
        raise RecordingError(f"time has dtype {headers['time'].dtype}, expected integer or float")
    fields = {name[len("field/"):]: header for name, header in headers.items() if name.startswith("field/")}
    check_layout(headers["time"].shape, {n: h.shape for n, h in fields.items()},
                 {n: h.dtype for n, h in fields.items()}, min_frames=1)
    sea = {name[len("sea/"):]: header for name, header in headers.items() if name.startswith("sea/")}
    index = fields.get("sea_field")
    check_sea_layout({n: h.shape for n, h in sea.items()}, {n: h.dtype for n, h in sea.items()},
                     fields["position_ned"].shape[1], None if index is None else index.dtype)
    total = sum(header.nbytes for header in headers.values())
    if total > max_bytes:
        raise RecordingError(f"the arrays declare {total} bytes, more than the {max_bytes} bytes allowed "
                             "(max_bytes)")


def read_recording_arrays(path: Path, max_bytes: int) -> tuple[
        np.ndarray, dict[str, np.ndarray], dict[str, Any], dict[str, np.ndarray]]:
    """``time`` [T], the fields {name: [T, E, ...]}, ``meta`` and the wave fields {component: [F, E, K]}
    (empty without a sea) of the recording file ``path``. Every
    header is read first; ``meta`` (small) is read and its format checked, then the declared layout of
    the arrays (:func:`_check_headers`) before any of them is read, and ``time`` before the fields."""
    with zipfile.ZipFile(path) as archive:
        members: dict[str, zipfile.ZipInfo] = {}
        for info in archive.infolist():
            name = _member_name(info)
            if name is not None and members.setdefault(name, info) is not info:
                raise RecordingError(f"{_label(name)} appears twice in the archive")
        headers = {name: _read_header(archive, info, name) for name, info in members.items()}
        _check_meta_header(headers)
        meta = _parse_meta(_read_array(archive, members.pop("meta")))
        if meta.get("format") != RECORDING_FORMAT:
            raise RecordingError(f"meta.format is {meta.get('format')!r}, expected {RECORDING_FORMAT!r}")
        _check_headers(headers, max_bytes)
        time = _read_array(archive, members.pop("time"))
        check_time(time)
        fields = {name[len("field/"):]: _read_array(archive, info) for name, info in members.items()
                  if name.startswith("field/")}
        sea = {name[len("sea/"):]: _read_array(archive, info) for name, info in members.items()
               if name.startswith("sea/")}
    return time, fields, meta, sea


def _read_array(archive: zipfile.ZipFile, info: zipfile.ZipInfo) -> np.ndarray:
    with archive.open(info) as stream:
        return npy_format.read_array(stream, allow_pickle=False)


def _parse_meta(data: np.ndarray) -> dict[str, Any]:
    """The ``meta`` JSON object of a file (its schema is checked by the :class:`Recording`)."""
    try:
        meta = json.loads(data.tobytes().decode("utf-8"))
    except RecursionError:
        raise RecordingError(f"meta is nested more than {MAX_META_DEPTH} levels deep") from None
    except (UnicodeDecodeError, json.JSONDecodeError) as error:
        raise RecordingError(f"meta is not a UTF-8 JSON document ({error})") from None
    if not isinstance(meta, dict):
        raise RecordingError(f"meta must be a JSON object, got {type(meta).__name__}")
    return meta


__all__ = ["FIELD_DTYPE_KINDS", "FIELD_TRAILING_SHAPES", "MAX_META_BYTES", "MAX_META_DEPTH",
           "MAX_RECORDING_BYTES", "META_SCHEMA", "RECORDING_FORMAT", "REQUIRED_FIELDS", "SEA_COMPONENTS",
           "RecordingError", "check_layout", "check_meta", "check_sea_layout", "check_sea_values",
           "check_time", "read_recording_arrays"]
