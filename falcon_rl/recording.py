"""Flight recordings: the file that the recorders write and the plots, the 3D renderer, the Tacview
exporter and the FlightGear streamer read.

A recording holds ``T`` frames of ``E`` aircraft. Every field is a float32 (or bool / int64) array
whose first two axes are [T, E]; scalars per aircraft are stored [T, E]. The file is a NumPy ``.npz``
(no pickles) with one array per field, ``time`` [T] in seconds and ``meta``, a JSON document::

    time                  [T]        s, simulated time of each frame (frame 0 = after reset)
    position_ned          [T, E, 3]  m, CG position, north-east-down about the origin
    quaternion            [T, E, 4]  body-to-NED unit quaternion (w, x, y, z)
    euler                 [T, E, 3]  rad, aerospace ZYX roll, pitch, yaw
    velocity_body         [T, E, 3]  m/s, inertial velocity in body FRD
    velocity_ned          [T, E, 3]  m/s, inertial velocity in NED
    angular_rate_body     [T, E, 3]  rad/s, p, q, r
    airspeed, alpha, beta [T, E]     m/s, rad, rad (wind and gusts included)
    height, wing_height   [T, E]     m, CG and wing quarter-chord height above ground
    lowest_tip_height     [T, E]     m, the lower wing tip above ground
    command               [T, E, 4]  normalised command [-1, 1] (elevator, aileron, rudder, throttle)
    surface_position      [T, E, 3]  rad, achieved elevator, aileron, rudder deflections
    throttle              [T, E, M]  achieved throttle per motor, [0, 1]
    thrust                [T, E]     N, total thrust
    aero_coefficients     [T, E, 6]  C_L, C_D, C_Y, C_l, C_m, C_n (ground effect included)
    gust_velocity_body    [T, E, 3]  m/s, Dryden gust velocity (body)
    gust_rate_body        [T, E, 3]  rad/s, Dryden gust rates (body)
    crashed               [T, E]     bool, the CG went below the ground
    surface_elevation     [T, E]     m, the sea's elevation under the CG (0 over the ground)
    surface_clearance     [T, E]     m, CG height above the surface under it
    lowest_tip_clearance  [T, E]     m, the lower wing tip above the surface under it
    over_water            [T, E]     1 over the aircraft's sea, 0 over the ground
    wave_velocity_ned     [T, E, 3]  m/s, the air's flow over the waves at the wing
    ... and the engine's diagnostics when it has them (``physics.derived``): aero_force_body [T, E, 3]
    (N), aero_moment_body [T, E, 3] (N m), motor_thrust [T, E, M] (N), ge_h_over_b, ge_lift_factor,
    ge_drag_factor [T, E]; and, from an env, action [T, E, C], reward [T, E], done [T, E] (bool),
    termination_reason [T, E] (int64, index into ``meta["termination_reasons"]``), the task's
    references under ``reference/<name>`` (its ``reference_<name>`` and ``<name>_command`` entries,
    e.g. reference/altitude, reference/bank), its other entries under
    ``task/<name>``, and ``sim_time`` [T, E] (each aircraft's own clock, which restarts at a reset).

A flight over the sea (``Simulator.sea``) also holds the wave fields of the recorded aircraft, enough
to redraw the sea: ``sea/<component>`` [F, E, K] for the components of
:data:`~falcon_rl.recording_schema.SEA_COMPONENTS` (amplitude m, wavenumber rad/m, frequency rad/s,
direction_cos, direction_sin of travel, phase rad; ``physics.sea.SeaSurface``), F distinct snapshots
of the recorded rows (a new one whenever a row's field changes, e.g. a new draw at a reset), and the
field ``sea_field`` [T, E] int64, the snapshot each frame flies over (-1: no recorded aircraft over
the sea then). An aircraft over the ground has zero amplitudes in a snapshot (eta = 0, the flat
ground). The elevation is eta(n, e, t) = sum_k a_k cos(k_k (n cos_k + e sin_k) - w_k t + phi_k) at
the aircraft's own clock t (``sim_time`` where recorded, else ``time``). Recordings without a sea
have neither.

``meta`` carries at least ``format`` (:data:`RECORDING_FORMAT`), ``airframe`` (a name
``falcon_rl.load_airframe`` accepts), ``dt`` (s between frames) and ``labels`` (one per aircraft), and
where known ``task``, ``controller``, ``maneuver``, ``seed``, ``backend``, ``env_ids`` and
``termination_reasons``. Any field but ``time``, ``position_ned`` and ``quaternion`` may be absent;
readers skip what is missing.

:meth:`Recording.load` reads a file it did not write as untrusted: before it reads any array data it
checks every ``.npy`` member's header (NumPy format 1.0 or 2.0) — a field's dtype (bool, integer or
float, never an object), its shape ([T] for ``time``, [T, E, ...] for a field, the trailing sizes of
:data:`FIELD_TRAILING_SHAPES`, at least one frame and one aircraft), that the zip member's size equals
what the header declares, and that all arrays together hold at most ``max_bytes``
(:data:`MAX_RECORDING_BYTES`, 2 GiB, by default) and ``meta`` at most :data:`MAX_META_BYTES`; the wave
fields likewise (all six components [F, E, K] floats, or none; ``sea_field`` integer). Then ``meta`` is
checked field by field (:data:`META_SCHEMA`; nesting at most :data:`MAX_META_DEPTH` deep; other keys
are kept as they are) and the wave fields' values (finite, unit directions, indexed by ``sea_field``).
Anything else is a :class:`RecordingError` of one line naming the
file, the field and the constraint. The checks live in :mod:`falcon_rl.recording_schema`.
"""

