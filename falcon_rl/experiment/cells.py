"""Cells of an experiment: one study x task x airframe x controller x seed x draw (x parameters) each,
the unit that is run, cached and aggregated.

A cell is run by its study's *cell function*, ``function(cell) -> result``, found through
:data:`CELL_FUNCTIONS` (study -> ``"module:attribute"``, imported on first use, so a registry entry costs
nothing until a cell of that study runs). The result is a mapping with at least ``"summary"``
({metric: float}) and anything else JSON-able, or a :class:`~falcon_rl.evaluation.protocols.ProtocolResult`
(its summary, settings, per-episode metrics and time per control step are kept). :func:`run_cell` seeds
Python's ``random``, NumPy's global generator and torch from the cell (:func:`global_seed`) before it
calls the function, and returns the result in its JSON form (non-finite floats read back as NaN) with
the wall time in ``"seconds"``: the same numbers whether the cell ran in this process, in a worker
process or on a Ray worker, and whether it was computed now or read from the cache.

The key of a cell (:meth:`Cell.key`) is the SHA-256 (first 32 hex digits) of the canonical JSON
(sorted keys, no spaces) of

    {"cell": {"study", "task", "airframe", "controller", "seed", "draw", "params"},
     "version": {"falcon_rl": <falcon_rl.__version__>, "commit": <git commit of the checkout or null>}}

so changing any field, the package version or the commit of the package's git checkout (when it is one;
an installed package has none and the commit is null) gives a new key. Uncommitted edits do not change
the key: commit before a sweep whose cache should follow the code.

A cell's ``locations`` (name -> path: where its function finds or puts files, e.g. the folder of the
policies it trains under ``--out``) say where, not what: they are not in the key, nor in the cell's
equality and hash, so the same settings run from another working directory, with ``--out`` typed
absolute or relative, or from a moved folder, read the same cached cells. Versions before locations
existed kept such paths among the params (and so in the key); :meth:`Cell.legacy` is that form, which
the cache still reads.
"""

from __future__ import annotations

import hashlib
import importlib
import json
import math
import random
import sys
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import Any

#: Study -> "module:attribute" of its cell function ``function(cell) -> result`` (imported on first use).
CELL_FUNCTIONS: dict[str, str] = {}

#: Types a parameter value may have (tuples of them too; lists are stored as tuples).
_SCALARS = (str, int, float, bool, type(None))
#: Fields of the cell in its key and its JSON form, in order (its JSON form adds ``locations`` when it has
#: any).
CELL_FIELDS = ("study", "task", "airframe", "controller", "seed", "draw", "params")


def _freeze(value: Any, name: str) -> Any:
    """A hashable, JSON-able parameter value: scalars as they are, lists and tuples as tuples."""
    if isinstance(value, _SCALARS):
        return value
    if isinstance(value, (list, tuple)):
        return tuple(_freeze(v, name) for v in value)
    raise ValueError(f"parameter {name!r}: {type(value).__name__} is not a JSON scalar or a tuple of them")


Params = tuple[tuple[str, Any], ...]


def freeze_params(params: Mapping[str, Any] | Params | None) -> Params:
    """``{name: value}`` (or pairs) -> the sorted, hashable pairs a :class:`Cell` holds."""
    pairs = list(params.items()) if isinstance(params, Mapping) else list(params or ())
    names = [name for name, _ in pairs]
    if any(not isinstance(name, str) for name in names):
        raise ValueError(f"parameter names must be strings, got {names!r}")
    if len(set(names)) != len(names):
        raise ValueError(f"parameter names repeat: {sorted(names)!r}")
    return tuple(sorted((name, _freeze(value, name)) for name, value in pairs))


