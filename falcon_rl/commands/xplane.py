"""``falcon-rl xplane``: fly a controller around X-Plane's aircraft over X-Plane's UDP interface.

    falcon-rl xplane --controller lqr --task altitude --airframe volantex_ranger        # X-Plane on 49000
    falcon-rl xplane --controller lqr --standin --seconds 10 --json                    # no X-Plane needed
    falcon-rl xplane --controller lqr --host 192.168.1.20 --bind 0.0.0.0 --record flight.npz

X-Plane: enable its UDP interface (Settings > Network, port 49000) and load an aircraft that matches
``--airframe``; the bridge places it at the task's initial condition, then reads the state (RREF) and
writes yoke ratios and throttle (DREF) each control step, on the wall clock. ``--standin`` starts a
loopback stand-in (falcon-rl's own simulator behind the same packets) on an ephemeral port and flies
it in lock-step, so that the command can be tried, and gives the same numbers as ``eval``, without
X-Plane. ``--json`` prints one document: the task's metrics, the status and the packet counts.
No state from X-Plane within ``--timeout`` s exits 1 with one line on stderr.
"""

from __future__ import annotations

import argparse
import sys

from ..defaults import DEFAULT_AIRFRAME
from ._common import (
    UsageError,
    bounded_float,
    bounded_int,
    check_controller,
    emit,
    episode_seconds,
    nonnegative_int,
    one_line,
    output_file,
)

NAME = "xplane"
HELP = "fly a controller around X-Plane's aircraft over its UDP interface (or a loopback stand-in)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from ..envs.tasks import task_names

    parser.add_argument("--controller", required=True,
                        help="a controller of the task (lqr, mppi, trim), ppo or a policy file")
    parser.add_argument("--task", choices=task_names(), default="altitude")
    parser.add_argument("--airframe", default=DEFAULT_AIRFRAME, help="shipped name or path to a JSON file")
    parser.add_argument("--host", default="127.0.0.1", help="X-Plane's address (default 127.0.0.1)")
    parser.add_argument("--port", type=bounded_int(1, 65535), default=49000, help="X-Plane's UDP port")
    parser.add_argument("--bind", default="127.0.0.1",
                        help="local address of the bridge's socket (default loopback; 0.0.0.0 for a remote "
                             "X-Plane)")
    parser.add_argument("--seconds", type=episode_seconds, default=None,
                        help="flight length, s (default: the task's episode)")
    parser.add_argument("--seed", type=nonnegative_int, default=0, help="seed of the task's episode draw")
    parser.add_argument("--timeout", type=bounded_float(0.0, 600.0, "s"), default=2.0,
                        help="s to wait for a state from X-Plane (default 2)")
    parser.add_argument("--record", default=None, help="write the flight log (.npz recording) here")
    parser.add_argument("--standin", action="store_true",
                        help="fly a loopback X-Plane stand-in (lock-step) instead of X-Plane; --host/--port "
                             "ignored")


def run(args: argparse.Namespace) -> int:
    from ..airframe import load_airframe

    airframe = load_airframe(args.airframe)
    check_controller(args.controller, args.task, args.airframe)
    record = output_file(args.record, "--record") if args.record is not None else None
    if "\0" in args.host or not args.host.strip():
        raise UsageError(f"--host {args.host!r} is not a host name or address")
    from ..bridges.xplane import XPlaneBridge, XPlaneTimeout
    from ..bridges.xplane_standin import XPlaneStandIn

    try:
        if args.standin:
            from ..envs.tasks import task_spec

            decimation = int(task_spec(args.task).env_default("decimation", 1))
            with XPlaneStandIn(airframe, frame_seconds=decimation * 0.01) as standin, \
                    XPlaneBridge("127.0.0.1", standin.port, **_bridge_options(args)) as bridge:
                result = bridge.fly()
                standin_doc = standin.snapshot()
        else:
            with XPlaneBridge(args.host, args.port, bind=args.bind, pacing="wallclock",
                              **_bridge_options(args)) as bridge:
                result = bridge.fly()
                standin_doc = None
    except XPlaneTimeout as error:
        print(f"falcon-rl xplane: error: {one_line(error)}", file=sys.stderr)
        return 1
    except OSError as error:  # --host that does not resolve, --bind that is not a local address
        raise UsageError(f"cannot open the link to {args.host}:{args.port}: {error}") from None
    doc = {**result.document(), "standin": standin_doc}
    if record is not None:
        doc["record"] = str(result.recording.save(record))
    lines = [f"{result.settings['controller']} on {result.settings['airframe']}, task {args.task}, "
             f"through {'the stand-in' if args.standin else 'X-Plane at ' + result.settings['address']}:",
             f"  status {result.status} ({result.termination_reason}), {result.seconds_flown:.2f} s flown "
             f"in {result.wall_seconds:.1f} s",
             *(f"  {name}: {value:.4g}" for name, value in result.metrics.items()),
             "  packets: " + ", ".join(f"{k} {v}" for k, v in result.packets.items())]
    if "record" in doc:
        lines.append(f"  recording: {doc['record']}")
    emit(args, doc, "\n".join(lines))
    return 0 if result.status != "timeout" else 1


def _bridge_options(args: argparse.Namespace) -> dict:
    return {"task": args.task, "airframe": args.airframe, "controller": args.controller,
            "seconds": args.seconds, "seed": args.seed, "timeout": args.timeout}