from __future__ import annotations

import json
import zipfile
import zlib
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch

from .atomic_files import serialized, write_atomic
from .recording_schema import (  # the schema's names are this module's too (tests and users import them here)
    FIELD_DTYPE_KINDS,
    FIELD_TRAILING_SHAPES,
    MAX_META_BYTES,
    MAX_META_DEPTH,
    MAX_RECORDING_BYTES,
    META_SCHEMA,
    RECORDING_FORMAT,
    REQUIRED_FIELDS,
    SEA_COMPONENTS,
    RecordingError,
    check_layout,
    check_meta,
    check_sea_layout,
    check_sea_values,
    check_time,
    read_recording_arrays,
)

#: Fields of ``Simulator.state`` that are not recorded (constant or bookkeeping).
_SKIPPED_STATE_FIELDS = frozenset({"time", "surface_rate", "ground_contact"})


def quaternion_euler(quaternion: np.ndarray) -> np.ndarray:
    """Aerospace ZYX (roll, pitch, yaw) [..., 3] rad of body-to-NED quaternions [..., 4] (w, x, y, z):
    the NumPy twin of ``physics.rotations.quaternion_to_euler`` for recordings and viewers."""
    w, x, y, z = np.moveaxis(np.asarray(quaternion, dtype=np.float64), -1, 0)
    roll = np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2 * (w * y - z * x), -1.0, 1.0))
    yaw = np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return np.stack([roll, pitch, yaw], axis=-1)


