"""Griffe extension of the site build: every docstring of the package through ``prose.to_markdown``.

Named in mkdocs.yml (``extensions: [docs/griffe_prose.py]``). Role targets resolve in the scope of the
object that carries the docstring (its members, its module's imports, its parents), relative ones
(``:mod:`.presets```) from its package.
"""

from __future__ import annotations

import sys
from pathlib import Path

import griffe

sys.path.insert(0, str(Path(__file__).resolve().parent))

from prose import to_markdown  # a sibling of this file, not a package


def _resolver(obj: griffe.Object):
    module = obj if obj.is_module else obj.module
    package = module if module.is_init_module else module.parent

    def resolve(name: str) -> str | None:
        if name.startswith("."):
            base = package
            for _ in range(len(name) - len(name.lstrip(".")) - 1):
                base = base.parent if base is not None and base.parent is not None else base
            return f"{base.path}.{name.lstrip('.')}" if base is not None else None
        head, _, rest = name.partition(".")
        try:
            full = obj.resolve(head)
        except (griffe.NameResolutionError, AttributeError, KeyError):
            return None
        return f"{full}.{rest}" if rest else full

    return resolve


def comment_docstring(obj: griffe.Object) -> griffe.Docstring | None:
    """The ``#:`` comment lines right above an attribute (the code's way of documenting constants
    and dataclass fields, as Sphinx reads them), or None."""
    if obj.lineno is None or obj.filepath is None:
        return None
    try:
        lines = obj.lines_collection[obj.filepath]
    except KeyError:
        return None
    index, comment = obj.lineno - 2, []
    while index >= 0 and lines[index].strip().startswith("#:"):
        text = lines[index].strip()[2:]
        comment.insert(0, text[1:] if text.startswith(" ") else text)
        index -= 1
    if not comment:
        return None
    return griffe.Docstring("\n".join(comment), lineno=index + 2, endlineno=obj.lineno - 1, parent=obj)


class ProseDocstrings(griffe.Extension):
    """Rewrite each loaded object's docstring as Markdown (see ``prose.py``); give attributes
    documented by ``#:`` comments those comments as docstrings."""

    def on_object(self, *, obj: griffe.Object, loader: griffe.GriffeLoader, **kwargs) -> None:
        if obj.is_alias or obj.extra["falcon_docs"].get("markdown"):
            return
        if obj.docstring is None and obj.is_attribute:
            obj.docstring = comment_docstring(obj)
        if obj.docstring is None:
            return
        obj.docstring.value = to_markdown(obj.docstring.value, _resolver(obj))
        obj.extra["falcon_docs"]["markdown"] = True
