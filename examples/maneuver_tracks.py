"""The paper's maneuver figure: the attitude task's four maneuvers flown by a controller on the two
reference airframes, rendered as 3D tracks coloured by bank (rows airframes, columns maneuvers).

    python examples/maneuver_tracks.py --controller lqr --out runs/tracks

Writes ``tracks.png`` and one recording per flight (``<airframe>_<maneuver>.npz``, for
``falcon-rl replay``). The controller is any of ``falcon-rl fly``'s (lqr, mppi, ppo or a policy file).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from falcon_rl.cli import main as falcon_rl
from falcon_rl.envs.maneuvers import MANEUVERS
from falcon_rl.recording import Recording
from falcon_rl.viz.track import plot_tracks

AIRFRAMES = ("volantex_ranger", "airship_v7")


def fly_all(controller: str, out: Path, seed: int, seconds: float | None = None
            ) -> dict[tuple[str, str], Recording]:
    """Fly every (airframe, maneuver) pair through ``falcon-rl fly`` (each whole stream, or its first
    ``seconds``); returns the recordings."""
    recordings = {}
    for airframe in AIRFRAMES:
        for maneuver in MANEUVERS:
            path = out / f"{airframe}_{maneuver}.npz"
            code = falcon_rl(["fly", "--controller", controller, "--task", "attitude", "--airframe", airframe,
                              "--maneuver", maneuver, "--seed", str(seed), "--record", str(path),
                              *([] if seconds is None else ["--seconds", str(seconds)])])
            if code != 0:
                raise SystemExit(code)
            recordings[(airframe, maneuver)] = Recording.load(path)
    return recordings


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--controller", default="lqr")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--seconds", type=float, default=None, help="cut each maneuver (default: whole)")
    parser.add_argument("--out", type=Path, default=Path("runs/tracks"))
    args = parser.parse_args()
    print(plot_tracks(fly_all(args.controller, args.out, args.seed, args.seconds), args.out / "tracks.png"))
