"""Every bad input of the CLI ends the same way: exit code 2, nothing on stdout and exactly one printable
line on stderr that names the flag or file, the field and the constraint; never a traceback.

One table row per case, run in-process through ``falcon_rl.cli.main`` (validation fails before any env is
built, so the table stays fast); the malformed airframe files of tests/test_airframe_validation.py go
through the CLI as well. A closed stdout pipe needs a real process.
"""
# ruff: noqa: E501 (tables of test cases read best one case a line)

from __future__ import annotations

import copy
import json
import pickle
import shlex
import subprocess
import sys
import unicodedata
from pathlib import Path

import pytest
from test_airframe_validation import CASES, RAW_CASES, SOURCE

from falcon_rl.cli import main

ROOT = Path(__file__).resolve().parents[1]
POLICIES = ROOT / "falcon_rl" / "policies"
BIG = "9" * 400  # a 400-digit integer
UNWRITABLE = "/proc/falcon-rl-test/out"  # /proc takes no new folders, not even from root


def row(case_id: str, argv: str | list[str], needle: str):
    """One case: ``argv`` (a shell-like string, or a list for arguments a shell string cannot spell), with
    ``{name}`` placeholders for the files of the ``paths`` fixture, and a substring of the error line."""
    return pytest.param(shlex.split(argv) if isinstance(argv, str) else argv, needle, id=case_id)


