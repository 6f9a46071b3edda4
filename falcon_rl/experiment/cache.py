"""A folder of finished cells: one JSON file per cell, named by its key, so a killed sweep resumes where
it stopped and a changed cell (any field, or the code version; see :meth:`.cells.Cell.key`) runs alone.

Each file ``<key>.json`` holds

    {"format": "falcon-rl-cell/1", "key": str, "cell": Cell.to_dict(), "version": code_version(),
     "started": ISO-8601 UTC, "finished": ISO-8601 UTC, "result": {"summary": {...}, "seconds": ..., ...}}

written atomically (:func:`falcon_rl.atomic_files.write_atomic`), so a file is either whole or absent.
A file that cannot be read or does not match its cell is reported with a warning and treated as
missing: the cell is recomputed and the file replaced.
"""

from __future__ import annotations

import json
import os
import time
import warnings
from collections.abc import Iterable, Iterator, Mapping
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

from ..atomic_files import write_atomic
from .cells import Cell, code_version, jsonable, normalize_result

CACHE_FORMAT = "falcon-rl-cell/1"


def _iso(seconds: float) -> str:
    return datetime.fromtimestamp(seconds, tz=timezone.utc).isoformat(timespec="seconds")


def write_json_atomic(path: Path, document: Any) -> Path:
    """Write ``document`` (made JSON-able, non-finite floats as null) to ``path`` atomically
    (:func:`falcon_rl.atomic_files.write_atomic`)."""
    return write_atomic(path, json.dumps(jsonable(document), indent=1, allow_nan=False) + "\n")


class CellCache:
    """Finished cells under ``folder`` (created on first write); see the module docstring."""

    def __init__(self, folder: str | os.PathLike[str]):
        self.folder = Path(folder)
        if self.folder.exists() and not self.folder.is_dir():
            raise ValueError(f"cache folder {self.folder} is a file")

    def path(self, cell: Cell) -> Path:
        """The file of ``cell``."""
        return self.folder / f"{cell.key()}.json"

    def entry(self, cell: Cell) -> dict[str, Any] | None:
        """The whole cached document of ``cell`` (result, version, timestamps), or None when it is absent
        or damaged (a warning says which)."""
        path = self.path(cell)
        if not path.is_file():
            return None
        try:
            document = json.loads(path.read_text())
            if not isinstance(document, Mapping) or document.get("format") != CACHE_FORMAT:
                raise ValueError(f"not a {CACHE_FORMAT} document")
            if document.get("key") != cell.key() or Cell.from_dict(document["cell"]) != cell:
                raise ValueError("it holds another cell")
            document = dict(document)
            document["result"] = normalize_result(document["result"])
        except (OSError, ValueError, KeyError, TypeError) as error:
            warnings.warn(f"damaged cache file {path} ({error}); recomputing {cell.label()}", stacklevel=2)
            return None
        return document

    def get(self, cell: Cell) -> dict[str, Any] | None:
        """The cached result of ``cell``, or None when it has to run (absent or damaged)."""
        document = self.entry(cell)
        return None if document is None else document["result"]

    def put(self, cell: Cell, result: Mapping[str, Any], started: float | None = None) -> Path:
        """Store ``result`` of ``cell`` (``started``: epoch seconds, else now minus its "seconds")."""
        finished = time.time()
        if started is None:
            seconds = result.get("seconds")
            started = finished - (float(seconds) if isinstance(seconds, (int, float)) else 0.0)
        document = {"format": CACHE_FORMAT, "key": cell.key(), "cell": cell.to_dict(),
                    "version": code_version(), "started": _iso(started), "finished": _iso(finished),
                    "result": dict(result)}
        return write_json_atomic(self.path(cell), document)

    def finished(self, cells: Iterable[Cell]) -> set[Cell]:
        """The cells of ``cells`` with a readable cached result."""
        return {cell for cell in cells if self.entry(cell) is not None}

    def __contains__(self, cell: object) -> bool:
        return isinstance(cell, Cell) and self.entry(cell) is not None

    def __iter__(self) -> Iterator[Path]:
        """The cell files in the folder (any code version), sorted."""
        return iter(sorted(self.folder.glob("*.json")) if self.folder.is_dir() else [])


__all__ = ["CACHE_FORMAT", "CellCache", "write_json_atomic"]
