"""The time-domain panels of a flight recording (falcon_rl.viz.timeseries): files, skipped panels,
layouts, argument checks and the command-to-deflection mapping."""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
import pytest
import torch
from PIL import Image

from falcon_rl import Simulator
from falcon_rl.constants import DEG
from falcon_rl.recording import Recording, record_simulator
from falcon_rl.viz import timeseries
from falcon_rl.viz.timeseries_panels import MAX_AIRCRAFT_PER_FIGURE, render, select_aircraft, unwrap_in_time

FRAMES = 40
#: The engine's diagnostics and the env's fields: a plain simulator recording without them must still plot.
DIAGNOSTICS = ("aero_force_body", "aero_moment_body", "motor_thrust", "ge_h_over_b", "ge_lift_factor",
               "ge_drag_factor", "reward", "action")
COMMAND = (0.5, -0.25, 0.0, 0.2)


@pytest.fixture(scope="module")
def recording(ranger) -> Recording:
    """40 frames of two aircraft at a fixed command, with an altitude reference, a reference without a
    counterpart and a reward added as an env recorder would."""
    sim = Simulator(ranger, num_envs=2, backend="torch")
    sim.reset()
    rec = record_simulator(sim, torch.tensor([COMMAND] * 2), FRAMES, meta={"labels": ["left", "right"]})
    rec.fields["reference/altitude"] = rec["height"] + 2.0
    rec.fields["reference/rate"] = np.full_like(rec["height"], -2.0)
    rec.fields["reward"] = np.linspace(0.0, 1.0, rec.num_frames, dtype=np.float32)[:, None].repeat(2, 1)
    return rec


def without(rec: Recording, names: tuple[str, ...]) -> Recording:
    """``rec`` without the fields ``names`` and without any reference."""
    fields = {k: v for k, v in rec.fields.items() if k not in names and not k.startswith("reference/")}
    return Recording(rec.time, fields, rec.meta)


def bare_recording(rec: Recording) -> Recording:
    """``rec`` with only the fields every recording has (position and quaternion)."""
    return Recording(rec.time, {name: rec[name] for name in ("position_ned", "quaternion")}, rec.meta)


def assert_png(path, min_size=(300, 200)) -> None:
    assert path.is_file() and path.stat().st_size > 0
    with Image.open(path) as image:
        assert image.format == "PNG"
        assert image.size[0] >= min_size[0] and image.size[1] >= min_size[1]


def test_plot_all_writes_every_panel_as_png_and_svg(recording, tmp_path):
    written = timeseries.plot_all(recording, tmp_path, formats=("png", "svg"))
    panels = ("states", "forces", "actuators", "ground_effect", "tracking")
    assert written == [tmp_path / f"{panel}.{fmt}" for panel in panels for fmt in ("png", "svg")]
    for path in written:
        if path.suffix == ".png":
            assert_png(path)
        else:
            assert "<svg" in path.read_text()[:2000]


@pytest.mark.parametrize("plot", [timeseries.plot_states, timeseries.plot_actuators])
def test_recording_without_diagnostics_still_plots(recording, tmp_path, plot):
    plain = without(recording, DIAGNOSTICS)
    path = plot(plain, tmp_path / "panel.png")
    assert path == tmp_path / "panel.png"
    assert_png(path)


def test_recording_without_diagnostics_keeps_what_exists(recording, ranger):
    plain = without(recording, DIAGNOSTICS)
    force, moment, force_coefficients, moment_coefficients, thrust = timeseries.force_rows(plain)
    assert force is None and moment is None
    assert [p.title for p in force_coefficients.plots] == ["$C_{L}$", "$C_{D}$", "$C_{Y}$"]
    assert moment_coefficients is not None
    assert [line.label for line in thrust.plots[0].lines] == ["total"]
    h_over_b, factors, height = timeseries.ground_effect_rows(plain)
    assert factors is None
    span = ranger.geometry.span
    np.testing.assert_allclose(h_over_b.plots[0].lines[0].values, recording["wing_height"] / span, rtol=1e-5)
    np.testing.assert_allclose(h_over_b.plots[0].lines[0].values, recording["ge_h_over_b"], rtol=1e-4)
    assert [line.label for line in height.plots[0].lines] == ["CG", "lowest wing tip"]