@dataclass(frozen=True)
class Cell:
    """One run of an experiment. ``params`` are sorted (name, value) pairs (build them from a dict with
    :meth:`make` or :func:`freeze_params`); values are JSON scalars or tuples of them. ``locations``
    (sorted (name, path) pairs) say where the cell's function finds or puts files; they are not part of
    the cell's identity (key, equality, hash; see the module docstring)."""

    study: str
    task: str
    airframe: str
    controller: str
    seed: int
    draw: int = 0
    params: Params = ()
    locations: Params = field(default=(), compare=False)

    def __post_init__(self) -> None:
        for name in ("study", "task", "airframe", "controller"):
            if not isinstance(getattr(self, name), str) or not getattr(self, name):
                raise ValueError(f"cell {name} must be a non-empty string, got {getattr(self, name)!r}")
        for name in ("seed", "draw"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 0:
                raise ValueError(f"cell {name} must be an int >= 0, got {value!r}")
        object.__setattr__(self, "params", freeze_params(self.params))
        object.__setattr__(self, "locations", freeze_params(self.locations))
        for name, value in self.locations:
            if not isinstance(value, str):
                raise ValueError(f"cell location {name!r} must be a path string, got {value!r}")

    @classmethod
    def make(cls, study: str, task: str, airframe: str, controller: str, seed: int, draw: int = 0,
             params: Mapping[str, Any] | None = None, locations: Mapping[str, str] | Params | None = None
             ) -> Cell:
        """A cell with ``params`` (and ``locations``) given as dicts."""
        return cls(study, task, airframe, controller, seed, draw, freeze_params(params),
                   freeze_params(locations))

    @property
    def param_dict(self) -> dict[str, Any]:
        """The parameters as a dict."""
        return dict(self.params)

    def identity(self) -> dict[str, Any]:
        """What the cell computes, the content of its key: the :data:`CELL_FIELDS`, ``params`` as a
        dict."""
        return {name: (self.param_dict if name == "params" else getattr(self, name)) for name in CELL_FIELDS}

    def to_dict(self) -> dict[str, Any]:
        """JSON form: :meth:`identity`, and ``locations`` as a dict when there are any (tuples as lists
        once dumped)."""
        locations = {"locations": dict(self.locations)} if self.locations else {}
        return {**self.identity(), **locations}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Cell:
        """Inverse of :meth:`to_dict` (also after a JSON round trip)."""
        if not isinstance(data, Mapping):
            raise ValueError(f"a cell document is a JSON object, got {type(data).__name__}")
        missing = [name for name in CELL_FIELDS if name not in data and name not in ("draw", "params")]
        if missing:
            raise ValueError(f"cell document lacks {missing}")
        return cls.make(data["study"], data["task"], data["airframe"], data["controller"], data["seed"],
                        data.get("draw", 0), data.get("params") or {}, data.get("locations") or {})

    def legacy(self) -> Cell:
        """The cell as versions before ``locations`` held it: its locations among its params (keyed; the
        form of their cache files, :meth:`key` of this)."""
        return Cell.make(self.study, self.task, self.airframe, self.controller, self.seed, self.draw,
                         {**self.param_dict, **dict(self.locations)})

    def group(self) -> tuple[Any, ...]:
        """The cell without its seed and draw: the replicates of a table entry share it."""
        return (self.study, self.task, self.airframe, self.controller, self.params)

    def label(self) -> str:
        """Short human-readable name, e.g. ``altitude/altitude/navion/LQR seed=0 draw=1 wind=5``."""
        extra = "".join(f" {name}={value}" for name, value in self.params)
        return (f"{self.study}/{self.task}/{self.airframe}/{self.controller} seed={self.seed} "
                f"draw={self.draw}{extra}")

    def key(self, version: Mapping[str, Any] | None = None) -> str:
        """Stable hex hash of the cell and the code version (:func:`code_version` unless given); see the
        module docstring for what goes into it."""
        document = {"cell": self.identity(), "version": dict(code_version() if version is None else version)}
        text = json.dumps(document, sort_keys=True, separators=(",", ":"), allow_nan=False)
        return hashlib.sha256(text.encode()).hexdigest()[:32]


def _git_dir(start: Path) -> Path | None:
    """The git directory of the checkout holding ``start`` (a ``.git`` folder, or the one a worktree's
    ``.git`` file points to); None outside a checkout."""
    for folder in (start, *start.parents):
        dot_git = folder / ".git"
        if dot_git.is_dir():
            return dot_git
        if dot_git.is_file():
            text = dot_git.read_text().strip()
            if text.startswith("gitdir:"):
                target = Path(text[len("gitdir:"):].strip())
                return target if target.is_absolute() else (folder / target).resolve()
            return None
    return None


def git_commit(start: Path | None = None) -> str | None:
    """The commit checked out where the package lives (read from the git files, without running git);
    None when it is not in a checkout or the files cannot be read."""
    try:
        git_dir = _git_dir((start or Path(__file__)).resolve().parent)
        if git_dir is None:
            return None
        head = (git_dir / "HEAD").read_text().strip()
        if not head.startswith("ref:"):
            return head or None
        ref = head[len("ref:"):].strip()
        common = git_dir
        if (git_dir / "commondir").is_file():
            common = (git_dir / (git_dir / "commondir").read_text().strip()).resolve()
        for base in (git_dir, common):
            if (base / ref).is_file():
                return (base / ref).read_text().strip() or None
        packed = common / "packed-refs"
        if packed.is_file():
            for line in packed.read_text().splitlines():
                parts = line.split()
                if len(parts) == 2 and parts[1] == ref:
                    return parts[0]
    except OSError:
        return None
    return None


@lru_cache(maxsize=1)
def code_version() -> dict[str, str | None]:
    """``{"falcon_rl": version, "commit": git commit or None}`` of the running code (read once)."""
    package = sys.modules.get(__name__.split(".")[0])
    version = getattr(package, "__version__", None)
    if version is None:
        from importlib.metadata import PackageNotFoundError
        from importlib.metadata import version as dist_version

        try:
            version = dist_version("falcon-rl")
        except PackageNotFoundError:
            version = "unknown"
    return {"falcon_rl": str(version), "commit": git_commit()}


def register_cell_function(study: str, reference: str) -> None:
    """Register ``reference`` ("module:attribute") as the cell function of ``study``."""
    module, _, attribute = reference.partition(":")
    if not study or not module or not attribute:
        raise ValueError(f"cell function of {study!r} must read 'module:attribute', got {reference!r}")
    CELL_FUNCTIONS[study] = reference


def resolve_function(reference: str) -> Callable[[Cell], Any]:
    """Import ``"module:attribute"`` and return the attribute (dots in it walk into objects)."""
    module, _, attribute = reference.partition(":")
    if not module or not attribute:
        raise ValueError(f"cell function reference must read 'module:attribute', got {reference!r}")
    target: Any = importlib.import_module(module)
    for part in attribute.split("."):
        target = getattr(target, part)
    if not callable(target):
        raise ValueError(f"cell function {reference!r} is not callable")
    return target


def cell_reference(study: str) -> str:
    """The registered "module:attribute" of ``study``'s cell function."""
    if study not in CELL_FUNCTIONS:
        raise ValueError(f"no cell function for study {study!r}; registered: {sorted(CELL_FUNCTIONS)}")
    return CELL_FUNCTIONS[study]


def global_seed(cell: Cell) -> int:
    """The seed of the global generators for ``cell``: NumPy's ``SeedSequence([seed, draw])`` reduced to
    32 bits, so each (seed, draw) pair gets its own stream."""
    import numpy as np

    return int(np.random.SeedSequence([cell.seed, cell.draw]).generate_state(1, np.uint32)[0])


def seed_everything(seed: int) -> None:
    """Seed Python's ``random``, NumPy's global generator and torch (all devices) with ``seed``."""
    import numpy as np
    import torch

    random.seed(seed)
    np.random.seed(seed)
    torch.manual_seed(seed)


def jsonable(value: Any) -> Any:
    """``value`` as plain JSON data: tensors and arrays as (nested) lists, tuples as lists, non-finite
    floats as None, paths and other objects as strings."""
    if isinstance(value, bool) or value is None or isinstance(value, (str, int)):
        return value
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, Mapping):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, set, frozenset)):
        return [jsonable(v) for v in value]
    if hasattr(value, "tolist"):  # torch tensors, numpy arrays and scalars
        return jsonable(value.tolist())
    return str(value)


