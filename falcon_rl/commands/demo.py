"""``falcon-rl demo``: the main job on embedded defaults.

1. Altitude acquisition and hold on the Volantex Ranger: the shipped PPO policy (or, with
   ``--train``, one trained from scratch here until it solves the protocol's validation episodes),
   the LQR and MPPI baselines, scored on the paper's protocol; the table in the paper's layout and
   one PNG per controller.
2. Trim of every shipped airframe at cruise and the ground-effect thrust table, with its figure.
3. The flight seen: the LQR flying the attitude task's circle maneuver, as a 3D animation (GIF), a
   Tacview file (ACMI) and the time-domain panels.

Everything goes to ``runs/demo`` (report.md, results.json, PNGs, GIF, ACMI, demo.log). On a 2-core CPU
the default run takes a few minutes; MPPI dominates, hence its small episode count.

Progress (:class:`StageLog`): one line per stage, ``demo [  12.3 s] altitude protocol: LQR, 100
episodes`` (seconds since the start), kept in ``demo.log`` in the output folder and printed on stderr
when stderr is not a terminal (a pipe, a log file); on a terminal a bar over the stages shows the
current one, above the stages' own step bars.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import TextIO

from ..atomic_files import write_atomic
from ..defaults import BATCH_BACKENDS, DEFAULT_AIRFRAME, DEFAULT_BACKEND
from ._common import (
    bounded_int,
    comma_list,
    emit,
    inside,
    nonnegative_int,
    one_line,
    output_dir,
    positive_int,
    use_threads,
)

NAME = "demo"
HELP = "run the main job: shipped PPO vs LQR vs MPPI on the altitude protocol, trims, ground effect"
CONTROLLERS = ("ppo", "lqr", "mppi", "trim")
#: The progress log the demo keeps in its output folder (one line per stage).
LOG_NAME = "demo.log"


class StageLog:
    """Progress of a job made of stages: one line per stage, ``NAME [ELAPSED s] STAGE``, kept in ``path``
    (rewritten whole at each stage, atomically) and printed on ``stream`` (default stderr) unless it is a
    terminal, where a tqdm bar over the ``total`` stages names the current one instead. Used as a
    context manager: a stage that raises is logged as failed (one line) before the error goes on."""

    def __init__(self, name: str, path: Path, total: int, stream: TextIO | None = None) -> None:
        from tqdm import tqdm

        self.name, self.path = name, path
        self.stream = sys.stderr if stream is None else stream
        #: Whether the stream is a terminal: bars there (the stages' own ones too), lines elsewhere.
        self.interactive = self.stream.isatty()
        self.lines: list[str] = []
        self.stages = 0
        self.started = time.monotonic()
        self.bar = tqdm(total=total, desc=name, unit="stage", file=self.stream, disable=not self.interactive,
                        bar_format="{desc} [{n}/{total} stages, {elapsed}]")

    def stage(self, text: str) -> None:
        """Start the stage described by ``text`` (the previous one is done)."""
        if self.stages:
            self.bar.update(1)
        self.stages += 1
        self.bar.set_description_str(f"{self.name}: {text}")
        self._line(text)

    def note(self, text: str) -> None:
        """A line that is no stage (a controller left out): logged, and printed on a terminal too."""
        line = self._line(text)
        if self.interactive:
            self.bar.write(line, file=self.stream)

    def _line(self, text: str) -> str:
        """Log ``NAME [ELAPSED s] text`` (printed unless on a terminal); returns the line."""
        line = f"{self.name} [{time.monotonic() - self.started:7.1f} s] {text}"
        self.lines.append(line)
        write_atomic(self.path, "\n".join(self.lines) + "\n")
        if not self.interactive:
            print(line, file=self.stream, flush=True)
        return line

    def __enter__(self) -> StageLog:
        return self

    def __exit__(self, kind: type[BaseException] | None, error: BaseException | None, trace: object) -> None:
        self.bar.update(self.bar.total - self.bar.n)
        self.bar.close()
        self._line("done" if error is None else f"failed: {one_line(error)}")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", default="runs/demo",
                        help=f"output folder (report.md, results.json, figures, GIF, ACMI and {LOG_NAME}, "
                             "the progress: a line per stage, also on stderr when it is not a terminal)")
    parser.add_argument("--airframe", default=DEFAULT_AIRFRAME, help="airframe of the altitude protocol")
    parser.add_argument("--controllers", default="ppo,lqr,mppi",
                        help=f"comma list of {', '.join(CONTROLLERS)} (default ppo,lqr,mppi)")
    parser.add_argument("--episodes", type=positive_int, default=100, help="protocol episodes per controller")
    parser.add_argument("--mppi-episodes", type=positive_int, default=5,
                        help="protocol episodes for MPPI (slow)")
    parser.add_argument("--train", action="store_true",
                        help="train PPO from scratch instead of using the shipped one, until it solves "
                             "the altitude protocol's validation (survival 1, acquisition >= 0.95, RMSE <= "
                             "0.5 m, confirmed on 100 more episodes; a few minutes on the Ranger on 2 CPU "
                             "cores)")
    parser.add_argument("--frames", type=positive_int, default=None,
                        help="with --train: the most env steps it may take (default: the recipe's)")
    parser.add_argument("--backend", choices=BATCH_BACKENDS, default=DEFAULT_BACKEND,
                        help="simulator (default warp)")
    parser.add_argument("--seed", type=nonnegative_int, default=0)
    parser.add_argument("--threads", type=bounded_int(1, 4096), default=1, help="torch CPU threads")


def training_config(args: argparse.Namespace, out: Path):
    """The PPO altitude recipe ``demo --train`` runs: the airframe's defaults, stopped at the first
    validation that solves the protocol (``ALTITUDE_SOLVED``) or at ``--frames``; no final evaluation
    (the demo scores the policy itself)."""
    from ..envs.tasks.altitude import ALTITUDE_SOLVED
    from ..recipes import ppo

    return ppo.make_config("altitude", airframe=args.airframe, frames=args.frames, seed=args.seed,
                           backend=args.backend, out=str(out / "ppo_train"), final_eval_episodes=0,
                           threads=args.threads, stop_when=ALTITUDE_SOLVED)


def _scored_controllers(args: argparse.Namespace, requested: list[str]) -> tuple[list[str], str | None]:
    """(the controllers the demo scores, why PPO is left out or None): without ``--train``, PPO only where
    a policy is shipped for the airframe."""
    if "ppo" not in requested or args.train:
        return requested, None
    from ..policies import shipped_policy

    try:
        shipped_policy("altitude", args.airframe)
    except ValueError as exc:  # no shipped policy for this airframe: score the baselines only
        return [c for c in requested if c != "ppo"], f"skipping PPO ({one_line(exc)}); --train trains one"
    return requested, None


def _protocol(args: argparse.Namespace, controllers: list[str], airframe: str, out: Path, log: StageLog
              ) -> tuple[list, list[Path], dict]:
    """Score the controllers on the altitude protocol, a stage each (training PPO first with ``--train``);
    returns (results, figures, training summary)."""
    training: dict = {}
    ppo_source = "ppo"
    if args.train and "ppo" in controllers:
        from ..recipes import ppo

        log.stage(f"training PPO on {airframe} until it solves the altitude protocol's validation")
        training = ppo.train(training_config(args, out))
        ppo_source = training["policy"]
    results, figures = [], []
    for name in controllers:
        episodes = args.mppi_episodes if name == "mppi" else args.episodes
        log.stage(f"altitude protocol: {name.upper()}, {episodes} episodes")
        result, figure = _score(args, name, ppo_source if name == "ppo" else name, episodes, airframe, out)
        results.append(result)
        figures.append(figure)
    return results, figures, training


def _score(args: argparse.Namespace, name: str, source: str, episodes: int, airframe: str, out: Path
           ) -> tuple:
    """One controller (``source``: a baseline name or a policy file) on the altitude protocol and its
    figure: (ProtocolResult, PNG path)."""
    from ..evaluation.controllers import make_controller
    from ..evaluation.protocols import altitude_protocol
    from ..viz.evaluation import plot_altitude

    result = altitude_protocol(args.airframe, name.upper(), lambda env: make_controller(source, env),
                               episodes=episodes, seed=args.seed, backend=args.backend)
    return result, plot_altitude(result, inside(out, f"altitude_{airframe}_{name}.png", "figure name"))


def _trims_and_ground_effect(out: Path, progress: bool) -> tuple[list[str], dict]:
    """Trim at cruise and the ground-effect table of every shipped airframe (``progress``: a bar over
    them): (report lines, document)."""
    from tqdm import tqdm

    from ..airframe import list_airframes, load_airframe
    from ..evaluation.ground_effect_trim import format_table, ground_effect_table, rows_as_dicts
    from ..physics.trim import trim_level
    from ..viz.ground_effect import plot_ground_effect

    trims, tables = {}, {}
    for name in tqdm(list_airframes(), desc="trim + ground-effect table", unit="airframe", leave=False,
                     disable=not progress):
        airframe = load_airframe(name)
        trims[name] = trim_level(airframe, airframe.envelope.cruise_speed, 100.0).row(0)
        tables[name] = ground_effect_table(airframe)
    png = plot_ground_effect(tables, out / "ground_effect.png")
    lines = ["## Trim at cruise, 100 m", "",
             "| airframe | V (m/s) | alpha (deg) | elevator (deg) | throttle | thrust (N) | C_L | C_D |",
             "|---|---:|---:|---:|---:|---:|---:|---:|"]
    for name, r in trims.items():
        lines.append(f"| {name} | {r['airspeed_mps']:.2f} | {r['alpha_deg']:.2f} | "
                     f"{r['elevator_deg']:.2f} | {r['throttle']:.3f} | {r['thrust_n']:.4g} | "
                     f"{r['lift_coefficient']:.3f} | {r['drag_coefficient']:.4f} |")
    lines += ["", "## Ground effect on trim thrust", ""]
    lines += [format_table(name, rows) + "\n" for name, rows in tables.items()]
    lines += [f"![ground effect]({png.name})", ""]
    doc = {"trim": trims, "ge_table": {k: rows_as_dicts(v) for k, v in tables.items()}, "plot": str(png)}
    return lines, doc


#: The demo's flight: the attitude task's circle maneuver flown by the LQR, s.
FLIGHT_SECONDS = 20.0


def _seen_flight(args: argparse.Namespace, airframe: str, out: Path, log: StageLog) -> tuple[list[str], dict]:
    """Fly the circle with the LQR, then write circle.gif, circle.acmi and the panels (a stage each):
    (report lines, document)."""
    from ..viz.acmi import write_acmi
    from ..viz.animation import write_animation
    from ..viz.timeseries import plot_all
    from .fly import fly

    flight = argparse.Namespace(task="attitude", controller="lqr", maneuver="circle", envs=1,
                                seconds=FLIGHT_SECONDS, seed=args.seed, backend=args.backend, device="cpu")
    log.stage(f"the LQR on the circle maneuver: {FLIGHT_SECONDS:g} s flight")
    recording, summary = fly(flight, airframe, {"maneuver": "circle"}, progress=log.interactive)
    log.stage("the circle seen: GIF, Tacview file, panels")
    gif = write_animation(recording, out / "circle.gif", fps=10.0, width=360, height=270,
                          progress=None if log.interactive else False)
    acmi = write_acmi(recording, out / "circle.acmi")
    panels = plot_all(recording, out / "circle_panels")
    lines = ["## The flight seen: LQR on the circle maneuver", "",
             f"{FLIGHT_SECONDS:.0f} s of the attitude task's circle on {airframe} (final bank "
             f"{float(recording['euler'][-1, 0, 0]) * 57.29578:.1f} deg). Tacview file: [{acmi.name}]"
             f"({acmi.name}); replay anything with `falcon-rl replay`.", "", f"![circle]({gif.name})", ""]
    lines += [f"![{p.stem}]({p.parent.name}/{p.name})" for p in panels if p.stem in ("states", "forces")]
    return [*lines, ""], {"flight": {**summary, "gif": str(gif), "acmi": str(acmi),
                                     "panels": [str(p) for p in panels]}}


def run(args: argparse.Namespace) -> int:
    from ..airframe import load_airframe
    from ..evaluation.report import result_document

    requested = comma_list(args.controllers, "--controllers", CONTROLLERS)
    airframe = load_airframe(args.airframe).name
    out = output_dir(args.out)
    use_threads(args)
    controllers, skipped = _scored_controllers(args, requested)
    stages = len(controllers) + 3 + int(args.train and "ppo" in controllers)
    with StageLog(NAME, out / LOG_NAME, stages) as log:
        if skipped:
            log.note(skipped)
        results, figures, training = _protocol(args, controllers, airframe, out, log)
        log.stage("trim and ground-effect table of every shipped airframe")
        trim_lines, trim_doc = _trims_and_ground_effect(out, log.interactive)
        flight_lines, flight_doc = _seen_flight(args, airframe, out, log)
        report, text = _write_report(args, requested, results, figures, training, airframe, out,
                                     [*trim_lines, *flight_lines])
    doc = {"altitude": [result_document(r) for r in results], **trim_doc, **flight_doc, "report": str(report),
           "log": str(out / LOG_NAME), "figures": [str(f) for f in figures], "training": training}
    emit(args, doc, text + f"\nreport: {report}")
    return 0


def _write_report(args: argparse.Namespace, requested: list[str], results: list, figures: list[Path],
                  training: dict, airframe: str, out: Path, sections: list[str]) -> tuple[Path, str]:
    """report.md (and results.json) of the demo: the protocol's table with where PPO came from, then
    ``sections``; returns (its path, its text)."""
    from ..evaluation.report import write_report

    source = "trained here from scratch" if args.train else "shipped (falcon_rl/policies)"
    if args.train and training:
        source += (f", {training['frames']:,} frames in {training['wall_seconds']:.0f} s, " +
                   ("not solved" if training.get("solved") is None else "stopped when solved"))
    if "ppo" not in requested:
        source = "not requested"
    elif not any(r.controller == "PPO" for r in results):
        source = "not scored: no shipped policy for this airframe"
    report = write_report(results, out, figures, "falcon-rl demo")
    head, _, tail = report.read_text().partition("## Altitude acquisition and hold")
    text = (head + f"## Altitude acquisition and hold ({airframe}; PPO {source})" + tail
            + "\n" + "\n".join(sections))
    write_atomic(report, text)
    return report, text