CLI_CASES = [
    # the top level
    row("no command", "", "the following arguments are required: COMMAND"),
    row("unknown command", "hover", "invalid choice: 'hover'"),
    row("unknown top-level flag", "--bogus airframes", "unrecognized arguments: --bogus"),
    row("unknown subcommand flag", "airframes --bogus", "unrecognized arguments: --bogus"),
    # trim
    row("trim no airframe", "trim", "the following arguments are required: --airframe"),
    row("trim unknown airframe", "trim --airframe concorde", "unknown airframe 'concorde'"),
    row("trim escape codes in name", ["trim", "--airframe", "\x1b[31mred"], r"unknown airframe '\x1b[31mred'"),
    row("trim undecodable argv", ["trim", "--airframe", "\udcff"], r"unknown airframe '\udcff'"),
    row("trim NUL in path", ["trim", "--airframe", "a\0.json"], "holds a NUL character"),
    row("trim flag without value", "trim --airframe", "argument --airframe: expected one argument"),
    row("trim missing file", "trim --airframe {tmp}/missing.json", "missing.json: airframe file not found"),
    row("trim directory", "trim --airframe {dir_json}", "dir.json: a directory, not an airframe file"),
    row("trim airspeed text", "trim --airframe navion --airspeed fast", "--airspeed: 'fast' is not a number"),
    row("trim airspeed zero", "trim --airframe navion --airspeed 0", "--airspeed: '0' must be in (0, 340] m/s"),
    row("trim airspeed negative", "trim --airframe navion --airspeed -3", "'-3' must be in (0, 340] m/s"),
    row("trim airspeed inf", "trim --airframe navion --airspeed inf", "--airspeed: 'inf' is not a finite number"),
    row("trim airspeed nan", "trim --airframe navion --airspeed nan", "'nan' is not a finite number"),
    row("trim airspeed overflow", "trim --airframe navion --airspeed 1e400", "'1e400' is not a finite number"),
    row("trim airspeed supersonic", "trim --airframe navion --airspeed 1e6", "must be in (0, 340] m/s"),
    row("trim height zero", "trim --airframe navion --height 0", "--height: '0' must be in (0, 20000] m"),
    row("trim height huge", "trim --airframe navion --height 1e7", "--height: '1e7' must be in (0, 20000] m"),
    row("trim height 400 digits", f"trim --airframe navion --height {BIG}", "is not a finite number"),
    row("trim ground-effect model", "trim --airframe navion --ground-effect wall", "invalid choice: 'wall'"),
    row("trim below stall", "trim --airframe navion --airspeed 15",
        "below the stall speed 25.26 m/s (the wing stalls at alpha 20.0 deg)"),
    row("trim saturated elevator", "trim --airframe navion --airspeed 0.001",
        "the elevator saturates (needs 20.1 deg, its limits are [-20.0, 20.0] deg)"),
    row("trim above max speed", "trim --airframe navion --airspeed 100",
        "needs throttle 1.100, outside [0, 1]; 100.00 m/s is above the maximum speed"),
    # ge-table
    row("ge-table no airframe", "ge-table", "the following arguments are required: --airframe"),
    row("ge-table airspeed zero", "ge-table --airframe navion --airspeed 0", "'0' must be in (0, 340] m/s"),
    row("ge-table airspeed nan", "ge-table --airframe navion --airspeed nan", "'nan' is not a finite number"),
    row("ge-table unknown airframe", "ge-table --airframe concorde --out {out}", "unknown airframe 'concorde'"),
    row("ge-table out unwritable", f"ge-table --airframe navion --out {UNWRITABLE}",
        f"--out '{UNWRITABLE}' is not a writable directory (No such file or directory)"),
    row("ge-table out is a file", "ge-table --airframe navion --out {file}", "is not a writable directory"),
    row("ge-table airframe is a folder", "ge-table --airframe {dir_json}", "dir.json: a directory"),
    row("ge-table model", "ge-table --airframe navion --ground-effect wall", "invalid choice: 'wall'"),
    # eval
    row("eval no controller", "eval", "the following arguments are required: --controller"),
    row("eval unknown task", "eval --controller trim --task hover", "invalid choice: 'hover'"),
    row("eval controller not of task", "eval --controller lqr --task path_following --out {out}",
        "controller 'lqr' does not apply to task 'path_following'"),
    row("eval mppi not of task", "eval --controller mppi --task trajectory --out {out}",
        "does not apply to task 'trajectory'"),
    row("eval missing policy", "eval --controller no_such_policy.pt --out {out}",
        "--controller 'no_such_policy.pt' is neither a controller of the task nor a policy file"),
    row("eval NUL in policy path", ["eval", "--controller", "a\0.pt"], "nor a policy file"),
    row("eval text renamed .pt", "eval --controller {text_pt} --out {out}",
        "notes.pt: truncated, corrupt or not a torch file"),
    row("eval empty policy", "eval --controller {empty_pt} --out {out}", "empty.pt: empty file (0 bytes)"),
    row("eval plain pickle", "eval --controller {pickle_pt} --out {out}", "plain.pt: a plain Python pickle"),
    row("eval policy is a folder", "eval --controller {dir} --out {out}", "folder: is a folder"),
    row("eval policy of another task", "eval --controller {attitude_pt} --task altitude --out {out}",
        "a policy of task 'attitude' does not fly task 'altitude'"),
    row("eval no shipped ppo", "eval --controller ppo --task attitude --airframe navion --out {out}",
        "--controller ppo: no shipped ppo policy for task 'attitude' on 'navion'"),
    row("eval episodes zero", "eval --controller trim --episodes 0", "--episodes: '0' must be >= 1"),
    row("eval episodes negative", "eval --controller trim --episodes -1", "'-1' must be >= 1"),
    row("eval episodes text", "eval --controller trim --episodes many", "'many' is not an integer"),
    row("eval episodes fraction", "eval --controller trim --episodes 1.5", "'1.5' is not an integer"),
    row("eval episodes 400 digits", f"eval --controller trim --episodes {BIG}", "is out of range (at most"),
    row("eval seed negative", "eval --controller trim --seed -1", "--seed: '-1' must be >= 0"),
    row("eval seed 400 digits", f"eval --controller trim --seed {BIG}", "is out of range"),
    row("eval seconds zero", "eval --controller trim --seconds 0", "--seconds: '0' must be in (0, 3600] s"),
    row("eval seconds negative", "eval --controller trim --seconds -5", "must be in (0, 3600] s"),
    row("eval seconds inf", "eval --controller trim --seconds inf", "'inf' is not a finite number"),
    row("eval seconds nan", "eval --controller trim --seconds nan", "'nan' is not a finite number"),
    row("eval seconds a year", "eval --controller trim --seconds 3e7", "must be in (0, 3600] s"),
    row("eval backend", "eval --controller trim --backend jax", "invalid choice: 'jax'"),
    row("eval cuda index", "eval --controller trim --device cuda:64", "CUDA"),
    row("eval device tpu", "eval --controller trim --device tpu", "--device 'tpu' is not a torch device"),
    row("eval device mps", "eval --controller trim --device mps", "only cpu and cuda devices are supported"),
    row("eval device empty", ["eval", "--controller", "trim", "--device", ""], "is not a torch device"),
    row("eval unknown airframe", "eval --controller trim --airframe concorde", "unknown airframe 'concorde'"),
    row("eval malformed airframe", "eval --controller trim --airframe {bad_af}", "bad.json: not valid JSON"),
    row("eval maneuvers unknown", "eval --controller trim --task attitude --maneuvers loop --out {out}",
        "--maneuvers: unknown ['loop']"),
    row("eval maneuvers empty", "eval --controller trim --task attitude --maneuvers , --out {out}",
        "--maneuvers must be a comma list of at least one name"),
    row("eval maneuvers wrong task", "eval --controller trim --task altitude --maneuvers circle --out {out}",
        "--maneuvers does not apply to the altitude protocol"),
    row("eval sea state wrong task", "eval --controller trim --task altitude --sea-state 2 --out {out}",
        "--sea-state does not apply to the altitude protocol"),
    row("eval sea state out of range", "eval --controller trim --task sea_skimming --sea-state 7 --out {out}",
        "invalid choice: 7"),
    row("eval clearance negative", "eval --controller trim --task sea_skimming --clearance -0.1 --out {out}",
        "--clearance must be a number of spans in (0, 2]"),
    row("eval turbulence unknown", "eval --controller trim --task path_following --turbulence gale --out {out}",
        "invalid choice: 'gale'"),
    row("eval guided on a task without a path", "eval --controller guided-lqr --task altitude --out {out}",
        "guided-lqr"),
    row("eval out unwritable", f"eval --controller trim --out {UNWRITABLE}", "is not a writable directory"),
    row("eval out is a file", "eval --controller trim --out {file}", "is not a writable directory"),
    row("eval out NUL", ["eval", "--controller", "trim", "--out", "a\0b"], "is not a writable directory"),
    # experiment
    row("experiment no action", "experiment", "the following arguments are required: action"),
    row("experiment unknown action", "experiment sweep", "invalid choice: 'sweep'"),
    row("experiment unknown task", "experiment ablation --tasks hover", "--tasks: unknown ['hover']"),
    row("experiment no task", "experiment ablation --tasks ,", "--tasks must be a comma list of at least one"),
    row("experiment no controller", ["experiment", "ablation", "--controllers", ""],
        "--controllers must be a comma list of at least one name"),
    row("experiment controller not of task", "experiment ablation --tasks path_following --controllers lqr",
        "--controllers: controller 'lqr' does not apply to task 'path_following'"),
    row("experiment missing policy", "experiment ablation --controllers nope.pt",
        "--controllers 'nope.pt' is neither a controller of the task nor a policy file"),
    row("experiment text policy", "experiment ablation --controllers {text_pt}", "not a torch file"),
    row("experiment no shipped ppo", "experiment ablation --tasks attitude --controllers ppo --airframe navion",
        "no shipped ppo policy for task 'attitude' on 'navion'"),
    row("experiment episodes zero", "experiment ablation --episodes 0", "--episodes: '0' must be >= 1"),
    row("experiment seconds inf", "experiment ablation --seconds inf", "--seconds: 'inf' is not a finite number"),
    row("experiment seconds zero", "experiment ablation --seconds 0", "must be in (0, 3600] s"),
    row("experiment cuda index", "experiment ablation --device cuda:64", "CUDA"),
    row("experiment backend", "experiment ablation --backend jax", "invalid choice: 'jax'"),
    row("experiment unknown airframe", "experiment ablation --airframe concorde", "unknown airframe 'concorde'"),
    row("experiment seed negative", "experiment ablation --seed -1", "--seed: '-1' must be >= 0"),
    row("experiment out unwritable", f"experiment ablation --out {UNWRITABLE}", "is not a writable directory"),
    # bench
    row("bench unknown backend", "bench --backend jax", "--backend: unknown ['jax']; choose from"),
    row("bench no backend", "bench --backend ,", "--backend must be a comma list of at least one name"),
    row("bench envs zero", "bench --envs 0", "--envs must be a comma list of env counts: '0' must be an integer in"),
    row("bench envs text", "bench --envs a", "'a' is not an integer"),
    row("bench envs 400 digits", f"bench --envs {BIG}", "is out of range (at most"),
    row("bench envs too many", "bench --envs 100000000", "must be an integer in [1, 1048576]"),
    row("bench steps zero", "bench --steps 0", "--steps: '0' must be >= 1"),
    row("bench trials too few", "bench --trials 4", "--trials: '4' must be an integer in [5,"),
    row("bench warmup negative", "bench --warmup -1", "--warmup: '-1' must be >= 0"),
    row("bench dt zero", "bench --dt 0", "--dt: '0' must be in (0, 0.1] s"),
    row("bench dt inf", "bench --dt inf", "'inf' is not a finite number"),
    row("bench dt nan", "bench --dt nan", "'nan' is not a finite number"),
    row("bench dt huge", "bench --dt 10", "must be in (0, 0.1] s"),
    row("bench threads zero", "bench --threads 0", "--threads: '0' must be an integer in [1, 4096]"),
    row("bench warp threads zero", "bench --warp-threads 0", "--warp-threads: '0' must be an integer in"),
    row("bench cuda index", "bench --device cuda:64", "CUDA"),
    row("bench device", "bench --device gpu", "--device 'gpu' is not a torch device"),
    row("bench integrator", "bench --integrator rk45", "invalid choice: 'rk45'"),
    row("bench unknown airframe", "bench --airframe concorde", "unknown airframe 'concorde'"),
    row("bench baseline", "bench --baseline xplane", "invalid choice: 'xplane'"),
    row("bench malformed airframe", "bench --airframe {bad_af}", "bad.json: not valid JSON"),
    row("bench out unwritable", f"bench --out {UNWRITABLE}", "is not a writable directory"),
    # demo
    row("demo episodes zero", "demo --episodes 0", "--episodes: '0' must be >= 1"),
    row("demo mppi episodes zero", "demo --mppi-episodes 0", "--mppi-episodes: '0' must be >= 1"),
    row("demo unknown controller", "demo --controllers ppo,pid", "--controllers: unknown ['pid']"),
    row("demo no controller", "demo --controllers ,", "--controllers must be a comma list of at least one"),
    row("demo frames zero", "demo --frames 0", "--frames: '0' must be >= 1"),
    row("demo threads zero", "demo --threads 0", "--threads: '0' must be an integer in [1, 4096]"),
    row("demo seed text", "demo --seed x", "--seed: 'x' is not an integer"),
    row("demo backend", "demo --backend jax", "invalid choice: 'jax'"),
    row("demo unknown airframe", "demo --airframe concorde --out {out}", "unknown airframe 'concorde'"),
    row("demo malformed airframe", "demo --airframe {bad_af} --out {out}", "bad.json: not valid JSON"),
    row("demo out unwritable", f"demo --out {UNWRITABLE}", "is not a writable directory"),
    # validate
    row("validate no target", "validate", "the following arguments are required: target"),
    row("validate unknown target", "validate xplane --airframe navion", "invalid choice: 'xplane'"),
    row("validate heights text", "validate jsbsim --airframe navion --heights a,b", "'a' is not a number"),
    row("validate heights zero", "validate jsbsim --airframe navion --heights 0", "'0' must be in (0, 20000] m"),
    row("validate heights inf", "validate jsbsim --airframe navion --heights 1,inf", "'inf' is not a finite"),
    row("validate heights empty", "validate jsbsim --airframe navion --heights ,", "expected comma-separated"),
    row("validate duration zero", "validate jsbsim --airframe navion --duration 0", "'0' must be in (0, 3600] s"),
    row("validate duration nan", "validate jsbsim --airframe navion --duration nan", "not a finite number"),
    row("validate dt zero", "validate jsbsim --airframe navion --dt 0", "'0' must be in (0, 0.05] s"),
    row("validate dt large", "validate jsbsim --jsbsim-model c172p --dt 0.1", "'0.1' must be in (0, 0.05] s"),
    row("validate ground effect", "validate jsbsim --airframe navion --ground-effect sometimes",
        "--ground-effect: unknown ['sometimes']; choose from off, on, both"),
    row("validate excitation", "validate jsbsim --airframe navion --excitation spin",
        "--excitation: unknown ['spin']; choose from trim, doublet"),
    row("validate amplitude", "validate jsbsim --airframe navion --doublet-amplitude 2", "'2' must be in (0, 1]"),
    row("validate amplitude nan", "validate jsbsim --airframe navion --doublet-amplitude nan", "not a finite"),
    row("validate unknown airframe", "validate jsbsim --airframe concorde", "unknown airframe 'concorde'"),
    row("validate malformed airframe", "validate jsbsim --airframe {bad_af}", "bad.json: not valid JSON"),
    row("validate out unwritable", f"validate jsbsim --airframe navion --out {UNWRITABLE}",
        "is not a writable directory"),
    # airframe derive
    row("derive no geometry", "airframe derive", "the following arguments are required: geometry"),
    row("derive unknown action", "airframe build x.json", "invalid choice: 'build'"),
    row("derive missing geometry", "airframe derive {tmp}/missing.json", "geometry file not found"),
    row("derive geometry is a folder", "airframe derive {dir}", "geometry file not found"),
    row("derive geometry not JSON", "airframe derive {bad_af}", "bad.json: not valid JSON"),
    row("train negative obs delay", ["train", "ppo", "--out", "{tmp}/t", "--set",
                                     'env_options={{"obs_delay_ms": -5}}'], "delays must be finite numbers"),
    row("train reversed delay range", ["train", "ppo", "--out", "{tmp}/t", "--set",
                                       'env_options={{"action_delay_ms": (50, 10)}}'], "low <= high"),
    row("train huge obs delay", ["train", "ppo", "--out", "{tmp}/t", "--set",
                                 'env_options={{"obs_delay_ms": 1e12}}'], "delays must be finite numbers"),
    row("derive geometry not UTF-8", "airframe derive {latin1_json}", "latin1.json: not UTF-8 text"),
    row("derive geometry duplicate key", "airframe derive {geom_duplicate}", "duplicate key 'name'"),
    row("derive geometry NaN", "airframe derive {geom_nan}", "must be finite"),
    row("derive geometry a list", "airframe derive {geom_list}", "one JSON object"),
    row("derive name with escape codes", "airframe derive {geom_escape}", r"field 'name': contains control characters: \x1b[2J"),
    row("derive name with a path", "airframe derive {geom_path}", "field 'name' '../evil.json' must be a plain name"),
    row("derive out is a folder", "airframe derive {geometry} --out {dir}", "is a directory, not a file name"),
    row("derive out unwritable", f"airframe derive {{geometry}} --out {UNWRITABLE}/x.json",
        "is not a writable directory"),
    row("derive plot unwritable", f"airframe derive {{geometry}} --out {{tmp}}/x.json --plot {UNWRITABLE}/p.png",
        "--plot '/proc/falcon-rl-test/out' is not a writable directory"),
]


