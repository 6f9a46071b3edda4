"""Layers run one way: no module of ``falcon_rl`` imports a layer above its own, and no modules import
each other in a cycle.

Every import statement counts, also the ones inside functions and under ``TYPE_CHECKING``, and so do
``importlib.import_module`` calls with a literal name, or with ``f"falcon_rl.pkg.{name}"``,
``f"{pkg.__name__}.{name}"`` (``pkg`` an imported module) or ``f"{__package__}.{name}"``: those import the
modules of ``pkg`` whose names (``"name"`` or ``"name:attribute"``) are string literals of the file, or
every module of ``pkg`` when none are.
Importing ``a.b.c`` also runs the ``__init__`` of the packages ``a.b`` above it, so those count as
imported too (unless the importer lives inside them, where they already ran); ``from pkg import name``
imports the submodule ``pkg.name`` when there is one, else the package's ``__init__`` itself.
"""

from __future__ import annotations

import ast
from collections.abc import Callable, Iterable
from pathlib import Path

ROOT = "falcon_rl"
PACKAGE_DIR = Path(__file__).resolve().parents[1] / ROOT

#: Bottom to top: a module may import modules of its own layer and of the layers below. An entry names a
#: module or a package (and everything in it); the root package (the public facade) is on top.
#: ``validation`` and ``derive`` import only physics and the airframe, so they sit on the lowest layer that
#: allows it.
LAYERS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("constants", ("falcon_rl.constants", "falcon_rl.defaults", "falcon_rl._lazy", "falcon_rl.atomic_files")),
    ("airframe", ("falcon_rl.airframe", "falcon_rl.airframe_terms")),
    ("physics / recording", ("falcon_rl.physics", "falcon_rl.recording", "falcon_rl.recording_schema")),
    ("envs / transforms / baselines / policies / validation / derive",
     ("falcon_rl.envs", "falcon_rl.transforms", "falcon_rl.baselines", "falcon_rl.policies",
      "falcon_rl.validation", "falcon_rl.derive")),
    ("recipes / evaluation", ("falcon_rl.recipes", "falcon_rl.evaluation")),
    ("experiment", ("falcon_rl.experiment",)),
    ("viz / bridges", ("falcon_rl.viz", "falcon_rl.bridges")),
    ("commands", ("falcon_rl.commands", "falcon_rl.cli", ROOT)),
)

Graph = dict[str, set[str]]


def layer_of(module: str, layers: tuple[tuple[str, tuple[str, ...]], ...] = LAYERS, root: str = ROOT
             ) -> int | None:
    """Index in ``layers`` of the longest entry naming ``module`` or a package holding it (the root
    package names only itself); None when no entry does."""
    best: tuple[int, int] | None = None
    for index, (_, entries) in enumerate(layers):
        for entry in entries:
            names_module = module == entry or (entry != root and module.startswith(entry + "."))
            if names_module and (best is None or len(entry) > best[0]):
                best = (len(entry), index)
    return None if best is None else best[1]


def ancestors(module: str) -> list[str]:
    """``a.b.c`` -> [``a``, ``a.b``]."""
    parts = module.split(".")
    return [".".join(parts[:i]) for i in range(1, len(parts))]


def imported_names(tree: ast.AST, module: str, is_package: bool, known: set[str]) -> set[str]:
    """The modules of ``known`` that the code of ``module`` imports (see the module docstring)."""
    package = module if is_package else module.rpartition(".")[0]
    bound = {"__name__": module, "__package__": package}  # for import_module(f"{pkg.__name__}.{name}")
    targets: set[str] = set()
    dynamic: list[ast.expr] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            targets.update(alias.name for alias in node.names)
            bound.update({alias.asname: alias.name for alias in node.names if alias.asname})
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                base = ".".join([*anchor, *([base] if base else [])])
            for alias in node.names:
                sub = f"{base}.{alias.name}"
                targets.add(sub if sub in known else base)
                if sub in known:
                    bound[alias.asname or alias.name] = sub
        elif isinstance(node, ast.Call) and node.args and _is_import_module(node.func):
            dynamic.append(node.args[0])
    strings = {node.value.partition(":")[0] for node in ast.walk(tree)
               if isinstance(node, ast.Constant) and isinstance(node.value, str)}
    for arg in dynamic:
        name, any_submodule = _dynamic_module(arg, bound)
        inside = [m for m in known if name and m.startswith(name + ".")] if any_submodule else []
        named = [m for m in inside if m[len(str(name)) + 1:] in strings]
        targets.update(named or inside or ([name] if name else []))
    own = {*ancestors(module), module}
    found: set[str] = set()
    for target in targets:
        if target in known:
            found.add(target)
        found.update(a for a in ancestors(target) if a in known and a not in own and a != ROOT)
    found.discard(module)
    return found


