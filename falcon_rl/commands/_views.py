"""What ``fly``, ``replay`` and ``demo`` write from a recording: the recording itself, the time-domain
panels, a 3D animation, a Tacview file and a live FlightGear stream (the options and the writer)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from ._common import UsageError, nonnegative_float, output_dir, output_file


def host_port(text: str) -> tuple[str, int]:
    """``HOST:PORT`` (port in 1..65535), else UsageError."""
    host, sep, port = text.rpartition(":")
    if not sep or not host or not port.isdigit() or not 1 <= int(port) <= 65535:
        raise UsageError(f"--flightgear {text!r} must be HOST:PORT with a port in 1..65535")
    return host, int(port)


def add_view_arguments(parser: argparse.ArgumentParser, record: bool = True) -> None:
    """--record (when ``record``), --plots, --gif / --mp4, --acmi, --flightgear, --flightgear-speed."""
    if record:
        parser.add_argument("--record", default=None, help="write the flight recording (.npz) here")
    parser.add_argument("--plots", default=None, help="folder for the time-domain panels (PNG)")
    movie = parser.add_mutually_exclusive_group()
    movie.add_argument("--gif", default=None, help="write a 3D animation (GIF) here")
    movie.add_argument("--mp4", default=None, help="write a 3D animation (MP4, ffmpeg) here")
    parser.add_argument("--acmi", default=None, help="write a Tacview file here (.acmi or .zip.acmi)")
    parser.add_argument("--flightgear", default=None, metavar="HOST:PORT",
                        help="stream aircraft 0 to FlightGear's native-fdm UDP input "
                             "(fgfs --fdm=null --native-fdm=socket,in,60,,5550,udp)")
    parser.add_argument("--flightgear-speed", type=nonnegative_float, default=1.0,
                        help="FlightGear stream pace: 1 real time, 2 twice as fast, 0 as fast as possible")


def check_view_arguments(args: argparse.Namespace) -> None:
    """Every output path writable and the FlightGear address valid, before anything flies."""
    for flag in ("record", "gif", "mp4", "acmi"):
        value = getattr(args, flag, None)
        if value is not None:
            output_file(value, f"--{flag}")
    if args.gif is not None and not args.gif.lower().endswith(".gif"):
        raise UsageError(f"--gif {args.gif!r} must end in .gif")
    if args.mp4 is not None and not args.mp4.lower().endswith(".mp4"):
        raise UsageError(f"--mp4 {args.mp4!r} must end in .mp4")
    if args.acmi is not None and not args.acmi.lower().endswith(".acmi"):
        raise UsageError(f"--acmi {args.acmi!r} must end in .acmi or .zip.acmi")
    if args.plots is not None:
        output_dir(args.plots, "--plots")
    if args.flightgear is not None:
        host_port(args.flightgear)


def write_views(args: argparse.Namespace, recording: Any) -> dict[str, Any]:
    """Write what the options ask for; returns {output: path or paths} (and FlightGear's packet count)."""
    written: dict[str, Any] = {}
    if getattr(args, "record", None):
        written["record"] = str(recording.save(args.record))
    if args.plots:
        from ..viz.timeseries import plot_all

        written["plots"] = [str(p) for p in plot_all(recording, Path(args.plots))]
    movie = args.gif or args.mp4
    if movie:
        from ..viz.animation import write_animation

        written["gif" if args.gif else "mp4"] = str(write_animation(recording, movie))
    if args.acmi:
        from ..viz.acmi import write_acmi

        written["acmi"] = str(write_acmi(recording, args.acmi))
    if args.flightgear:
        from ..bridges.flightgear import FlightGearStreamer

        host, port = host_port(args.flightgear)
        with FlightGearStreamer(host, port, realtime=args.flightgear_speed > 0) as streamer:
            written["flightgear_packets"] = streamer.stream(recording, speed=args.flightgear_speed)
    return written