@pytest.fixture(scope="module")
def paths(tmp_path_factory) -> dict[str, str]:
    """The files the table refers to: folders, a plain file, files that are not policies, bad JSON."""
    tmp = tmp_path_factory.mktemp("bad-inputs")
    (tmp / "folder").mkdir()
    (tmp / "dir.json").mkdir()
    (tmp / "file.txt").write_text("a file, not a folder\n")
    (tmp / "notes.pt").write_text("these are notes, renamed .pt\n")
    (tmp / "empty.pt").write_bytes(b"")
    (tmp / "plain.pt").write_bytes(pickle.dumps({"weights": [1, 2, 3]}))
    (tmp / "bad.json").write_text("{nope")
    (tmp / "geom_duplicate.json").write_text('{"name": "a", "name": "b"}')
    (tmp / "geom_nan.json").write_text('{"name": "a", "mass": NaN}')
    (tmp / "geom_list.json").write_text("[1, 2]")
    (tmp / "latin1.json").write_bytes('{"name": "caf\u00e9"}'.encode("latin-1"))
    geometry = json.loads((ROOT / "airframes" / "geometry" / "volantex_ranger.json").read_text())
    for stem, name in (("escape", "\x1b[2Jwiped"), ("path", "../evil")):
        (tmp / f"geom_{stem}.json").write_text(json.dumps({**geometry, "name": name}))
    return {"tmp": str(tmp), "out": str(tmp / "out"), "dir": str(tmp / "folder"), "dir_json": str(tmp / "dir.json"),
            "file": str(tmp / "file.txt"), "text_pt": str(tmp / "notes.pt"), "empty_pt": str(tmp / "empty.pt"),
            "pickle_pt": str(tmp / "plain.pt"), "bad_af": str(tmp / "bad.json"),
            "latin1_json": str(tmp / "latin1.json"), "attitude_pt": str(POLICIES / "ppo_attitude_volantex_ranger.pt"),
            "geometry": str(ROOT / "airframes" / "geometry" / "volantex_ranger.json"),
            "geom_escape": str(tmp / "geom_escape.json"), "geom_path": str(tmp / "geom_path.json"),
            **{f"geom_{k}": str(tmp / f"geom_{k}.json") for k in ("duplicate", "nan", "list")}}