def _is_import_module(func: ast.expr) -> bool:
    return (isinstance(func, ast.Attribute) and func.attr == "import_module") or (
        isinstance(func, ast.Name) and func.id == "import_module")


def _dynamic_module(arg: ast.expr, bound: dict[str, str]) -> tuple[str | None, bool]:
    """(module, whether any module inside it) of an ``import_module`` argument: ``"a.b"`` -> (a.b, False);
    ``f"a.b.{x}"`` and ``f"{pkg.__name__}.{x}"`` (``pkg`` bound to module a.b) -> (a.b, True); else None."""
    if isinstance(arg, ast.Constant) and isinstance(arg.value, str):
        return arg.value, False
    if not isinstance(arg, ast.JoinedStr) or not arg.values:
        return None, False
    head, *rest = arg.values
    if isinstance(head, ast.FormattedValue) and rest and isinstance(rest[0], ast.Constant):
        base = _bound_module(head.value, bound)
        if base is None:
            return None, False
        text, rest = base + str(rest[0].value), rest[1:]
    elif isinstance(head, ast.Constant):
        text = str(head.value)
    else:
        return None, False
    if not rest:
        return text, False
    return (text[:-1], True) if text.endswith(".") else (None, False)


def _bound_module(expr: ast.expr, bound: dict[str, str]) -> str | None:
    """The module named by ``__name__``, ``pkg`` or ``pkg.__name__`` (``pkg`` bound to a module)."""
    if isinstance(expr, ast.Attribute) and expr.attr == "__name__":
        expr = expr.value
    return bound.get(expr.id) if isinstance(expr, ast.Name) else None


def import_graph(package_dir: Path = PACKAGE_DIR, root: str = ROOT) -> Graph:
    """Module -> the package's modules it imports, for every ``.py`` file under ``package_dir``."""
    files = {}
    for path in sorted(package_dir.rglob("*.py")):
        parts = [root, *path.relative_to(package_dir).with_suffix("").parts]
        if parts[-1] == "__init__":
            parts.pop()
        files[".".join(parts)] = path
    known = set(files)
    return {module: imported_names(ast.parse(path.read_text(), str(path)), module,
                                   path.name == "__init__.py", known)
            for module, path in files.items()}


def find_cycles(graph: Graph) -> list[list[str]]:
    """Cycles (their modules in import order, the first one repeated at the end) that together pass
    through every module of every strongly connected component that has one."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    cycles: list[list[str]] = []

    def visit(node: str) -> None:  # Tarjan's algorithm
        index[node] = low[node] = len(index)
        stack.append(node)
        for succ in sorted(graph.get(node, ())):
            if succ not in index:
                visit(succ)
                low[node] = min(low[node], low[succ])
            elif succ in stack:
                low[node] = min(low[node], index[succ])
        if low[node] == index[node]:
            component = {stack.pop()}
            while node not in component:
                component.add(stack.pop())
            on_a_cycle: set[str] = set()
            for member in [node, *sorted(component - {node})]:
                if member not in on_a_cycle and (len(component) > 1 or node in graph.get(node, ())):
                    cycles.append(_cycle_through(member, graph, component))
                    on_a_cycle.update(cycles[-1])

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return cycles


def _cycle_through(start: str, graph: Graph, component: set[str]) -> list[str]:
    """A shortest path start -> ... -> start inside ``component`` (breadth first)."""
    paths = {start: [start]}
    frontier = [start]
    while frontier:
        next_frontier = []
        for node in frontier:
            for succ in sorted(graph.get(node, ())):
                if succ == start:
                    return [*paths[node], start]
                if succ in component and succ not in paths:
                    paths[succ] = [*paths[node], succ]
                    next_frontier.append(succ)
        frontier = next_frontier
    raise AssertionError(f"{start} is on no cycle")


def upward_imports(graph: Graph, layer: Callable[[str], int | None]) -> list[str]:
    """``importer -> imported`` for every import of a higher layer than the importer's."""
    return [f"{importer} -> {imported}" for importer, targets in sorted(graph.items())
            for imported in sorted(targets) if (layer(imported) or 0) > (layer(importer) or 0)]


