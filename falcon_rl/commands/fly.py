"""``falcon-rl fly``: fly a controller on a task and look at the flight.

    falcon-rl fly --controller lqr --task attitude --airframe volantex_ranger --maneuver circle \\
        --seconds 30 --acmi a.acmi --gif a.gif --plots p/
    falcon-rl fly --controller ppo --task altitude --envs 4 --record flight.npz --mp4 flight.mp4
    falcon-rl fly --controller lqr --task altitude --flightgear 127.0.0.1:5550

Flies ``--envs`` aircraft at the protocols' 10 ms control step with the controller of ``eval`` (a
baseline of the task, ppo or a policy file), records every aircraft (state, engine diagnostics,
actions, rewards, task references) and writes what is asked: the recording, the time-domain panels,
a 3D animation, a Tacview file, a live FlightGear stream. An aircraft that terminates stays where it
ended (a crash stops on the ground) until the others finish.
"""

from __future__ import annotations

import argparse

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


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from ..envs.maneuvers import MANEUVERS
    from ..envs.tasks import task_names
    from .eval import controllers_help

    parser.add_argument("--controller", required=True, help=controllers_help())
    parser.add_argument("--task", choices=task_names(), default="altitude")
    parser.add_argument("--airframe", default="volantex_ranger", help="shipped name or path to a JSON file")
    parser.add_argument("--maneuver", choices=MANEUVERS, default=None,
                        help="command stream of the attitude task (default: its random training stream)")
    parser.add_argument("--envs", type=positive_int, default=1, help="aircraft flown (and recorded)")
    add_flight_arguments(parser, "seconds flown (default: the task's episode; a maneuver's stream)",
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
    written = write_views(args, recording)
    doc = {"task": args.task, "airframe": airframe.name, "controller": label, "maneuver": args.maneuver,
           "envs": args.envs, "seconds": recording.num_frames and float(recording.time[-1]),
           **summary, "outputs": written}
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


def fly(args: argparse.Namespace, airframe: str, options: dict) -> tuple:
    """Fly and record until the seconds or every episode end (a maneuver's stream ends its episode):
    (recording, summary {terminated (crashes, stalls: not the end of the episode), termination reasons,
    mean reward, final heights})."""
    import numpy as np
    import torch
    from torchrl.envs import TransformedEnv
    from tqdm import tqdm

    from ..envs import make_env
    from ..evaluation.controllers import make_controller
    from ..evaluation.protocols import PROTOCOL_DECIMATION
    from ..transforms.record import FlightRecorder

    env = make_env(args.task, airframe, num_envs=args.envs, backend=args.backend, device=args.device,
                   seed=args.seed, decimation=PROTOCOL_DECIMATION, **options)
    policy = make_controller(args.controller, env)
    recorder = FlightRecorder(range(args.envs), meta={"controller": args.controller,
                                                       "maneuver": args.maneuver})
    recorded = TransformedEnv(env, recorder)
    steps = env.max_episode_steps if args.seconds is None else max(1, round(args.seconds / env.control_dt))
    done = torch.zeros(args.envs, dtype=torch.bool, device=env.device)
    terminated = torch.zeros_like(done)
    td = recorded.reset()
    with torch.no_grad():
        for _ in tqdm(range(steps), desc=f"fly {args.controller}", unit="step", leave=False, mininterval=1.0):
            td = recorded.step(policy(td))
            done |= td["next", "done"].reshape(-1)
            terminated |= td["next", "terminated"].reshape(-1)
            td = recorded.step_mdp(td)
            if bool(done.all()):
                break
    recording = recorder.recording()
    reasons = recording["termination_reason"][-1] if recording.has("termination_reason") else None
    names = recording.meta.get("termination_reasons", [])
    summary = {
        "terminated": int(terminated.sum()),
        "termination_reasons": [] if reasons is None else [names[r] if 0 <= r < len(names) else str(r)
                                                           for r in reasons.tolist()],
        "mean_reward": float(np.nanmean(recording["reward"])) if recording.has("reward") else float("nan"),
        "final_height_m": [float(h) for h in recording["height"][-1]],
    }
    return recording, summary