def assert_one_line(capsys, argv: list[str], needle: str) -> str:
    """Run ``argv``: exit code 2, nothing on stdout, one printable line on stderr holding ``needle``."""
    code = main(argv)
    out, err = capsys.readouterr()
    assert code == 2, (argv, code, err)
    assert out == "", out
    assert "Traceback" not in err
    lines = err.splitlines()
    assert len(lines) == 1 and err.endswith("\n"), err
    assert not any(unicodedata.category(ch).startswith("C") for ch in lines[0]), lines[0]
    assert lines[0].startswith("falcon-rl"), lines[0]
    assert needle in lines[0], lines[0]
    return lines[0]


@pytest.mark.parametrize(("argv", "needle"), CLI_CASES)
def test_bad_cli_input_exits_2_with_one_line(capsys, paths, argv, needle):
    assert_one_line(capsys, [arg.format(**paths) for arg in argv], needle)


def test_cuda_on_a_machine_without_it(capsys):
    """The audit's first case: --device cuda where torch sees no CUDA device."""
    import torch

    if torch.cuda.is_available():
        pytest.skip("this machine has CUDA")
    for argv in (["eval", "--controller", "trim"], ["experiment", "ablation"], ["bench"]):
        assert_one_line(capsys, [*argv, "--device", "cuda"], "--device 'cuda': CUDA is not available")


