"""API reference pages, one per subpackage, generated from the package's files at build time.

Each page shows the subpackage's docstring and then every public module in it (``::: module``,
rendered by mkdocstrings from the docstrings); a nested subpackage (``envs.tasks``) has a page of its
own. Modules and subpackages are found on disk, so a new one appears without editing the site.
"""

from __future__ import annotations

import ast
import importlib.util
from dataclasses import dataclass
from pathlib import Path

from prose import inline

PACKAGE = "falcon_rl"

#: Page order, by the layers of the package (bottom to top); a subpackage not named here follows them.
ORDER: tuple[str, ...] = ("airframe", "physics", "recording", "envs", "envs.tasks", "transforms", "baselines",
                          "policies", "validation", "derive", "recipes", "evaluation", "experiment", "viz",
                          "bridges", "modules")

#: Not in the API reference: the CLI subcommands have the CLI reference page.
SKIPPED: frozenset[str] = frozenset({"commands"})

#: Top-level modules that get a page of their own; the others share the "modules" page.
OWN_PAGE: frozenset[str] = frozenset({"airframe", "recording"})


@dataclass(frozen=True)
class ApiPage:
    """One page: its file under docs/ (``api/NAME.md``), nav title and Markdown."""

    path: str
    title: str
    markdown: str


def package_dir() -> Path:
    """Folder of the installed package (found without importing it)."""
    spec = importlib.util.find_spec(PACKAGE)
    if spec is None or not spec.submodule_search_locations:
        raise RuntimeError(f"package {PACKAGE!r} is not importable; pip install -e '.[dev]' first")
    return Path(next(iter(spec.submodule_search_locations)))


def _public(path: Path) -> bool:
    return not path.name.startswith(("_", "."))


def _modules(folder: Path) -> list[str]:
    return sorted(p.stem for p in folder.glob("*.py") if _public(p))


def _subpackages(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir()
                  if p.is_dir() and not p.is_symlink() and _public(p) and (p / "__init__.py").is_file())


def _directive(identifier: str, **options: object) -> str:
    lines = [f"::: {identifier}"]
    if options:
        lines.append("    options:")
        lines.extend(f"      {key}: {str(value).lower() if isinstance(value, bool) else value}"
                     for key, value in options.items())
    return "\n".join(lines)


def _package_page(dotted: str, folder: Path) -> str:
    identifier = f"{PACKAGE}.{dotted}"
    parts = [_directive(identifier, members="false", heading_level=1)]
    nested = _subpackages(folder)
    if nested:
        parts += ["", "Subpackages: " + ", ".join(f"[`{identifier}.{name}`]({dotted}.{name}.md)"
                                                  for name in nested) + "."]
    for module in _modules(folder):
        parts += ["", _directive(f"{identifier}.{module}")]
    return "\n".join(parts) + "\n"


def api_pages() -> list[ApiPage]:
    """The reference pages, index first, in ``ORDER``."""
    root = package_dir()
    pages: dict[str, ApiPage] = {}

    def add_package(dotted: str, folder: Path) -> None:
        if dotted.split(".")[0] in SKIPPED:
            return
        pages[dotted] = ApiPage(f"api/{dotted}.md", f"{PACKAGE}.{dotted}", _package_page(dotted, folder))
        for name in _subpackages(folder):
            add_package(f"{dotted}.{name}", folder / name)

    for name in _subpackages(root):
        add_package(name, root / name)
    shared = []
    for module in _modules(root):
        if module in OWN_PAGE:
            pages[module] = ApiPage(f"api/{module}.md", f"{PACKAGE}.{module}",
                                    _directive(f"{PACKAGE}.{module}", heading_level=1) + "\n")
        else:
            shared.append(module)
    if shared:
        body = "\n\n".join(_directive(f"{PACKAGE}.{module}") for module in shared)
        pages["modules"] = ApiPage("api/modules.md", "Other modules",
                                   f"# Other modules\n\nThe package's top-level modules.\n\n{body}\n")
    ordered = [pages.pop(name) for name in ORDER if name in pages] + [pages[name] for name in sorted(pages)]
    rows = "\n".join(f"| [{page.title}]({Path(page.path).name}) | {_summary(page)} |" for page in ordered)
    index = ApiPage("api/index.md", "Overview", "\n".join([
        "# API reference", "",
        "Generated at build time from the package's docstrings (the prose of the code, one place per "
        "idea): one page per subpackage, each module in full. Names in `__all__` of a subpackage are "
        "documented in the module that defines them.", "",
        _directive(PACKAGE, members="false", show_root_heading=False, show_root_toc_entry=False), "",
        "| page | contents |", "|---|---|", rows, ""]))
    return [index, *ordered]


def _summary(page: ApiPage) -> str:
    """First line of the package docstring behind a page (read from the file, without importing)."""
    dotted = page.title.removeprefix(f"{PACKAGE}.")
    folder = package_dir() / dotted.replace(".", "/")
    source = folder / "__init__.py" if folder.is_dir() else folder.with_suffix(".py")
    if not source.is_file():
        return "top-level modules: " + ", ".join(f"`{m}`" for m in _modules(package_dir())
                                                 if m not in OWN_PAGE)
    doc = ast.get_docstring(ast.parse(source.read_text(encoding="utf-8"))) or ""
    package = f"{PACKAGE}.{dotted}"
    if source.name != "__init__.py":
        package = package.rpartition(".")[0]
    base = source.parent

    def resolve(name: str) -> str:
        """Role targets of the docstring: absolute, relative (".mod") or a module of the package."""
        if name.startswith("."):
            return f"{package}.{name.lstrip('.')}"
        head = name.split(".")[0]
        if (base / f"{head}.py").is_file() or (base / head / "__init__.py").is_file():
            return f"{package}.{name}"
        if name.startswith(f"{PACKAGE}."):
            return name
        return f"{package}.{name}"

    return inline(doc.split("\n\n")[0].replace("\n", " ").strip(), resolve, in_table=True)
