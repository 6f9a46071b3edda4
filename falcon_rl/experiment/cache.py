"""A folder of finished cells: one JSON file per cell, named by its key, so a killed sweep resumes where
it stopped and a changed cell (any field, or the code version; see :meth:`.cells.Cell.key`) runs alone.

Each file ``<key>.json`` holds

    {"format": "falcon-rl-cell/1", "key": str, "cell": Cell.to_dict(), "version": code_version(),
     "started": ISO-8601 UTC, "finished": ISO-8601 UTC, "result": {"summary": {...}, "seconds": ..., ...}}

written atomically (:func:`falcon_rl.atomic_files.write_atomic`), so a file is either whole or absent.
A file that cannot be read or does not match its cell (not JSON, not UTF-8, another cell, a field of the
wrong type, numbers beyond a float or Python's integer-digit limit, nesting too deep to parse) is
reported with a one-line warning naming it and treated as missing: the cell is recomputed and the file
replaced. Something else at a cell file's name (a folder, say) is refused with a one-line
:class:`CacheEntryError` naming it before any cell runs: the result could not be written there, and
the folder is not this cache's to move or delete.

Files of earlier versions, which kept a cell's locations among its params (and so in its key), are
still read (:meth:`.cells.Cell.legacy`) when a cell has no file under its own key.
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
#: What reading a damaged cell file raises (bad bytes, bad JSON, bad fields, too deep, too large).
_DAMAGED = (OSError, ValueError, KeyError, TypeError, RecursionError, OverflowError)
#: Optional result fields every study's result may hold, and the types they must have when present.
_RESULT_FIELDS = {"status": (str,), "seconds": (int, float, type(None)), "traces": (Mapping,)}


class CacheEntryError(ValueError):
    """Something other than a file stands at a cell file's name (one line, naming it)."""


def checked_result(result: Mapping[str, Any]) -> dict[str, Any]:
    """``result`` (normalized, :func:`.cells.normalize_result`) when its optional fields have their
    types (:data:`_RESULT_FIELDS`), else ValueError naming the field."""
    for name, types in _RESULT_FIELDS.items():
        value = result.get(name)
        if name in result and (isinstance(value, bool) or not isinstance(value, types)):
            raise ValueError(f"result field {name!r} is {type(value).__name__}, not "
                             f"{' or '.join(t.__name__ for t in types)}")
    return dict(result)


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
        or damaged (a one-line warning names the file); :class:`CacheEntryError` when something other
        than a file stands at its name."""
        path = self.path(cell)
        if os.path.lexists(path) and not path.is_file():
            raise CacheEntryError(f"cache entry {path} of {cell.label()} is not a file (a folder?): move "
                                  f"or delete it, the cell's result is written there")
        legacy = cell.legacy()
        if not path.is_file() and legacy.key() != cell.key() and self.path(legacy).is_file():
            return self._read(self.path(legacy), legacy, cell)
        return self._read(path, cell, cell) if path.is_file() else None

    @staticmethod
    def _read(path: Path, stored: Cell, cell: Cell) -> dict[str, Any] | None:
        """The document of ``path`` if it holds ``stored`` (``cell`` or its legacy form), else None
        with a one-line warning."""
        try:
            document = json.loads(path.read_text())
            if not isinstance(document, Mapping) or document.get("format") != CACHE_FORMAT:
                raise ValueError(f"not a {CACHE_FORMAT} document")
            if document.get("key") != stored.key() or Cell.from_dict(document["cell"]) != stored:
                raise ValueError("it holds another cell")
            document = dict(document)
            document["result"] = checked_result(normalize_result(document["result"]))
        except _DAMAGED as error:
            reason = " ".join(str(error).split()) or type(error).__name__
            warnings.warn(f"damaged cache file {path} ({reason}); recomputing {cell.label()}", stacklevel=3)
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


__all__ = ["CACHE_FORMAT", "CacheEntryError", "CellCache", "checked_result", "write_json_atomic"]
