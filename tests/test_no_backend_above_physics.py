"""No code above ``falcon_rl/physics/`` names a backend or reaches past the engine contract: it asks the
engine what it can do (``Engine.RUNS_TASK_KERNELS``, ``Engine.fuse``, ...) and takes backend names from
``falcon_rl.defaults``. Read from the source (AST), so a new module is checked as soon as it exists."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from falcon_rl.physics.backends import ENGINES
from falcon_rl.physics.engine import Engine

PACKAGE = Path(__file__).resolve().parents[1] / "falcon_rl"
#: The engines' own modules: what code above the physics must not import.
BACKEND_MODULES = {"torch_backend", "warp_backend", "scipy_backend", "warp_kernels"}
#: Engine members every engine has (the contract), public and private names alike.
CONTRACT = {name for cls in Engine.__mro__ for name in vars(cls)}


def modules_above_physics() -> list[Path]:
    return sorted(path for path in PACKAGE.rglob("*.py")
                  if "physics" not in path.relative_to(PACKAGE).parts and path.name != "defaults.py")


def backend_name(node: ast.AST) -> str | None:
    """The backend a string constant names (registered engines and their ``-compile`` variants)."""
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        name = node.value.removesuffix("-compile")
        return name if name in ENGINES else None
    return None


def violations(path: Path) -> list[str]:
    tree = ast.parse(path.read_text(), str(path))
    found: list[str] = []

    def say(node: ast.AST, what: str) -> None:
        found.append(f"{path.relative_to(PACKAGE.parent)}:{getattr(node, 'lineno', 0)}: {what}")

    for node in ast.walk(tree):
        if isinstance(node, ast.Compare):
            for side in (node.left, *node.comparators):
                if backend_name(side) or (isinstance(side, ast.Tuple | ast.List | ast.Set)
                                          and any(backend_name(e) for e in side.elts)):
                    say(node, "compares with a backend name")
        elif isinstance(node, ast.arguments):
            named = [*node.posonlyargs, *node.args]
            defaults = list(zip(named[len(named) - len(node.defaults):], node.defaults, strict=True))
            defaults += [(a, d) for a, d in zip(node.kwonlyargs, node.kw_defaults, strict=True) if d]
            for arg, default in defaults:
                if backend_name(default):
                    say(default, f"defaults {arg.arg} to a backend name")
        elif isinstance(node, ast.keyword) and node.arg == "backend" and backend_name(node.value):
            say(node, "passes a backend name")
        elif isinstance(node, ast.AnnAssign | ast.Assign) and backend_name(node.value or ast.Constant(None)):
            say(node, "assigns a backend name")
        elif isinstance(node, ast.ImportFrom):
            names = (node.module or "").split(".") + [alias.name for alias in node.names]
            if BACKEND_MODULES & set(names):
                say(node, f"imports a backend module ({', '.join(sorted(BACKEND_MODULES & set(names)))})")
        elif (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Attribute)
              and node.value.attr == "engine" and node.attr not in CONTRACT):
            say(node, f"calls engine.{node.attr}, which is not in the engine contract")
    return found


def test_no_module_above_the_physics_names_a_backend_or_reaches_past_the_contract() -> None:
    paths = modules_above_physics()
    assert len(paths) > 100  # the whole package is read
    problems = [line for path in paths for line in violations(path)]
    assert not problems, "\n".join(problems)


@pytest.mark.parametrize("source, problem", [
    ('if sim.backend == "warp":\n    pass\n', "compares with a backend name"),
    ('def f(backend="torch"):\n    pass\n', "defaults backend to a backend name"),
    ('make_env("altitude", backend="warp")\n', "passes a backend name"),
    ("from ..physics.warp_backend import warp_device\n", "imports a backend module"),
    ("env.sim.engine.bind_views()\n", "not in the engine contract"),
    ('x = "torch-compile"\n', "assigns a backend name"),
])
def test_the_check_finds_each_kind_of_violation(tmp_path: Path, source: str, problem: str) -> None:
    module = PACKAGE / "envs" / "_probe_for_the_contract_test.py"
    try:
        module.write_text(source)
        assert any(problem in line for line in violations(module))
    finally:
        module.unlink()
    assert not violations(PACKAGE / "envs" / "factory.py")
    assert "RUNS_TASK_KERNELS" in CONTRACT and "fuse" in CONTRACT and "bind_views" not in CONTRACT
