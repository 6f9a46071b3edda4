"""Faults found by trying ``falcon-rl demo``, ``eval`` and ``fly``, one test (parametrized over its cases)
per row:

1. ``falcon-rl demo | cat`` printed nothing for minutes: every stage is a line on stderr (with the
   seconds since the start) when stderr is not a terminal, a bar on a terminal, and always a line in
   ``demo.log`` in the output folder (a failed stage too).
2. ``falcon-rl eval`` overwrote ``runs/eval/report.md`` of the run before: each run gets its own folder
   without ``--out``; a ``--out`` that holds a report is refused in one line unless ``--force``; where
   the report went is said on stderr and in the JSON.
3. ``falcon-rl fly --seconds 240`` stopped at the task's 30 s episode without a word: the episode is
   lengthened to the seconds asked; a maneuver's shorter stream is said in one line and in the output;
   flights whose recording or GIF would not fit in memory are refused in one line before they fly.

The demo's heavy stages are faked (the test checks the progress around them); the eval and fly runs are
a fraction of a second of flight.
"""

from __future__ import annotations

import io
import json
import re
from datetime import datetime, timezone
from pathlib import Path

import pytest
import torch

import falcon_rl.envs
import falcon_rl.envs.tasks.attitude.task
import falcon_rl.evaluation.controllers
import falcon_rl.evaluation.report
from falcon_rl.cli import main
from falcon_rl.commands import demo
from falcon_rl.commands import eval as eval_command
from falcon_rl.commands import fly as fly_command

#: What stderr holds besides the messages: Warp's start-up notice, fly's step bar (and its blank ends).
NOISE = re.compile(r"Warp|^fly \w+:|^\s*$")


def cli(argv: list[str], capsys) -> tuple[int, str, list[str]]:
    """Exit code, stdout and stderr lines (without :data:`NOISE`) of ``falcon-rl argv`` in-process."""
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, [line for line in err.splitlines() if not NOISE.search(line)]


# ------------------------------------------------------------------ row 1: the demo shows its progress
#: A stage line: ``demo [ELAPSED s] STAGE``.
STAGE_LINE = re.compile(r"^demo \[ *\d+\.\d s\] (.+)$")


class Terminal(io.StringIO):
    """A stream that says it is a terminal."""

    def isatty(self) -> bool:
        return True


def fake_heavy_stages(monkeypatch, seen_progress: list[bool], fail: bool) -> None:
    """The demo's scoring, trims and flight as instant fakes (the flight raises with ``fail``); each
    records whether it was asked for its own progress bars."""

    def score(args, name, source, episodes, airframe, out):
        return name.upper(), out / f"altitude_{name}.png"

    def trims(out, progress):
        seen_progress.append(progress)
        return ["## Trim"], {"trim": {}}

    def flight(args, airframe, out, log):
        seen_progress.append(log.interactive)
        log.stage("the LQR on the circle maneuver: 20 s flight")
        if fail:
            raise OSError(28, "No space left on device")
        return ["## Flight"], {"flight": {}}

    def write_report(results, out, figures, title):
        report = out / "report.md"
        report.write_text(f"# {title}\n\n## Altitude acquisition and hold\n\n{results}\n")
        return report

    monkeypatch.setattr(demo, "_score", score)
    monkeypatch.setattr(demo, "_trims_and_ground_effect", trims)
    monkeypatch.setattr(demo, "_seen_flight", flight)
    monkeypatch.setattr(falcon_rl.evaluation.report, "write_report", write_report)
    monkeypatch.setattr(falcon_rl.evaluation.report, "result_document", lambda result: {"controller": result})


DEMO_STAGES = ["altitude protocol: LQR, 3 episodes", "altitude protocol: MPPI, 1 episodes",
               "trim and ground-effect table of every shipped airframe",
               "the LQR on the circle maneuver: 20 s flight"]