@dataclass
class Recording:
    """``T`` frames of ``E`` aircraft: ``time`` [T] s, ``fields`` {name: [T, E, ...]} and, over the
    sea, the wave fields ``sea`` {component: [F, E, K]} that ``fields["sea_field"]`` [T, E] indexes."""

    time: np.ndarray
    fields: dict[str, np.ndarray]
    meta: dict[str, Any] = field(default_factory=dict)
    sea: dict[str, np.ndarray] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.time = np.asarray(self.time, dtype=np.float64)
        self.fields = {name: np.asarray(value) for name, value in self.fields.items()}
        self.sea = {name: np.asarray(value) for name, value in (self.sea or {}).items()}
        check_layout(self.time.shape, {n: v.shape for n, v in self.fields.items()},
                     {n: v.dtype for n, v in self.fields.items()})
        index = self.fields.get("sea_field")
        check_sea_layout({n: v.shape for n, v in self.sea.items()}, {n: v.dtype for n, v in self.sea.items()},
                         self.num_envs, None if index is None else index.dtype)
        check_sea_values(self.sea, index)
        check_time(self.time)
        self.meta = {"format": RECORDING_FORMAT, **self.meta}
        self.meta.setdefault("labels", [f"aircraft {e}" for e in range(self.num_envs)])
        check_meta(self.meta, self.num_envs)

    @property
    def num_frames(self) -> int:
        """T."""
        return int(self.time.shape[0])

    @property
    def num_envs(self) -> int:
        """E, the number of aircraft."""
        return int(self.fields["position_ned"].shape[1])

    @property
    def dt(self) -> float:
        """Seconds between frames (``meta["dt"]``, else the median spacing of ``time``)."""
        if "dt" in self.meta:
            return float(self.meta["dt"])
        return float(np.median(np.diff(self.time))) if self.num_frames > 1 else 0.0

    @property
    def has_sea(self) -> bool:
        """Whether the recording holds wave fields (a flight over the sea)."""
        return bool(self.sea)

    def has(self, name: str) -> bool:
        """Whether the field ``name`` was recorded."""
        return name in self.fields

    def __getitem__(self, name: str) -> np.ndarray:
        return self.fields[name]

    def references(self) -> dict[str, np.ndarray]:
        """The task references {name: [T, E, ...]} (fields ``reference/<name>``)."""
        return {name.split("/", 1)[1]: value for name, value in self.fields.items()
                if name.startswith("reference/")}

    def select(self, envs: Iterable[int]) -> Recording:
        """A recording of the aircraft ``envs`` only (indices into E)."""
        index = list(envs)
        labels = self.meta.get("labels", [])
        meta = {**self.meta, "labels": [labels[e] for e in index] if labels else labels}
        return Recording(self.time, {k: v[:, index] for k, v in self.fields.items()}, meta,
                         {k: v[:, index] for k, v in self.sea.items()})

    def save(self, path: str | Path) -> Path:
        """Write ``path`` (.npz, compressed; the suffix is added when missing) whole or not at all."""
        path = Path(path)
        if path.suffix != ".npz":
            path = path.with_name(path.name + ".npz")
        arrays = {f"field/{name}": value for name, value in self.fields.items()}
        arrays.update({f"sea/{name}": value for name, value in self.sea.items()})
        meta = np.frombuffer(json.dumps(self.meta).encode(), dtype=np.uint8)
        return write_atomic(path, serialized(
            lambda stream: np.savez_compressed(stream, time=self.time, meta=meta, **arrays)))

    @classmethod
    def load(cls, path: str | Path, max_bytes: int = MAX_RECORDING_BYTES) -> Recording:
        """Read a file :meth:`save` wrote, checking it as the module docstring says before reading
        more than ``max_bytes`` of arrays; a foreign, damaged or oversized file raises
        :class:`RecordingError` of one line naming the file, the field and the constraint."""
        path = Path(path)
        if path.is_file() and not zipfile.is_zipfile(path):
            raise RecordingError(f"{path}: not a recording (a recording is an .npz archive)")
        try:
            return cls(*read_recording_arrays(path, max_bytes))
        except RecordingError as error:
            raise RecordingError(f"{path}: {error}") from None
        except (OSError, ValueError, EOFError, zipfile.BadZipFile, zlib.error, NotImplementedError,
                RuntimeError) as error:
            reason = getattr(error, "strerror", None) or error
            raise RecordingError(f"{path}: cannot be read as a recording ({reason})") from None

def state_frame(state: Mapping[str, torch.Tensor], env_ids: torch.Tensor | list[int] | None = None,
                num_motors: int | None = None) -> dict[str, np.ndarray]:
    """One frame {name: [E, ...]} of the rows ``env_ids`` (all when None) of ``Simulator.state``."""
    frame: dict[str, np.ndarray] = {}
    for name, value in state.items():
        if name in _SKIPPED_STATE_FIELDS or not isinstance(value, torch.Tensor):
            continue
        rows = value if env_ids is None else value[env_ids]
        if name == "motor_thrust" and num_motors is not None:
            rows = rows[:, :num_motors]
        frame[name] = rows.detach().cpu().numpy().copy()
    return frame


def sea_snapshot(sea: Any, over_water: torch.Tensor | None,
                 rows: torch.Tensor | list[int] | None = None) -> np.ndarray | None:
    """The wave fields [6, E, K] (:data:`SEA_COMPONENTS` in order) of the rows ``rows`` (all when None) of
    ``sea`` (a ``physics.sea.SeaSurface`` of [N, K] tensors, or None), the amplitudes of the rows not
    ``over_water`` [N] zeroed (their unused field is the flat ground); None without a sea or when no
    recorded row is over it."""
    if sea is None or over_water is None:
        return None
    water = (over_water if rows is None else over_water[rows]) != 0
    if not bool(water.any()):
        return None
    stack = torch.stack([getattr(sea, name) if rows is None else getattr(sea, name)[rows]
                         for name in SEA_COMPONENTS])
    stack[0] = torch.where(water[:, None], stack[0], torch.zeros_like(stack[0]))
    return stack.detach().cpu().numpy()


