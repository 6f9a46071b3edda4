"""Start-up: ``import falcon_rl`` and ``falcon-rl --help`` import neither torch, TorchRL nor Warp, the
Gymnasium ids are registered all the same, and the help texts are complete."""

from __future__ import annotations

import contextlib
import json
import subprocess
import sys
from pathlib import Path

import pytest

import falcon_rl
from falcon_rl.cli import DESCRIPTION, command_modules, main

ROOT = Path(__file__).resolve().parents[1]
HEAVY = ("torch", "torchrl", "tensordict", "warp")
COMMANDS = {"airframe", "airframes", "bench", "demo", "eval", "experiment", "fly", "ge-table", "replay",
            "train", "trim", "validate", "xplane"}


def run_python(code: str) -> dict:
    """Run ``code`` in a fresh interpreter; it prints one JSON document as its last line."""
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_import_is_light_and_registers_the_gym_ids():
    doc = run_python(
        "import json, sys\n"
        "import falcon_rl\n"
        f"heavy = sorted(m for m in {HEAVY!r} if m in sys.modules)\n"
        "import gymnasium\n"
        "env = gymnasium.make('falcon_rl/Altitude-v0', airframe='volantex_ranger')\n"
        "obs, _ = env.reset(seed=0)\n"
        "print(json.dumps({'heavy': heavy, 'obs': list(obs.shape), 'steps': env.spec.max_episode_steps}))\n")
    assert doc["heavy"] == []
    assert doc["obs"][0] > 0 and doc["steps"] > 0


def test_help_and_version_import_nothing_heavy():
    doc = run_python(
        "import contextlib, io, json, sys\n"
        "from falcon_rl.cli import main\n"
        "with contextlib.redirect_stdout(io.StringIO()) as out:\n"
        "    codes = [main(['--help']), main(['--version']), main(['trim', '--help'])]\n"
        f"heavy = sorted(m for m in {HEAVY!r} if m in sys.modules)\n"
        "print(json.dumps({'codes': codes, 'heavy': heavy, 'out': out.getvalue()}))\n")
    assert doc["codes"] == [0, 0, 0] and doc["heavy"] == []
    assert "falcon-rl airframes" in doc["out"] and "--airspeed" in doc["out"]


def test_version_prints_the_package_version(capsys):
    from importlib.metadata import PackageNotFoundError, version

    assert main(["--version"]) == 0
    assert capsys.readouterr().out.strip() == f"falcon-rl {falcon_rl.__version__}"
    with contextlib.suppress(PackageNotFoundError):  # a source tree that is not installed has no metadata
        assert version("falcon-rl") == falcon_rl.__version__


def test_help_lists_every_subcommand_with_a_complete_description(capsys):
    assert main(["--help"]) == 0
    out = capsys.readouterr().out
    assert set(command_modules()) == COMMANDS
    words = " ".join(out.split())
    for name, module in command_modules().items():
        assert f" {name} {' '.join(module.HELP.split()[:4])}" in words, name
    assert DESCRIPTION.endswith(".") and " ".join(DESCRIPTION.split()) in words
    assert "typical commands:" in out and "falcon-rl eval --task altitude --controller lqr" in out


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_every_subcommand_help_works(capsys, command):
    assert main([command, "--help"]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"usage: falcon-rl {command}") and "--json" in out


def test_eval_help_lists_every_controller_of_every_task(capsys):
    from falcon_rl.envs.tasks import TASK_SPECS

    assert main(["eval", "--help"]) == 0
    out = " ".join(capsys.readouterr().out.split())
    for task, spec in TASK_SPECS.items():
        assert f"{task}: {', '.join(sorted(spec.controllers))}" in out, task
    assert "ppo, sac or td3 (the shipped policy of that algorithm" in out and "policy file" in out
    assert "--policy-seed" in out
    assert "--backend {torch,warp}" in out and "default warp" in out


def test_builtin_gym_registrations_match_the_task_registry():
    """The ids that ``import falcon_rl`` registers without torch are those ``register_gym_envs`` makes."""
    import gymnasium

    from falcon_rl.envs import BUILTIN_GYM_IDS
    from falcon_rl.envs.gym import register_gym_envs
    from falcon_rl.envs.tasks import TASK_SPECS

    shipped = {name for name, spec in TASK_SPECS.items()
               if spec.task.__module__.startswith("falcon_rl.envs.tasks.")}
    assert set(BUILTIN_GYM_IDS) == shipped
    light = {task: gymnasium.spec(gym_id) for task, (gym_id, _) in BUILTIN_GYM_IDS.items()}
    for spec in light.values():
        del gymnasium.registry[spec.id]
    try:
        assert set(register_gym_envs()) >= {spec.id for spec in light.values()}
        for task, spec in light.items():
            assert gymnasium.spec(spec.id) == spec, task
    finally:
        gymnasium.registry.update({spec.id: spec for spec in light.values()})


def test_lazy_names_stay_importable():
    """Every public name of the lazy packages resolves where it did before, and ``dir`` lists it."""
    import importlib

    for package in ("falcon_rl", "falcon_rl.envs", "falcon_rl.physics", "falcon_rl.transforms",
                    "falcon_rl.evaluation"):
        module = importlib.import_module(package)
        for name in module.__all__:
            assert getattr(module, name) is not None, (package, name)
            assert name in dir(module), (package, name)
        with pytest.raises(AttributeError, match="has no attribute 'no_such_name'"):
            module.no_such_name  # noqa: B018