def test_panel_without_its_fields_is_skipped_not_an_error(recording, tmp_path):
    plain = without(recording, DIAGNOSTICS)
    assert timeseries.plot_tracking(plain, tmp_path / "tracking.png") is None
    assert not (tmp_path / "tracking.png").exists()
    bare = bare_recording(recording)
    assert [p.name for p in timeseries.plot_all(bare, tmp_path / "bare")] == ["states.png"]
    for builder in (timeseries.force_rows, timeseries.actuator_rows, timeseries.ground_effect_rows,
                    timeseries.tracking_rows):
        assert all(row is None for row in builder(bare))


def test_svg_path_writes_svg(recording, tmp_path):
    path = timeseries.plot_actuators(recording, tmp_path / "actuators.svg")
    assert path.read_text().lstrip().startswith("<?xml") and "<svg" in path.read_text()


def test_facet_draws_one_column_per_aircraft(recording, tmp_path):
    rows = [row for row in timeseries.state_rows(recording) if row is not None]
    faceted = render(recording, rows, "states", facet=True)
    overlaid = render(recording, rows, "states")
    try:
        assert len(faceted.axes) == len(rows) * recording.num_envs
        assert [ax.get_title() for ax in faceted.axes[:recording.num_envs]] == ["left", "right"]
        widest = max(len(row.plots) for row in rows)
        assert len(overlaid.axes) == len(rows) * widest
        assert len(overlaid.axes[0].lines) == recording.num_envs  # north, one line per aircraft
    finally:
        plt.close(faceted)
        plt.close(overlaid)
    assert_png(timeseries.plot_actuators(recording, tmp_path / "facet.png", facet=True))


def test_commanded_targets_map_the_command_onto_the_airframe_limits(ranger):
    command = np.array([[1.0, 1.0, 1.0, 1.0], [-1.0, -1.0, -1.0, -1.0], [0.0, 0.0, 0.0, 0.0],
                        [2.0, -3.0, 0.5, 0.5]])
    surfaces, throttle = timeseries.commanded_targets(command, ranger)
    low = np.array([ranger.actuators[s].limits[0] for s in ("elevator", "aileron", "rudder")])
    high = np.array([ranger.actuators[s].limits[1] for s in ("elevator", "aileron", "rudder")])
    np.testing.assert_allclose(surfaces[0], high, rtol=1e-12)
    np.testing.assert_allclose(surfaces[1], low, rtol=1e-12)
    np.testing.assert_allclose(surfaces[2], 0.5 * (low + high), atol=1e-12)
    np.testing.assert_allclose(surfaces[3], [high[0], low[1], low[2] + 0.75 * (high[2] - low[2])], rtol=1e-12)
    np.testing.assert_allclose(throttle, [1.0, 0.0, 0.5, 0.75], rtol=1e-12)
    # the shape [T, E, 4] of a recording is kept
    surfaces, throttle = timeseries.commanded_targets(np.zeros((5, 3, 4)), ranger)
    assert surfaces.shape == (5, 3, 3) and throttle.shape == (5, 3)


def test_actuator_panel_draws_the_mapped_command_in_degrees(recording, ranger):
    deflection, throttle = timeseries.actuator_rows(recording)
    elevator = deflection.plots[0]
    commanded = next(line for line in elevator.lines if line.label == "commanded")
    achieved = next(line for line in elevator.lines if line.label == "achieved")
    low, high = ranger.actuators["elevator"].limits
    # frame 0 is the state after reset, before the first command
    np.testing.assert_allclose(commanded.values[1:], (low + 0.75 * (high - low)) / DEG, rtol=1e-6)
    np.testing.assert_allclose(achieved.values, recording["surface_position"][..., 0] / DEG, rtol=1e-5)
    assert commanded.style == "--" and achieved.style == "-"
    throttle_commanded = next(line for line in throttle.plots[0].lines if line.label == "commanded")
    np.testing.assert_allclose(throttle_commanded.values[1:], 0.6, rtol=1e-6)


