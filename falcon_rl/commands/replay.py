"""``falcon-rl replay``: look again at a recorded flight.

    falcon-rl replay flight.npz --gif flight.gif --plots plots/
    falcon-rl replay flight.npz --acmi flight.zip.acmi --flightgear 127.0.0.1:5550

Reads a recording (``falcon-rl fly --record``, the ``FlightRecorder`` transform or the Gymnasium
``RecordFlight`` wrappers) and writes the same outputs as ``fly``: time-domain panels, a 3D animation,
a Tacview file, a live FlightGear stream. A file that is not a recording, or one that breaks its
schema, exits 2 with one line naming the file, the field and the constraint, before anything is
written: the arrays' headers are checked before any data is read (dtypes, shapes consistent with
``time``, at most ``MAX_RECORDING_BYTES``, 2 GiB, of arrays), then the metadata field by field (see
:mod:`falcon_rl.recording`).
"""

from __future__ import annotations

import argparse

from ._common import UsageError, emit, nonnegative_int
from ._views import add_view_arguments, check_view_arguments, write_views

NAME = "replay"
HELP = "write plots, a 3D animation, a Tacview file or a FlightGear stream from a flight recording"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("recording", help="a recording file (.npz) written by fly --record or a recorder")
    parser.add_argument("--envs", default=None,
                        help="comma list of the recorded aircraft to show (indices, default all)")
    parser.add_argument("--seed", type=nonnegative_int, default=0, help=argparse.SUPPRESS)
    add_view_arguments(parser, record=False)


def _indices(text: str | None, count: int) -> list[int] | None:
    """The --envs indices (each in [0, count)), else UsageError."""
    if text is None:
        return None
    items = [item.strip() for item in text.split(",") if item.strip()]
    if not items or not all(item.isdigit() and int(item) < count for item in items):
        raise UsageError(f"--envs {text!r} must be a comma list of indices in [0, {count})")
    return [int(item) for item in items]


def run(args: argparse.Namespace) -> int:
    from ..recording import Recording, RecordingError

    try:
        recording = Recording.load(args.recording)
    except RecordingError as error:
        raise UsageError(str(error)) from None
    envs = _indices(args.envs, recording.num_envs)
    if envs is not None:
        recording = recording.select(envs)
    check_view_arguments(args)
    written = write_views(args, recording)
    meta = recording.meta
    doc = {"recording": args.recording, "airframe": meta.get("airframe"), "task": meta.get("task"),
           "controller": meta.get("controller"), "frames": recording.num_frames, "envs": recording.num_envs,
           "seconds": float(recording.time[-1] - recording.time[0]), "outputs": written}
    lines = [f"{args.recording}: {recording.num_frames} frames of {recording.num_envs} aircraft "
             f"({meta.get('airframe')}, {doc['seconds']:.2f} s)"]
    lines += [f"{name}: {value}" for name, value in written.items()] or ["nothing to write: ask for "
                                                                          "--plots, --gif, --mp4, --acmi "
                                                                          "or --flightgear"]
    emit(args, doc, "\n".join(lines))
    return 0