@pytest.mark.parametrize(("terminal", "fail"), [(False, False), (True, False), (False, True)],
                         ids=["piped", "terminal", "piped-failing-stage"])
def test_demo_shows_every_stage_and_logs_it(monkeypatch, capsys, tmp_path, terminal, fail):
    seen_progress: list[bool] = []
    fake_heavy_stages(monkeypatch, seen_progress, fail)
    stream = Terminal() if terminal else io.StringIO()
    monkeypatch.setattr("sys.stderr", stream)
    out = tmp_path / "demo"
    code = main(["demo", "--out", str(out), "--controllers", "lqr,mppi", "--episodes", "3",
                 "--mppi-episodes", "1", "--json"])
    logged = (out / demo.LOG_NAME).read_text().splitlines()
    stages = [STAGE_LINE.match(line).group(1) for line in logged]
    last = "failed: [Errno 28] No space left on device" if fail else "done"
    assert stages == [*DEMO_STAGES, last]
    assert seen_progress == [terminal, terminal]  # the stages' own bars on a terminal only
    shown = stream.getvalue()
    if terminal:  # the bar names the stages; the lines are the log's
        assert "demo: trim and ground-effect table" in shown and "] done" not in shown
    else:
        assert [line for line in shown.splitlines() if STAGE_LINE.match(line)] == logged
    if fail:
        assert code == 1 and shown.strip().splitlines()[-1].endswith("No space left on device")
    else:
        assert code == 0 and json.loads(capsys.readouterr().out)["log"] == str(out / demo.LOG_NAME)


# ------------------------------------------------------------------ row 2: a folder per eval run
EVAL = ["eval", "--controller", "trim", "--task", "climb_descend", "--episodes", "1", "--seconds", "0.05",
        "--json"]


def eval_json(capsys, *extra) -> tuple[int, dict | None, list[str]]:
    code, out, err = cli([*EVAL, *extra], capsys)
    return code, json.loads(out) if code == 0 else None, err


def test_run_folders_are_new_and_named_after_the_run(tmp_path):
    now = datetime(2025, 1, 2, 3, 4, 5, tzinfo=timezone.utc)
    parts = ("altitude", "my policy/v2", "volantex_ranger")
    first, second = (eval_command.run_folder(tmp_path, parts, now) for _ in range(2))
    assert first.name == "altitude-my_policy_v2-volantex_ranger-20250102T030405Z"
    assert second.name == first.name + "-2" and first.is_dir() and second.is_dir()
    long = eval_command.run_folder(tmp_path, ("altitude", "p" * 300, "../x"), now)
    assert long.name == f"altitude-{'p' * eval_command.MAX_PART_CHARACTERS}-_x-20250102T030405Z"