@pytest.mark.parametrize(("label", "mutate", "message"), CASES, ids=[c[0] for c in CASES])
def test_invalid_airframe_exits_2_with_one_line(capsys, tmp_path, label, mutate, message):
    document = copy.deepcopy(json.loads(SOURCE.read_text()))
    mutate(document)
    path = tmp_path / "broken.json"
    path.write_text(json.dumps(document))
    line = assert_one_line(capsys, ["trim", "--airframe", str(path)], str(path))
    assert "field '" in line, label


@pytest.mark.parametrize(("label", "transform", "message"), RAW_CASES, ids=[c[0] for c in RAW_CASES])
def test_malformed_airframe_file_exits_2_with_one_line(capsys, tmp_path, label, transform, message):
    path = tmp_path / "broken.json"
    path.write_bytes(transform(SOURCE.read_text()))
    line = assert_one_line(capsys, ["trim", "--airframe", str(path)], str(path))
    assert len(line) < 600, label


def test_validate_choices_match_the_comparison(capsys):
    """validate's flags list the settings and excitations of the comparison module they are passed to."""
    from falcon_rl.commands import validate
    from falcon_rl.validation.jsbsim_compare import EXCITATIONS, GE_SETTINGS

    assert (tuple(GE_SETTINGS), tuple(EXCITATIONS)) == (validate.GROUND_EFFECT, validate.EXCITATIONS)