def test_references_are_matched_to_the_quantity_they_command(recording):
    assert timeseries.reference_counterpart("reference_altitude") == "height"
    assert timeseries.reference_counterpart("target_altitude") == "height"
    assert timeseries.reference_counterpart("bank_command") == "roll"
    assert timeseries.reference_counterpart("airspeed_command") == "airspeed"
    assert timeseries.reference_counterpart("reference_climb_rate") == "climb_rate"
    assert timeseries.reference_counterpart("reference_position") == "position_ned"
    assert timeseries.reference_counterpart("altitude_error") is None
    # the names the recorders write: reference_<x> and <x>_command entries as reference/<x>
    assert timeseries.reference_counterpart("altitude") == "height"
    assert timeseries.reference_counterpart("bank") == "roll"
    assert timeseries.reference_counterpart("climb_rate") == "climb_rate"
    assert timeseries.reference_counterpart("position") == "position_ned"
    assert timeseries.reference_counterpart("velocity") == "velocity_ned"
    assert timeseries.reference_counterpart("rate") is None
    altitude, error, reward = timeseries.tracking_rows(recording)
    reference, achieved = altitude.plots[0].lines
    np.testing.assert_allclose(reference.values - achieved.values, 2.0, rtol=1e-6)
    np.testing.assert_allclose(achieved.values, recording["height"], rtol=1e-6)
    assert altitude.ylabel == "height (m)" and error.ylabel == "rate (as recorded)"
    assert [line.label for line in error.plots[0].lines] == ["reference"]
    np.testing.assert_allclose(reward.plots[1].lines[0].values[-1], recording["reward"].sum(0), rtol=1e-6)


def test_yaw_unwrap_keeps_nan_frames_local():
    yaw = np.array([[3.1, 0.0], [np.nan, 0.1], [-3.1, 0.2], [-3.0, np.nan]])
    unwrapped = unwrap_in_time(yaw)
    np.testing.assert_allclose(unwrapped[[0, 2, 3], 0], [3.1, 2 * np.pi - 3.1, 2 * np.pi - 3.0])
    assert np.isnan(unwrapped[1, 0]) and np.isnan(unwrapped[3, 1])
    np.testing.assert_allclose(unwrapped[:3, 1], [0.0, 0.1, 0.2])


def test_states_fall_back_on_the_quaternion_for_euler_angles(recording):
    bare = bare_recording(recording)
    recorded = timeseries.QUANTITIES["euler"].extract(recording)
    derived = timeseries.QUANTITIES["euler"].extract(bare)
    np.testing.assert_allclose(derived, recorded, atol=1e-5)


def test_envs_select_and_cap_the_aircraft(recording):
    assert select_aircraft(recording, [1]).meta["labels"] == ["right"]
    many = Recording(recording.time, {k: np.repeat(v, 5, axis=1) for k, v in recording.fields.items()},
                     {"airframe": "volantex_ranger"})
    assert many.num_envs == 10
    assert select_aircraft(many, None).num_envs == MAX_AIRCRAFT_PER_FIGURE
    with pytest.raises(ValueError, match="at most"):
        select_aircraft(many, range(MAX_AIRCRAFT_PER_FIGURE + 1))


@pytest.mark.parametrize("envs", [[2], [-1], [], [0, 0], [0.5]])
def test_bad_env_index_raises(recording, tmp_path, envs):
    with pytest.raises(ValueError):
        timeseries.plot_states(recording, tmp_path / "states.png", envs=envs)
    with pytest.raises(ValueError):
        timeseries.plot_all(recording, tmp_path, envs=envs)
    assert not list(tmp_path.iterdir())


def test_unknown_format_and_empty_recording_raise(recording, tmp_path):
    with pytest.raises(ValueError, match="unknown format"):
        timeseries.plot_all(recording, tmp_path, formats=("png", "jpeg"))
    with pytest.raises(ValueError, match="unknown format"):
        timeseries.plot_states(recording, tmp_path / "states.gif")
    empty = Recording(np.zeros(0), {"position_ned": np.zeros((0, 2, 3)), "quaternion": np.zeros((0, 2, 4))})
    with pytest.raises(ValueError, match="empty recording"):
        timeseries.plot_states(empty, tmp_path / "states.png")
    assert not list(tmp_path.iterdir())