@pytest.mark.parametrize("case", ["no-out-twice", "out-with-report", "out-with-report-force"])
def test_eval_keeps_the_report_of_an_earlier_run(case, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    if case == "no-out-twice":
        runs = [eval_json(capsys) for _ in range(2)]
        reports = [Path(doc["report"]) for _, doc, _ in runs]
        assert [code for code, _, _ in runs] == [0, 0] and reports[0] != reports[1]
        for (_, _, err), report in zip(runs, reports, strict=True):
            assert report.parent.parent == eval_command.RUNS_FOLDER and report.is_file()
            assert report.parent.name.startswith("climb_descend-trim-volantex_ranger-")
            assert err == [f"eval: report in {report}"]
        return
    out = tmp_path / "mine"
    out.mkdir()
    (out / "report.md").write_text("earlier run")
    force = ["--force"] if case.endswith("force") else []
    code, doc, err = eval_json(capsys, "--out", out, *force)
    if force:
        assert code == 0 and doc["report"] == str(out / "report.md")
        assert err == [f"eval: report in {out / 'report.md'}"]
        assert "## Climb and descend" in (out / "report.md").read_text()
    else:
        assert code == 2 and len(err) == 1 and "already holds the report.md of an earlier run" in err[0]
        assert "--force" in err[0] and (out / "report.md").read_text() == "earlier run"
        assert not Path("runs").exists()


# ------------------------------------------------------------------ row 3: fly flies the seconds asked
def short_task_episodes(monkeypatch) -> None:
    """Every task's own episode 0.5 s (a 1 s flight is then longer than the task's episode)."""
    make_env = falcon_rl.envs.make_env

    def short(task, airframe, **options):
        return make_env(task, airframe, **{"episode_seconds": 0.5, **options})

    monkeypatch.setattr(falcon_rl.envs, "make_env", short)


def falling_controller(monkeypatch) -> None:
    """Every controller commands -1 on every channel: the aircraft stalls and its episode ends at 1.25 s."""

    def falling(name, env, *args):
        return lambda td: td.set("action", torch.full(env.action_spec.shape, -1.0))

    monkeypatch.setattr(falcon_rl.evaluation.controllers, "make_controller", falling)


def short_maneuvers(monkeypatch) -> None:
    """Every maneuver's command stream cut to its first 0.5 s."""
    stream = falcon_rl.envs.tasks.attitude.task.maneuver_stream
    monkeypatch.setattr(falcon_rl.envs.tasks.attitude.task, "maneuver_stream",
                        lambda name, airframe, dt: stream(name, airframe, dt)[: round(0.5 / dt)])


FLY = ["fly", "--controller", "lqr", "--json"]
FLY_CASES = [
    # (id, patch, arguments, exit code, seconds flown, line on stderr)
    ("longer-than-the-task-episode", short_task_episodes, ["--seconds", "1"], 0, 1.0, None),
    ("every-episode-ends-first", falling_controller, ["--seconds", "2"], 0, 1.25,
     "flew 1.25 s of the 2 s asked: every aircraft's episode had ended"),
    ("longer-than-the-maneuver", short_maneuvers, ["--task", "attitude", "--maneuver", "circle", "--seconds",
                                                   "1"], 0, 0.5, "the circle maneuver's command stream ends"),
    ("over-the-longest-flight", None, ["--seconds", "601"], 2, None, "fly records at most 600 s"),
    ("over-the-recorded-frames", None, ["--envs", "40", "--seconds", "600"], 2, None,
     "would record 2,400,040 aircraft frames"),
    ("gif-over-its-longest", None, ["--seconds", "91", "--gif", "{tmp}/a.gif"], 2, None,
     "a GIF is held in memory until written, at most 90 s; use --mp4"),
]


@pytest.mark.parametrize(("patch", "extra", "code", "seconds", "message"), [c[1:] for c in FLY_CASES],
                         ids=[c[0] for c in FLY_CASES])
def test_fly_flies_the_seconds_asked_or_says_why(patch, extra, code, seconds, message, capsys, tmp_path,
                                                 monkeypatch):
    if patch is not None:
        patch(monkeypatch)
    got, out, err = cli([*FLY, *(a.format(tmp=tmp_path) for a in extra)], capsys)
    assert got == code, err
    assert err == ([] if message is None else [err[0]]) and (message is None or message in err[0]), err
    if code == 0:
        doc = json.loads(out)
        assert doc["seconds"] == pytest.approx(seconds) and doc["seconds_requested"] == float(extra[-1])
        assert (doc["stopped"] is None) == (message is None)
        assert message is None or message in doc["stopped"]
    else:
        assert not list(tmp_path.iterdir())  # refused before anything was written


def test_the_fly_limits_are_documented_in_its_help(capsys):
    """The limits the refusals quote are the ones --help states."""
    assert main(["fly", "--help"]) == 0
    shown = " ".join(capsys.readouterr().out.split())
    assert f"At most {fly_command.MAX_FLY_SECONDS:g} s" in shown
    assert f"with --gif at most {fly_command.MAX_GIF_SECONDS:g} s" in shown
