"""The paper's time-domain panels of a flight recording (:class:`~falcon_rl.recording.Recording`).

Each ``plot_*`` function draws one panel of the aircraft ``envs`` (indices into E; None: the first
:data:`~.timeseries_panels.MAX_AIRCRAFT_PER_FIGURE`) against time (s), overlaid in colours or, with
``facet=True``, one column per aircraft, writes it to ``path`` (.png, .svg or .pdf) and returns the
path, or None without writing when the recording has none of the panel's fields. Absent fields are
left out of a panel. Angles are shown in degrees, everything else in SI units.

- :func:`plot_states`: position (north, east, height), Euler angles, airspeed, ground speed and climb
  rate, alpha and beta, body rates.
- :func:`plot_forces`: aerodynamic force and moment (body FRD), the six coefficients, thrust per motor
  (the total when ``motor_thrust`` is absent).
- :func:`plot_actuators`: commanded (dashed, the normalised command mapped by the physics' own
  :func:`~falcon_rl.physics.actuators.command_targets` with the airframe's limits) against achieved
  (solid) deflection and throttle.
- :func:`plot_ground_effect`: h/b (``ge_h_over_b``, else wing_height / span), the lift and drag
  influence factors, CG and lowest wing-tip height.
- :func:`plot_tracking`: every task reference ``reference/<name>`` (dashed; the recorders write a
  task's ``reference_x`` and ``x_command`` entries as ``reference/x``) against the recorded quantity it
  commands (solid), and the reward per step and summed. The name is matched after dropping a
  ``reference_``, ``target_`` or ``commanded_`` prefix and a ``_command`` suffix, then
  through :data:`REFERENCE_ALIASES` (altitude -> height, bank -> roll, heading -> yaw, path_height ->
  height, path_course -> course, position -> position_ned, velocity -> velocity_ned) to a key of
  :data:`QUANTITIES`. A reference that matches nothing (an error, a path point) is drawn alone, in the
  units it was recorded in.
- :func:`plot_all`: all five panels into a folder.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path

import numpy as np
import torch

from ..airframe import AERO_COEFFICIENTS, SURFACES, Airframe, AirframeError, load_airframe
from ..constants import DEG
from ..physics.actuators import command_targets
from ..physics.params import build_params
from ..recording import Recording
from .timeseries_panels import (
    QUANTITIES,
    Line,
    Quantity,
    Row,
    as_float,
    check_formats,
    check_path,
    plot_of,
    recorded,
    render,
    row_of,
    select_aircraft,
    write,
)

#: Line styles of the motors of one aircraft (cycled).
_MOTOR_STYLES: tuple[str, ...] = ("-", "-.", ":", (0, (5, 1)))


#: Task reference names (prefix and suffix dropped) -> the key of :data:`QUANTITIES` they command.
REFERENCE_ALIASES: dict[str, str] = {
    "altitude": "height", "bank": "roll", "heading": "yaw", "path_height": "height", "path_course": "course",
    "position": "position_ned", "velocity": "velocity_ned",
}


def reference_counterpart(name: str) -> str | None:
    """The key of :data:`QUANTITIES` that the task reference ``name`` (``reference/<name>``) commands,
    or None (e.g. ``reference_altitude`` -> ``height``, ``bank_command`` -> ``roll``, ``altitude_error``
    -> None)."""
    stem = name
    for prefix in ("reference_", "target_", "commanded_"):
        stem = stem.removeprefix(prefix)
    stem = stem.removesuffix("_command")
    stem = REFERENCE_ALIASES.get(stem, stem)
    return stem if stem in QUANTITIES else None


# ---------------------------------------------------------------------------------------- airframe
@functools.lru_cache(maxsize=16)
def _load_airframe(name: str) -> Airframe | None:
    try:
        return load_airframe(name)
    except (AirframeError, OSError, ValueError):
        return None


def _recording_airframe(rec: Recording) -> Airframe | None:
    """The airframe ``meta["airframe"]`` names, or None when absent or not loadable."""
    name = rec.meta.get("airframe")
    return _load_airframe(str(name)) if name else None


def commanded_targets(command: np.ndarray, airframe: Airframe) -> tuple[np.ndarray, np.ndarray]:
    """Normalised commands [..., 4] in [-1, 1] (elevator, aileron, rudder, throttle) -> the physics'
    targets: (deflections [..., 3] rad between the airframe's actuator limits, throttle [...] in [0, 1]).
    The same clip and affine map the actuators use (:func:`falcon_rl.physics.actuators.command_targets`)."""
    command = as_float(command)
    if command.shape[-1] != 4:
        raise ValueError(f"command must be [..., 4], got shape {command.shape}")
    limits = build_params(airframe, 1, dtype=torch.float64)
    surfaces, throttle = command_targets(torch.from_numpy(command.reshape(-1, 4)), limits)
    return surfaces.numpy().reshape(*command.shape[:-1], 3), throttle.numpy().reshape(command.shape[:-1])


def _coefficient_title(name: str) -> str:
    """"CL" -> "$C_{L}$"."""
    return f"${name[0]}_{{{name[1:]}}}$"


# ---------------------------------------------------------------------------------------- panels
def state_rows(rec: Recording) -> list[Row | None]:
    """Position, Euler angles, speeds, aerodynamic angles and body rates."""
    q = QUANTITIES
    return [
        row_of("position (m)", [plot_of("north", [q["position_ned"].line(rec, 0)]),
                                plot_of("east", [q["position_ned"].line(rec, 1)]),
                                plot_of("height", [q["height"].line(rec)])]),
        row_of("attitude (deg)", [plot_of(name, [q["euler"].line(rec, i)])
                                  for i, name in enumerate(q["euler"].components)]),
        row_of("speed (m/s)", [plot_of(q[name].label, [q[name].line(rec)])
                               for name in ("airspeed", "ground_speed", "climb_rate")]),
        row_of("aero angle (deg)", [plot_of(f"$\\{name}$", [q[name].line(rec)])
                                    for name in ("alpha", "beta")]),
        row_of("body rate (deg/s)", [plot_of(name, [q["angular_rate_body"].line(rec, i)])
                                     for i, name in enumerate(q["angular_rate_body"].components)]),
    ]


def force_rows(rec: Recording) -> list[Row | None]:
    """Aerodynamic force and moment in body FRD, the six coefficients, thrust per motor (or total)."""
    def vector(field: str, unit: str, names: Sequence[str]) -> list:
        quantity = Quantity(field, unit, recorded(field))
        return [plot_of(name, [quantity.line(rec, i)]) for i, name in enumerate(names)]

    coefficients = Quantity("coefficient", "-", recorded("aero_coefficients"))
    coefficient_plots = [plot_of(_coefficient_title(name), [coefficients.line(rec, i)])
                         for i, name in enumerate(AERO_COEFFICIENTS)]
    if rec.has("motor_thrust"):
        motors = rec["motor_thrust"].shape[2]
        thrust = [Line(f"motor {m + 1}", as_float(rec["motor_thrust"][..., m]), _MOTOR_STYLES[m % 4])
                  for m in range(motors)]
    else:
        thrust = [Line("total", as_float(rec["thrust"]))] if rec.has("thrust") else []
    return [
        row_of("aero force (N)", vector("aero_force_body", "N", ("X (forward)", "Y (right)", "Z (down)"))),
        row_of("aero moment (N m)", vector("aero_moment_body", "N m", ("roll L", "pitch M", "yaw N"))),
        row_of("force coefficient", coefficient_plots[:3]),
        row_of("moment coefficient", coefficient_plots[3:]),
        row_of("thrust (N)", [plot_of("thrust per motor" if rec.has("motor_thrust") else "total thrust",
                                      thrust)]),
    ]


def actuator_rows(rec: Recording) -> list[Row | None]:
    """Per surface commanded (dashed) vs achieved (solid) deflection in degrees; throttle likewise
    (achieved per motor). The commanded lines need ``command`` and a loadable ``meta["airframe"]``."""
    airframe = _recording_airframe(rec)
    commanded_surfaces = commanded_throttle = None
    if rec.has("command") and airframe is not None:
        commanded_surfaces, commanded_throttle = commanded_targets(rec["command"], airframe)
    achieved = rec["surface_position"] if rec.has("surface_position") else None
    surfaces = []
    for i, name in enumerate(SURFACES):
        surfaces.append(plot_of(name, [
            None if commanded_surfaces is None else Line("commanded", commanded_surfaces[..., i] / DEG, "--"),
            None if achieved is None else Line("achieved", as_float(achieved[..., i]) / DEG, "-")]))
    throttle = [] if commanded_throttle is None else [Line("commanded", commanded_throttle, "--")]
    if rec.has("throttle"):
        motors = rec["throttle"].shape[2]
        throttle += [Line("achieved" if motors == 1 else f"achieved motor {m + 1}",
                          as_float(rec["throttle"][..., m]), _MOTOR_STYLES[m % 4]) for m in range(motors)]
    return [row_of("deflection (deg)", surfaces), row_of("throttle (0-1)", [plot_of("throttle", throttle)])]


def ground_effect_rows(rec: Recording) -> list[Row | None]:
    """h/b, the lift and drag influence factors (1 out of ground effect), CG and lowest-tip height."""
    airframe = _recording_airframe(rec)
    if rec.has("ge_h_over_b"):
        h_over_b = Line("", as_float(rec["ge_h_over_b"]))
    elif rec.has("wing_height") and airframe is not None:
        h_over_b = Line("", as_float(rec["wing_height"]) / airframe.geometry.span)
    else:
        h_over_b = None
    factors = [plot_of(title, [Line("", as_float(rec[name]))] if rec.has(name) else [])
               for title, name in (("lift", "ge_lift_factor"), ("induced drag", "ge_drag_factor"))]
    return [
        row_of("h/b", [plot_of("wing height / span", [h_over_b])]),
        row_of("influence factor", factors),
        row_of("height (m)", [plot_of("above ground", [
            QUANTITIES["height"].line(rec, label="CG", style="-") if rec.has("height") else None,
            Line("lowest wing tip", as_float(rec["lowest_tip_height"]), ":")
            if rec.has("lowest_tip_height") else None])]),
    ]


def tracking_rows(rec: Recording) -> list[Row | None]:
    """Each reference (dashed) against its :func:`reference_counterpart` (solid), in the counterpart's
    display units; a reference without one alone as recorded; then the reward per step and summed."""
    rows: list[Row | None] = []
    for name, reference in rec.references().items():
        reference = as_float(reference)
        if reference.ndim > 3:
            continue
        key = reference_counterpart(name)
        quantity = QUANTITIES[key] if key is not None else None
        width = reference.shape[2] if reference.ndim == 3 else 0
        if quantity is not None and len(quantity.components) != width:
            quantity = None
        components = range(width) if width else [None]
        plots = []
        for c in components:
            values = reference if c is None else reference[..., c]
            title = name if c is None else f"{name} {quantity.components[c] if quantity else c}"
            scale = quantity.scale if quantity else 1.0
            achieved = quantity.line(rec, c, "achieved", "-") if quantity else None
            plots.append(plot_of(title, [Line("reference", values * scale, "--"), achieved]))
        ylabel = f"{quantity.label} ({quantity.unit})" if quantity else f"{name} (as recorded)"
        rows.append(row_of(ylabel, plots))
    if rec.has("reward"):
        reward = as_float(rec["reward"])
        rows.append(row_of("reward", [plot_of("reward per step", [Line("", reward)]),
                                      plot_of("summed reward", [Line("", np.nancumsum(reward, axis=0))])]))
    return rows


#: Panel name (the file stem) -> (title, rows builder).
PANELS: dict[str, tuple[str, Callable[[Recording], list[Row | None]]]] = {
    "states": ("states", state_rows),
    "forces": ("forces and moments", force_rows),
    "actuators": ("actuators: commanded (dashed) vs achieved (solid)", actuator_rows),
    "ground_effect": ("ground effect", ground_effect_rows),
    "tracking": ("tracking: reference (dashed) vs achieved (solid)", tracking_rows),
}


# ---------------------------------------------------------------------------------------- public API
def _plot_panel(panel: str, rec: Recording, paths: Sequence[Path], envs: Sequence[int] | None,
                facet: bool) -> list[Path]:
    title, rows = PANELS[panel]
    selected = select_aircraft(rec, envs)
    fig = render(selected, rows(selected), title, facet)
    return [] if fig is None else write(fig, paths)


def _plot_one(panel: str, rec: Recording, path: str | Path, envs: Sequence[int] | None, facet: bool
              ) -> Path | None:
    written = _plot_panel(panel, rec, [check_path(path)], envs, facet)
    return written[0] if written else None


def plot_states(rec: Recording, path: str | Path, envs: Sequence[int] | None = None, facet: bool = False
                ) -> Path | None:
    """Position (m), Euler angles (deg), airspeed / ground speed / climb rate (m/s), alpha and beta (deg),
    body rates (deg/s) of the aircraft ``envs`` of ``rec`` ([T, E, ...] fields) against time [T] (s)."""
    return _plot_one("states", rec, path, envs, facet)


def plot_forces(rec: Recording, path: str | Path, envs: Sequence[int] | None = None, facet: bool = False
                ) -> Path | None:
    """Aerodynamic force (N) and moment (N m) in body FRD ([T, E, 3] each), the six coefficients
    ([T, E, 6]) and thrust per motor ([T, E, M], N; the total [T, E] when per-motor is absent)."""
    return _plot_one("forces", rec, path, envs, facet)


def plot_actuators(rec: Recording, path: str | Path, envs: Sequence[int] | None = None, facet: bool = False
                   ) -> Path | None:
    """Commanded (dashed, ``command`` [T, E, 4] mapped by :func:`commanded_targets`) vs achieved (solid,
    ``surface_position`` [T, E, 3] rad) deflection in deg per surface, and throttle [0, 1] (achieved
    ``throttle`` [T, E, M] per motor)."""
    return _plot_one("actuators", rec, path, envs, facet)


def plot_ground_effect(rec: Recording, path: str | Path, envs: Sequence[int] | None = None,
                       facet: bool = False) -> Path | None:
    """h/b ([T, E]: ``ge_h_over_b``, else ``wing_height`` / span), lift and induced-drag influence factors
    ([T, E]), CG height and lowest wing-tip height ([T, E], m)."""
    return _plot_one("ground_effect", rec, path, envs, facet)


def plot_tracking(rec: Recording, path: str | Path, envs: Sequence[int] | None = None, facet: bool = False
                  ) -> Path | None:
    """Each ``reference/<name>`` ([T, E] or [T, E, C]) against the quantity :func:`reference_counterpart`
    maps it to, and ``reward`` [T, E] per step and summed over the recording."""
    return _plot_one("tracking", rec, path, envs, facet)


def plot_all(rec: Recording, out_dir: str | Path, formats: Iterable[str] = ("png",),
             envs: Sequence[int] | None = None, facet: bool = False) -> list[Path]:
    """Write every panel with data as ``out_dir/<panel>.<format>`` (panels: states, forces, actuators,
    ground_effect, tracking; formats: png, svg, pdf) and return the paths written, panel by panel."""
    chosen = check_formats(formats)
    select_aircraft(rec, envs)  # refuse bad arguments before writing anything
    out_dir = Path(out_dir)
    written: list[Path] = []
    for panel in PANELS:
        written += _plot_panel(panel, rec, [out_dir / f"{panel}.{fmt}" for fmt in chosen], envs, facet)
    return written
