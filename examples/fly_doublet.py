"""Load an airframe, trim it, fly an elevator doublet on the Simulator and plot the response.

    .venv/bin/python examples/fly_doublet.py [--airframe volantex_ranger] [--out runs/doublet.png]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import torch

from falcon_rl import Simulator, load_airframe, trim_level
from falcon_rl.defaults import DEFAULT_AIRFRAME


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--airframe", default=DEFAULT_AIRFRAME)
    parser.add_argument("--out", default="runs/doublet.png")
    args = parser.parse_args()

    airframe = load_airframe(args.airframe)
    trim = trim_level(airframe, airframe.envelope.cruise_speed, height=50.0)
    print({k: round(v, 4) for k, v in trim.row(0).items()})

    sim = Simulator(airframe, num_envs=1, dtype=torch.float64)
    sim.reset(trim.state)  # the trimmed state vector [1, S]
    u_trim = trim.commands  # [1, 4]: elevator, aileron, rudder, throttle in [-1, 1]

    log: dict[str, list[float]] = {k: [] for k in ("t", "elevator", "alpha", "q", "theta", "h", "V")}
    for k in range(1000):  # 10 s at dt = 0.01 s
        t = k * sim.dt
        command = u_trim.clone()
        command[0, 0] += 0.1 if 1.0 <= t < 2.0 else (-0.1 if 2.0 <= t < 3.0 else 0.0)
        sim.step(command)
        s = sim.state
        log["t"].append(t + sim.dt)
        log["elevator"].append(float(torch.rad2deg(s["surface_position"][0, 0])))
        log["alpha"].append(float(torch.rad2deg(s["alpha"][0])))
        log["q"].append(float(torch.rad2deg(s["angular_rate_body"][0, 1])))
        log["theta"].append(float(torch.rad2deg(s["euler"][0, 1])))
        log["h"].append(float(s["height"][0]))
        log["V"].append(float(s["airspeed"][0]))

    panels = [("elevator", "elevator (deg)"), ("alpha", "alpha (deg)"), ("q", "pitch rate (deg/s)"),
              ("theta", "pitch (deg)"), ("h", "height (m)"), ("V", "airspeed (m/s)")]
    fig, axes = plt.subplots(3, 2, figsize=(9, 7), sharex=True)
    for ax, (key, label) in zip(axes.flat, panels, strict=True):
        ax.plot(log["t"], log[key])
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("time (s)")
    fig.suptitle(f"{airframe.display_name}: elevator doublet from trim at "
                 f"{airframe.envelope.cruise_speed} m/s")
    fig.tight_layout()
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=120)
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
