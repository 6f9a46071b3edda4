"""``falcon-rl fly``: fly a controller on a task and look at the flight.

    falcon-rl fly --controller lqr --task attitude --airframe volantex_ranger --maneuver circle \\
        --seconds 30 --acmi a.acmi --gif a.gif --plots p/
    falcon-rl fly --controller ppo --task altitude --envs 4 --record flight.npz --mp4 flight.mp4
    falcon-rl fly --controller lqr --task altitude --seconds 240 --flightgear 127.0.0.1:5550

Flies ``--envs`` aircraft at the protocols' 10 ms control step with the controller of ``eval`` (a
baseline of the task, ppo or a policy file), records every aircraft (state, engine diagnostics,
actions, rewards, task references) and writes what is asked: the recording, the time-domain panels,
a 3D animation, a Tacview file, a live FlightGear stream. An aircraft that terminates stays where it
ended (a crash stops on the ground) until the others finish.

Length: ``--seconds`` lengthens (or cuts) the task's episode to the time asked. A maneuver of the
attitude task is flown once, so its command stream's end ends the flight; that, or every aircraft's
episode ending early (a crash), is said in one line on stderr, and the output states the seconds
actually flown (``seconds``) next to the seconds asked (``seconds_requested``) and why they differ
(``stopped``). The recording is held in memory until the flight ends and a GIF until it is written, so
a flight is refused in one line, before anything flies, above :data:`MAX_FLY_SECONDS`, above
:data:`MAX_RECORDED_FRAMES` aircraft frames or, with ``--gif``, above :data:`MAX_GIF_SECONDS` (``--mp4``
streams its frames to disk).
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

from ..defaults import DEFAULT_AIRFRAME
from ._common import (
    UsageError,
    add_flight_arguments,
    check_controller,
    check_device,
    emit,
    positive_int,
    use_threads,
)
from ._views import add_view_arguments, check_view_arguments, write_views

NAME = "fly"
HELP = "fly a controller and write its recording, plots, 3D animation, Tacview file or FlightGear stream"

#: Longest flight ``fly`` records, s. The recording is held in memory until the flight ends: about 15 kB
#: a 10 ms control step plus 0.65 kB an aircraft (measured: 240 s of one aircraft took 0.37 GB, of 16
#: aircraft 0.60 GB), so 600 s of one aircraft is about 0.9 GB.
MAX_FLY_SECONDS = 600.0
#: Most aircraft frames (aircraft x 10 ms control steps) one flight records: about 1.3 GB at 0.65 kB each.
MAX_RECORDED_FRAMES = 2_000_000
#: Longest flight a --gif shows, s: a GIF holds every frame in memory until it is written (at real time
#: 20 frames a second of flight, about 0.5 MB each at 480x360: 90 s is about 0.9 GB). Use --mp4 above.
MAX_GIF_SECONDS = 90.0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from ..envs.maneuvers import MANEUVERS
    from ..envs.tasks import task_names
    from .eval import controllers_help

    parser.add_argument("--controller", required=True, help=controllers_help())
    parser.add_argument("--task", choices=task_names(), default="altitude")
    parser.add_argument("--airframe", default=DEFAULT_AIRFRAME, help="shipped name or path to a JSON file")
    parser.add_argument("--maneuver", choices=MANEUVERS, default=None,
                        help="command stream of the attitude task (default: its random training stream)")
    parser.add_argument("--envs", type=positive_int, default=1, help="aircraft flown (and recorded)")
    add_flight_arguments(parser, "seconds flown (default: the task's episode, which --seconds lengthens; a "
                         "maneuver is flown once: its stream's end ends the flight, said on stderr). At "
                         f"most {MAX_FLY_SECONDS:g} s and {MAX_RECORDED_FRAMES:,} aircraft x 10 ms steps "
                         f"(held in memory); with --gif at most {MAX_GIF_SECONDS:g} s (--mp4 has no such "
                         "limit)",
                         "runs/fly", "unused by fly (outputs go where their options say)")
    add_view_arguments(parser)


def run(args: argparse.Namespace) -> int:
    import math

    from ..airframe import load_airframe
    from ..envs.tasks import task_spec

    check_device(args.device)
    use_threads(args)
    airframe = load_airframe(args.airframe)
    label = check_controller(args.controller, args.task, args.airframe)
    options: dict = {}
    if args.maneuver is not None:
        if "maneuver" not in {f.name for f in _fields(task_spec(args.task).default_config())}:
            raise UsageError(f"--maneuver does not apply to task {args.task!r} (it flies the attitude task)")
        options["maneuver"] = args.maneuver
    check_view_arguments(args)
    recording, summary = fly(args, airframe.name, options)
    if summary["stopped"]:
        print(f"fly: {summary['stopped']}", file=sys.stderr)
    written = write_views(args, recording)
    doc = {"task": args.task, "airframe": airframe.name, "controller": label, "maneuver": args.maneuver,
           "envs": args.envs, **summary, "outputs": written}
    lines = [f"{label} flew {args.task} on {airframe.name} for {doc['seconds']:.2f} s ({args.envs} aircraft)",
             f"terminated: {summary['terminated']}  mean reward: {summary['mean_reward']:.4g}  "
             f"final height: {', '.join(f'{h:.2f}' for h in summary['final_height_m'])} m"]
    lines += [f"{name}: {value}" for name, value in written.items()]
    emit(args, {k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in doc.items()},
         "\n".join(lines))
    return 0


def _fields(config: object) -> tuple:
    from dataclasses import fields

    return fields(config)


def planned_steps(args: argparse.Namespace, env: Any) -> tuple[int, str | None]:
    """(control steps to fly, why they fall short of ``--seconds`` or None): the seconds asked, up to the
    episode's horizon (which ``--seconds`` set, except a maneuver's, the length of its stream)."""
    if args.seconds is None:
        return env.max_episode_steps, None
    asked = max(1, round(args.seconds / env.control_dt))
    if asked <= env.max_episode_steps:
        return asked, None
    horizon = env.max_episode_steps * env.control_dt
    end = f"its episode ends at {horizon:.2f} s"
    if args.maneuver:
        end = (f"the {args.maneuver} maneuver's command stream ends at {horizon:.2f} s (a maneuver is flown "
               "once; omit --maneuver for a longer flight)")
    return env.max_episode_steps, f"flew {horizon:.2f} s of the {args.seconds:g} s asked: {end}"


def check_flight_size(args: argparse.Namespace, steps: int, control_dt: float) -> None:
    """UsageError, before anything flies, when the flight of ``steps`` control steps would last more than
    :data:`MAX_FLY_SECONDS`, record more than :data:`MAX_RECORDED_FRAMES` aircraft frames or, with --gif,
    show more than :data:`MAX_GIF_SECONDS`."""
    seconds, frames = steps * control_dt, args.envs * (steps + 1)
    if seconds > MAX_FLY_SECONDS + 0.5 * control_dt:
        raise UsageError(f"--seconds {seconds:g}: fly records at most {MAX_FLY_SECONDS:g} s (the recording "
                         "is held in memory until the flight ends)")
    if frames > MAX_RECORDED_FRAMES:
        raise UsageError(f"--seconds {seconds:g} with --envs {args.envs} would record {frames:,} "
                         f"aircraft frames (10 ms each), over the {MAX_RECORDED_FRAMES:,} held in memory: "
                         "fly fewer seconds or fewer aircraft")
    if getattr(args, "gif", None) and seconds > MAX_GIF_SECONDS:
        raise UsageError(f"--gif of a {seconds:g} s flight: a GIF is held in memory until written, at most "
                         f"{MAX_GIF_SECONDS:g} s; use --mp4 (written as it renders) or --seconds "
                         f"<= {MAX_GIF_SECONDS:g}")


def fly(args: argparse.Namespace, airframe: str, options: dict, progress: bool = True) -> tuple:
    """Fly and record for ``args.seconds`` (the episode lengthened to them; None: the task's episode)
    or until every episode ends (a maneuver's stream ends its episode); ``progress``: a step bar on
    stderr. Returns (recording, summary {seconds flown, seconds_requested, stopped (why fewer seconds
    were flown than asked, or None), terminated (crashes, stalls: not the end of the episode),
    termination reasons, mean reward, final heights})."""
    import torch
    from torchrl.envs import TransformedEnv
    from tqdm import tqdm

    from ..envs import make_env
    from ..evaluation.controllers import make_controller
    from ..evaluation.protocols import PROTOCOL_DECIMATION
    from ..transforms.flight_recorder import FlightRecorder

    length = {} if args.seconds is None else {"episode_seconds": args.seconds}
    env = make_env(args.task, airframe, num_envs=args.envs, backend=args.backend, device=args.device,
                   seed=args.seed, decimation=PROTOCOL_DECIMATION, **options, **length)
    steps, stopped = planned_steps(args, env)
    check_flight_size(args, steps, env.control_dt)
    policy = make_controller(args.controller, env)
    recorder = FlightRecorder(range(args.envs), meta={"controller": args.controller,
                                                       "maneuver": args.maneuver})
    recorded = TransformedEnv(env, recorder)
    done = torch.zeros(args.envs, dtype=torch.bool, device=env.device)
    terminated = torch.zeros_like(done)
    flown = 0
    td = recorded.reset()
    with torch.no_grad():
        for _ in tqdm(range(steps), desc=f"fly {args.controller}", unit="step", leave=False, mininterval=1.0,
                      disable=not progress):
            flown += 1
            td = recorded.step(policy(td))
            done |= td["next", "done"].reshape(-1)
            terminated |= td["next", "terminated"].reshape(-1)
            td = recorded.step_mdp(td)
            if bool(done.all()):
                break
    return _summary(recorder.recording(), terminated, args.seconds,
                    stopped if flown == steps else _ended_early(args.seconds, flown * env.control_dt))


def _ended_early(asked: float | None, seconds: float) -> str:
    """Why a flight stopped after ``seconds`` when every aircraft's episode had ended."""
    asked_text = "" if asked is None else f" of the {asked:g} s asked"
    return f"flew {seconds:.2f} s{asked_text}: every aircraft's episode had ended (see termination_reasons)"


def _summary(recording: Any, terminated: Any, asked: float | None, stopped: str | None) -> tuple:
    """(recording, summary of :func:`fly`): the seconds flown are the recording's."""
    import numpy as np

    reasons = recording["termination_reason"][-1] if recording.has("termination_reason") else None
    names = recording.meta.get("termination_reasons", [])
    summary = {
        "seconds": float(recording.time[-1]) if recording.num_frames else 0.0,
        "seconds_requested": asked,
        "stopped": stopped,
        "terminated": int(terminated.sum()),
        "termination_reasons": [] if reasons is None else [names[r] if 0 <= r < len(names) else str(r)
                                                           for r in reasons.tolist()],
        "mean_reward": float(np.nanmean(recording["reward"])) if recording.has("reward") else float("nan"),
        "final_height_m": [float(h) for h in recording["height"][-1]],
    }
    return recording, summary