def _summary_floats(summary: Mapping[str, Any]) -> dict[str, float]:
    """{metric: float}, None (a non-finite value in JSON) read back as NaN."""
    return {str(k): (math.nan if v is None else float(v)) for k, v in summary.items()}


def normalize_result(result: Any) -> dict[str, Any]:
    """A cell function's return value in its cached form: a JSON round trip with the summary as floats
    (NaN where JSON holds null). A ProtocolResult gives summary, settings, per-episode metrics
    ("episodes") and "seconds_per_control_step"."""
    if hasattr(result, "summary") and not isinstance(result, Mapping):  # a ProtocolResult
        result = {"summary": result.summary, "settings": getattr(result, "settings", {}),
                  "episodes": getattr(result, "episodes", {}),
                  "seconds_per_control_step": getattr(result, "seconds_per_control_step", math.nan)}
    if not isinstance(result, Mapping) or not isinstance(result.get("summary"), Mapping):
        raise ValueError(f"a cell function returns a mapping with a 'summary' dict, "
                         f"got {type(result).__name__}")
    data = json.loads(json.dumps(jsonable(result), allow_nan=False))
    data["summary"] = _summary_floats(data["summary"])
    return data


def run_cell(cell: Cell, reference: str | None = None, threads: int = 1) -> dict[str, Any]:
    """Run ``cell`` with its study's cell function (or ``reference``, "module:attribute") on ``threads``
    torch CPU threads (the sweep's ``--threads``; one by default: a cell's networks and batches are small,
    and the sweep's parallelism is its workers), after seeding the global generators from
    :func:`global_seed`; returns the normalized result (see :func:`normalize_result`) with its wall time
    in ``"seconds"``."""
    import torch

    function = resolve_function(reference or cell_reference(cell.study))
    torch.set_num_threads(threads)
    seed_everything(global_seed(cell))
    start = time.perf_counter()
    raw = function(cell)
    seconds = time.perf_counter() - start
    result = normalize_result(raw)
    result["seconds"] = seconds
    return result


__all__ = ["CELL_FIELDS", "CELL_FUNCTIONS", "Cell", "cell_reference", "code_version", "freeze_params",
           "git_commit", "global_seed", "jsonable", "normalize_result", "register_cell_function",
           "resolve_function", "run_cell", "seed_everything"]