class RecordingBuilder:
    """Accumulates frames {name: [E, ...]} at times t, and the wave fields [6, E, K] they fly over, and
    stacks them into a :class:`Recording`."""

    def __init__(self, meta: Mapping[str, Any] | None = None) -> None:
        self.meta: dict[str, Any] = dict(meta or {})
        self.times: list[float] = []
        self.frames: list[dict[str, np.ndarray]] = []
        self.sea_fields: list[np.ndarray] = []

    def __len__(self) -> int:
        return len(self.frames)

    def add(self, time: float, frame: Mapping[str, np.ndarray], sea: np.ndarray | None = None) -> None:
        """Append one frame {name: [E, ...]} at ``time`` s over the wave fields ``sea`` [6, E, K]
        (:func:`sea_snapshot`; None: no sea), kept once while they do not change (field ``sea_field``)."""
        frame = dict(frame)
        if sea is not None:
            if not self.sea_fields or not np.array_equal(sea, self.sea_fields[-1]):
                self.sea_fields.append(np.array(sea))
            frame["sea_field"] = np.full(sea.shape[1], len(self.sea_fields) - 1, dtype=np.int64)
        self.times.append(float(time))
        self.frames.append(frame)

    def build(self) -> Recording:
        """The recording of the frames so far. A field missing from some frames (the action and reward
        of the frame at a reset) is filled there with NaN (float), False (bool) or -1 (integer)."""
        if not self.frames:
            raise RecordingError("nothing was recorded")
        names = list(dict.fromkeys(n for f in self.frames for n in f))
        fields = {n: np.stack(_filled(self.frames, n)) for n in names}
        for name, value in fields.items():
            if value.ndim == 1:  # one scalar per frame -> [T, 1]
                fields[name] = value[:, None]
        sea = ({name: np.stack([f[i] for f in self.sea_fields]) for i, name in enumerate(SEA_COMPONENTS)}
               if self.sea_fields else {})
        return Recording(np.asarray(self.times), fields, self.meta, sea)


def _filled(frames: list[dict[str, np.ndarray]], name: str) -> list[np.ndarray]:
    """Field ``name`` of every frame, a fill value where a frame lacks it."""
    template = np.asarray(next(f[name] for f in frames if name in f))
    if template.dtype == np.bool_:
        fill: Any = False
    elif np.issubdtype(template.dtype, np.integer):
        fill = -1
    else:
        fill = np.nan
    return [np.asarray(f[name]) if name in f else np.full_like(template, fill) for f in frames]


class FlightLog:
    """Records the aircraft ``env_ids`` of a flight env (anything with ``sim`` and ``control_dt``, and
    optionally ``config`` and ``termination_reasons``, such as :class:`~falcon_rl.envs.FixedWingEnv`)
    one frame per :meth:`capture`: the simulator's whole state with the engine's diagnostics and, over
    the sea, the recorded rows' wave fields (``sim.sea``), plus what the caller adds (action, reward,
    done, task entries). The recorder transform and the Gymnasium wrappers are built on it.

    Frame k is at ``time`` = k x ``control_dt`` (a global clock that runs on across resets); each
    aircraft's own simulated time is the field ``sim_time``. ``max_frames`` stops recording (never
    drops the beginning) once reached.
    """

    def __init__(self, env: Any, env_ids: Iterable[int] = (0,), max_frames: int | None = None,
                 meta: Mapping[str, Any] | None = None) -> None:
        self.env = env
        self.env_ids = [int(e) for e in env_ids]
        num_envs = int(env.sim.num_envs)
        if not self.env_ids or any(not 0 <= e < num_envs for e in self.env_ids):
            raise ValueError(f"env_ids must be a non-empty list of indices in [0, {num_envs}), "
                             f"got {self.env_ids}")
        if max_frames is not None and max_frames < 1:
            raise ValueError(f"max_frames must be at least 1, got {max_frames}")
        self.max_frames = max_frames
        config = getattr(env, "config", None)
        self.builder = RecordingBuilder({
            "airframe": env.sim.airframe.name, "dt": float(env.control_dt), "env_ids": self.env_ids,
            "labels": [f"env {e}" for e in self.env_ids],
            "task": getattr(config, "task", None), "backend": getattr(config, "backend", None),
            "seed": getattr(env, "seed_record", (0, None))[1],
            "termination_reasons": list(getattr(env, "termination_reasons", ())),
            **dict(meta or {})})
        self._rows = torch.tensor(self.env_ids, device=env.sim.device)

    @property
    def full(self) -> bool:
        """Whether ``max_frames`` frames were recorded."""
        return self.max_frames is not None and len(self.builder) >= self.max_frames

    def capture(self, extras: Mapping[str, torch.Tensor | np.ndarray] | None = None) -> None:
        """Append one frame: the simulator state of the recorded rows and ``extras`` {name: [N, ...]}
        (rows of all N envs; the recorded ones are kept)."""
        if self.full:
            return
        sim = self.env.sim
        state = sim.state
        frame = state_frame(state, self._rows, sim.airframe.num_motors)
        frame["sim_time"] = state["time"][self._rows].cpu().numpy()
        for name, value in (extras or {}).items():
            rows = value[self._rows] if isinstance(value, torch.Tensor) else np.asarray(value)[self.env_ids]
            rows = rows.detach().cpu().numpy() if isinstance(rows, torch.Tensor) else rows
            frame[name] = rows[:, 0] if rows.ndim == 2 and rows.shape[1] == 1 else rows
        sea = sea_snapshot(getattr(sim, "sea", None), state.get("over_water", None), self._rows)
        self.builder.add(len(self.builder) * float(self.env.control_dt), frame, sea)

    def recording(self) -> Recording:
        """What was recorded so far."""
        return self.builder.build()