def _lines(items: Iterable[str]) -> str:
    return "\n  ".join(["", *items])


def test_every_module_has_a_layer():
    unplaced = [module for module in import_graph() if layer_of(module) is None]
    assert not unplaced, f"modules in no layer of tests/test_layers.py LAYERS:{_lines(unplaced)}"


def test_no_import_cycles():
    cycles = find_cycles(import_graph())
    assert not cycles, f"import cycles:{_lines(' -> '.join(cycle) for cycle in cycles)}"


def test_no_upward_imports():
    upward = upward_imports(import_graph(), layer_of)
    names = [name for name, _ in LAYERS]
    assert not upward, f"imports against the layer order {' < '.join(names)}:{_lines(upward)}"


def test_the_checks_catch_a_cycle_and_an_upward_import():
    graph = {"falcon_rl.physics.a": {"falcon_rl.physics.b"}, "falcon_rl.physics.b": {"falcon_rl.physics.a"},
             "falcon_rl.airframe": {"falcon_rl.envs.x"}, "falcon_rl.envs.x": {"falcon_rl.physics.a"}}
    assert find_cycles(graph) == [["falcon_rl.physics.a", "falcon_rl.physics.b", "falcon_rl.physics.a"]]
    assert upward_imports(graph, layer_of) == ["falcon_rl.airframe -> falcon_rl.envs.x"]
    assert find_cycles({"a": {"b"}, "b": {"c"}, "c": set()}) == []
    assert find_cycles({"x": {"y", "z"}, "y": {"x"}, "z": {"x"}}) == [["x", "y", "x"], ["z", "x", "z"]]


def test_the_parser_sees_lazy_relative_and_dynamic_imports():
    source = """
import importlib
from . import state
from .. import recipes as recipe_package
from ..airframe import Airframe
def late(name):
    from . import make_env
    from ..transforms.presets import robustness_transforms
    importlib.import_module("falcon_rl.viz")
    return importlib.import_module(f"{recipe_package.__name__}.{name}")
"""
    known = {"falcon_rl", "falcon_rl.airframe", "falcon_rl.envs", "falcon_rl.envs.gym",
             "falcon_rl.envs.state", "falcon_rl.transforms", "falcon_rl.transforms.presets",
             "falcon_rl.recipes", "falcon_rl.recipes.ppo", "falcon_rl.viz"}
    found = imported_names(ast.parse(source), "falcon_rl.envs.gym", False, known)
    assert found == {"falcon_rl.envs.state", "falcon_rl.airframe", "falcon_rl.envs", "falcon_rl.transforms",
                     "falcon_rl.transforms.presets", "falcon_rl.recipes", "falcon_rl.recipes.ppo",
                     "falcon_rl.viz"}
    registry = """
ENGINES = {"warp": "warp_backend:WarpEngine"}
def engine(name):
    module, _, cls = ENGINES[name].partition(":")
    return getattr(importlib.import_module(f"{__package__}.{module}"), cls)
"""
    known = {"falcon_rl.physics", "falcon_rl.physics.warp_backend", "falcon_rl.physics.simulator"}
    assert imported_names(ast.parse(registry), "falcon_rl.physics.engine", False, known) == {
        "falcon_rl.physics.warp_backend"}
    assert layer_of("falcon_rl") == len(LAYERS) - 1 and layer_of("falcon_rl.unknown") is None