def test_outputs_stay_inside_out(capsys, tmp_path, monkeypatch):
    """An --airframe path with '..' names the figure after the airframe, inside --out, wherever it points."""
    (tmp_path / "a" / "b").mkdir(parents=True)
    (tmp_path / "a" / "ranger.json").write_text(SOURCE.read_text())
    monkeypatch.chdir(tmp_path / "a" / "b")
    before = {p for p in tmp_path.rglob("*")}
    code = main(["eval", "--controller", "trim", "--task", "climb_descend", "--airframe", "../ranger.json",
                 "--episodes", "1", "--seconds", "0.05", "--out", "out", "--json"])
    doc = json.loads(capsys.readouterr().out)
    assert code == 0
    written = {p for p in tmp_path.rglob("*") if p.is_file()} - before
    assert written and all(p.is_relative_to(tmp_path / "a" / "b" / "out") for p in written), written
    assert Path(doc["figure"]).name == "climb_descend_volantex_ranger_trim.png"


def test_closed_stdout_ends_quietly():
    """``falcon-rl airframes --json | head -0``: the reader is gone before the first write; no traceback."""
    process = subprocess.Popen([sys.executable, "-m", "falcon_rl.cli", "airframes", "--json"],
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=ROOT)
    process.stdout.close()  # before the interpreter has started: every write meets a closed pipe
    err = process.stderr.read().decode()
    assert process.wait(timeout=120) == 0, err
    assert err == "", err