def save_recording(log: FlightLog | None, path: str | Path | None, default: Path | None) -> Path:
    """Write what ``log`` recorded to ``path`` (else ``default``), the file written; ValueError when
    there is no path or nothing was recorded (the recorders' ``save``)."""
    target = path if path is not None else default
    if target is None:
        raise ValueError("no path: pass one here or to the constructor")
    if log is None:
        raise ValueError("nothing was recorded: append the recorder to an env and reset it")
    return log.recording().save(target)


def task_extras(task: Mapping[str, torch.Tensor] | None) -> dict[str, torch.Tensor]:
    """The task's entries {name: [N, ...]} as recording fields: what the aircraft should follow now
    (``reference_x`` and ``x_command`` entries, e.g. reference_altitude, bank_command) under
    ``reference/x``, the others (targets, errors) under ``task/<name>``."""
    out: dict[str, torch.Tensor] = {}
    for name, value in ({} if task is None else task).items():
        if name.startswith("reference_") and name != "reference_error":
            out[f"reference/{name[len('reference_'):]}"] = value
        elif name == "termination_reason":
            out[name] = value
        elif name.endswith("_command") and name != "stream_command":
            out[f"reference/{name[:-len('_command')]}"] = value
        else:
            out[f"task/{name}"] = value
    return out


def record_simulator(simulator: Any, commands: torch.Tensor | Any, steps: int, substeps: int = 1,
                     meta: Mapping[str, Any] | None = None) -> Recording:
    """Fly ``simulator`` from its current state for ``steps`` frames of ``substeps`` physics steps and
    record every aircraft (and, over the sea, their wave fields). ``commands`` is a fixed [N, C] command,
    or a callable ``(state) -> [N, C]``. A small helper for scripts and tests; envs are recorded by the
    recorder transform/wrapper."""
    builder = RecordingBuilder({"airframe": simulator.airframe.name, "dt": simulator.dt * substeps,
                                **dict(meta or {})})
    motors = simulator.airframe.num_motors
    state = simulator.state
    sea = getattr(simulator, "sea", None)
    builder.add(float(state["time"][0]), state_frame(state, num_motors=motors),
                sea_snapshot(sea, state.get("over_water", None)))
    for _ in range(steps):
        command = commands(state) if callable(commands) else commands
        simulator.step(command, substeps=substeps)
        state = simulator.state
        builder.add(float(state["time"][0]), state_frame(state, num_motors=motors),
                    sea_snapshot(sea, state.get("over_water", None)))
    return builder.build()


__all__ = ["FIELD_DTYPE_KINDS", "FIELD_TRAILING_SHAPES", "MAX_META_BYTES", "MAX_META_DEPTH",
           "MAX_RECORDING_BYTES", "META_SCHEMA", "RECORDING_FORMAT", "REQUIRED_FIELDS", "SEA_COMPONENTS",
           "FlightLog", "Recording", "RecordingBuilder", "RecordingError", "check_layout", "check_meta",
           "check_time", "quaternion_euler", "record_simulator", "save_recording", "sea_snapshot",
           "state_frame", "task_extras"]
