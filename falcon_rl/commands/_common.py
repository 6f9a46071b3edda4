"""What every subcommand shares: the bad-input error and the JSON-or-text output convention.

Conventions: ``--json`` prints exactly one JSON document on stdout (messages go to stderr);
exit 0 on success, 2 on bad input (:class:`UsageError`) with a one-line reason on stderr.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import tempfile
import unicodedata
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

from ..atomic_files import TEMPORARY_SUFFIX, temporary_prefix
from ..defaults import BATCH_BACKENDS, DEFAULT_BACKEND

#: Largest integer a count flag accepts (a 400-digit integer is a typo, not a request).
MAX_COUNT = 10**9
#: Longest episode a --seconds flag accepts, s.
MAX_EPISODE_SECONDS = 3600.0
#: Airspeeds the flight model covers, m/s (it is incompressible: below Mach 1 at sea level).
MAX_AIRSPEED = 340.0
#: Heights the atmosphere model covers, m (the ISA tables stop at 20 km).
MAX_HEIGHT = 20_000.0
#: What an output folder must have room for when its command names no files (:func:`output_dir`): a
#: 48-character file name.
ROOM_FOR = ("x" * 48,)
#: Random characters in the name of an atomic write's temporary (``tempfile``'s names).
_RANDOM_CHARACTERS = 8
#: Fallbacks of the system's limits where ``os.pathconf`` cannot tell (bytes; Linux's values).
_PATH_MAX, _NAME_MAX = 4096, 255


class UsageError(ValueError):
    """Bad user input: printed as one line on stderr, exit code 2."""


def emit(args: argparse.Namespace, document: Any, text: str) -> None:
    """Print ``document`` as JSON with --json, else the human-readable ``text``."""
    if getattr(args, "json", False):
        print(json.dumps(document, indent=2, default=float))
    else:
        print(text)


def _shown(text: str, limit: int = 40) -> str:
    """``text`` quoted for a message, cut to ``limit`` characters (a 400-digit value stays one line)."""
    return repr(text) if len(text) <= limit else f"{text[:limit]!r}... ({len(text)} characters)"


def _number(text: str, kind: type, what: str) -> float | int:
    try:
        value = kind(text)
    except (ValueError, OverflowError):
        raise argparse.ArgumentTypeError(f"{_shown(text)} is not {what}") from None
    if kind is float and not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{_shown(text)} is not a finite number")
    if kind is int and abs(value) > MAX_COUNT:
        raise argparse.ArgumentTypeError(f"{_shown(text)} is out of range (at most {MAX_COUNT})")
    return value


def positive_int(text: str) -> int:
    """argparse type: an integer >= 1."""
    value = int(_number(text, int, "an integer"))
    if value < 1:
        raise argparse.ArgumentTypeError(f"{text!r} must be >= 1")
    return value


def nonnegative_int(text: str) -> int:
    """argparse type: an integer >= 0."""
    value = int(_number(text, int, "an integer"))
    if value < 0:
        raise argparse.ArgumentTypeError(f"{text!r} must be >= 0")
    return value


def finite_float(text: str) -> float:
    """argparse type: a finite float."""
    return float(_number(text, float, "a number"))


def positive_float(text: str) -> float:
    """argparse type: a finite float > 0."""
    value = finite_float(text)
    if value <= 0.0:
        raise argparse.ArgumentTypeError(f"{text!r} must be > 0")
    return value


def nonnegative_float(text: str) -> float:
    """argparse type: a finite float >= 0."""
    value = finite_float(text)
    if value < 0.0:
        raise argparse.ArgumentTypeError(f"{text!r} must be >= 0")
    return value


def check_device(device: str, flag: str = "--device") -> str:
    """``device`` if torch can use it here, else UsageError (e.g. cuda on a CPU-only machine)."""
    import torch

    try:
        parsed = torch.device(device)
    except (RuntimeError, ValueError):
        raise UsageError(f"{flag} {device!r} is not a torch device (cpu, cuda, cuda:0, ...)") from None
    if parsed.type == "cuda" and not torch.cuda.is_available():
        raise UsageError(f"{flag} {device!r}: CUDA is not available on this machine (use cpu)")
    if parsed.type not in ("cpu", "cuda"):
        raise UsageError(f"{flag} {device!r}: only cpu and cuda devices are supported")
    if parsed.type == "cuda" and parsed.index is not None and parsed.index >= torch.cuda.device_count():
        raise UsageError(f"{flag} {device!r}: this machine has {torch.cuda.device_count()} CUDA device(s)")
    return device


def _limit(folder: Path, name: str, fallback: int) -> int:
    """``os.pathconf`` of the nearest existing folder at or above ``folder`` (``fallback`` where the
    system cannot tell)."""
    existing = next((p for p in (folder, *folder.parents) if p.is_dir()), Path("/"))
    try:
        return int(os.pathconf(existing, name))
    except (OSError, ValueError, AttributeError):  # no such limit here (or no pathconf: Windows)
        return fallback


def _temporary_of(relative: str) -> Path:
    """The temporary an atomic write of ``relative`` makes (:mod:`falcon_rl.atomic_files`:
    ``.<name>.<random>.tmp``, as long as anything written there)."""
    written = Path(relative)
    return written.with_name(f"{temporary_prefix(written)}{'x' * _RANDOM_CHARACTERS}{TEMPORARY_SUFFIX}")


def check_lengths(path: str | Path, files: Iterable[str], flag: str = "--out") -> None:
    """UsageError unless every file of ``files`` (paths relative to the folder ``path``), as the temporary
    an atomic write makes of it, fits the system's limits: each name at most NAME_MAX bytes, the whole
    absolute path under PATH_MAX (``os.pathconf``; 255 and 4096 on Linux)."""
    folder = Path(os.path.abspath(path))
    name_max, path_max = _limit(folder, "PC_NAME_MAX", _NAME_MAX), _limit(folder, "PC_PATH_MAX", _PATH_MAX)
    shown = _shown(str(path), 80)
    for temporary in map(_temporary_of, files):
        for name in temporary.parts:
            size = len(os.fsencode(name))
            if size > name_max:
                raise UsageError(f"{flag} {shown}: the file name {_shown(name, 80)} written under it is "
                                 f"{size} bytes, more than this file system's limit of {name_max} (NAME_MAX)")
        size = len(os.fsencode(str(folder / temporary)))
        if size >= path_max:
            raise UsageError(f"{flag} {shown} is too long: the files written under it would have paths of "
                             f"{size} bytes, and the system's limit is {path_max - 1} (PATH_MAX {path_max}); "
                             f"shorten it by {size - path_max + 1}")


def output_dir(path: str | Path, flag: str = "--out", files: Iterable[str] = ROOM_FOR) -> Path:
    """``path`` as a directory that exists (created) and is writable, with room for ``files`` (paths
    relative to it: the longest the command writes, :func:`check_lengths`), else UsageError. The
    writability probe is a temporary of a unique name, so checks running at once do not collide."""
    path = Path(path)
    check_lengths(path, files, flag)
    try:
        path.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=path, prefix=".write-test."):
            pass
    except (OSError, ValueError) as exc:  # ValueError: a NUL byte in the path
        reason = getattr(exc, "strerror", None) or exc
        raise UsageError(f"{flag} {str(path)!r} is not a writable directory ({reason})") from None
    return path


def inside(root: Path, name: str, flag: str) -> Path:
    """``root / name`` where ``name`` is one plain file name (no folders, no ``..``), else UsageError:
    outputs stay inside ``--out`` whatever a name given on the command line contains."""
    candidate = Path(name)
    if candidate.name != name or name in ("", ".", ".."):
        raise UsageError(f"{flag} {name!r} must be a plain name, not a path")
    return root / name


def output_file(path: str | Path, flag: str) -> Path:
    """``path`` as a file to write: not a directory, in a writable directory (created), else UsageError."""
    path = Path(path)
    if path.is_dir() or path.name in ("", ".", ".."):
        raise UsageError(f"{flag} {str(path)!r} is a directory, not a file name")
    output_dir(path.parent, flag, (path.name,))
    return path


def bounded_float(low: float, high: float, unit: str = "", closed_low: bool = False
                  ) -> Callable[[str], float]:
    """argparse type: a finite float in (low, high] ([low, high] with ``closed_low``); ``unit`` follows the
    interval in the message."""
    interval = f"{'[' if closed_low else '('}{low:g}, {high:g}]{' ' + unit if unit else ''}"

    def parse(text: str) -> float:
        value = finite_float(text)
        if not ((value >= low if closed_low else value > low) and value <= high):
            raise argparse.ArgumentTypeError(f"{text!r} must be in {interval}")
        return value

    parse.__name__ = "number"  # argparse names the type in some of its messages
    return parse


def bounded_int(low: int, high: int) -> Callable[[str], int]:
    """argparse type: an integer in [low, high]."""

    def parse(text: str) -> int:
        value = int(_number(text, int, "an integer"))
        if not low <= value <= high:
            raise argparse.ArgumentTypeError(f"{text!r} must be an integer in [{low}, {high}]")
        return value

    parse.__name__ = "integer"
    return parse


#: --seconds of the protocols: an episode length in (0, MAX_EPISODE_SECONDS] s.
episode_seconds = bounded_float(0.0, MAX_EPISODE_SECONDS, "s")


def add_flight_arguments(parser: argparse.ArgumentParser, seconds_help: str, out_default: str | None,
                         out_help: str) -> None:
    """The options every command that flies a protocol takes: --seed, --backend, --device, --seconds
    (episode length), --out and --threads (see :func:`use_threads`)."""
    parser.add_argument("--seed", type=nonnegative_int, default=0)
    parser.add_argument("--backend", choices=BATCH_BACKENDS, default=DEFAULT_BACKEND,
                        help="simulator (default warp)")
    parser.add_argument("--device", default="cpu", help="cpu or cuda[:N] (default cpu)")
    parser.add_argument("--seconds", type=episode_seconds, default=None, help=seconds_help)
    parser.add_argument("--out", default=out_default, help=out_help)
    parser.add_argument("--threads", type=bounded_int(1, 4096), default=1,
                        help="torch CPU threads (default 1: the fastest for small networks and batches)")


def use_threads(args: argparse.Namespace) -> None:
    """Set torch's CPU threads to ``args.threads``. One is the default: a policy or planner call on a
    small batch is a string of small operators, and more threads only add synchronisation (on a busy
    2-core machine a 64x64 policy call on 20 envs took 11-30 ms with 2 threads, 0.35 ms with 1)."""
    import torch

    torch.set_num_threads(args.threads)


def comma_list(text: str, flag: str, choices: tuple[str, ...] | None = None) -> list[str]:
    """The non-empty items of a comma list, each one of ``choices`` when given, else UsageError."""
    items = [item.strip() for item in text.split(",") if item.strip()]
    valid = f"; choose from {', '.join(choices)}" if choices is not None else ""
    unknown = sorted(set(items) - set(choices)) if choices is not None else []
    if unknown:
        raise UsageError(f"{flag}: unknown {unknown}{valid}")
    if not items:
        raise UsageError(f"{flag} must be a comma list of at least one name{valid} (got {text!r})")
    return items


def check_policy(name: str, task: str, flag: str = "--controller") -> Path:
    """``name`` as a policy file that flies ``task`` (its own task or one that ``task`` derives from), checked
    before any env is built, else UsageError naming the flag, the file and what is wrong with it."""
    from ..envs.tasks import TASK_SPECS, task_spec
    from ..policies import read_policy

    path = Path(name)
    if "\0" in name or not path.exists():
        raise UsageError(f"{flag} {name!r} is neither a controller of the task nor a policy file")
    try:
        _, meta = read_policy(path)
    except ValueError as exc:  # FileFormatError: one line naming the file and the defect
        raise UsageError(f"{flag}: {exc}") from None
    trained_on = meta.get("task") if isinstance(meta, dict) else None
    spec, parent = task_spec(task), TASK_SPECS.get(str(trained_on))
    if trained_on not in (None, task) and (parent is None or not issubclass(spec.task, parent.task)):
        raise UsageError(f"{flag} {name!r}: a policy of task {trained_on!r} does not fly task {task!r}")
    return path


def check_controller(name: str, task: str, airframe: str, flag: str = "--controller", policy_seed: int = 0
                     ) -> str:
    """The label of controller ``name`` for ``task`` on ``airframe`` (a baseline of the task, ppo, sac or td3
    for the shipped policy of ``policy_seed``, or a policy file that flies the task), else UsageError:
    checked before any env is built."""
    from ..envs.tasks import task_spec
    from ..evaluation.controllers import baseline_names
    from ..policies import ALGORITHMS, shipped_policy

    if name not in ALGORITHMS and policy_seed != 0:
        raise UsageError(f"--policy-seed picks a shipped {'/'.join(ALGORITHMS)} policy; it does not apply to "
                         f"{flag} {name}")
    if name in baseline_names():
        try:
            task_spec(task).controller(name)
        except ValueError as exc:
            raise UsageError(f"{flag}: {exc}") from None
        return name
    if name in ALGORITHMS:
        try:
            shipped_policy(task, airframe, name, policy_seed)
        except ValueError as exc:
            raise UsageError(f"{flag} {name}: {exc}") from None
        return name if policy_seed == 0 else f"{name}_seed{policy_seed}"
    return check_policy(name, task, flag).stem


def printable(text: str) -> str:
    """``text`` with control and format characters (terminal escapes, bidi overrides, newlines, undecodable
    bytes) written as escapes, so that printing it moves no cursor and recolours nothing."""
    return "".join(ch.encode("unicode_escape", "backslashreplace").decode("ascii")
                   if unicodedata.category(ch).startswith("C") else ch for ch in text)


def one_line(message: object) -> str:
    """The message of an error (or its type when it has none) as one printable line."""
    text = " ".join(str(message).split()) if str(message).strip() else type(message).__name__
    return printable(text)


__all__ = [
    "MAX_AIRSPEED",
    "MAX_COUNT",
    "MAX_EPISODE_SECONDS",
    "MAX_HEIGHT",
    "UsageError",
    "add_flight_arguments",
    "bounded_float",
    "bounded_int",
    "check_controller",
    "check_device",
    "check_lengths",
    "check_policy",
    "comma_list",
    "emit",
    "episode_seconds",
    "finite_float",
    "inside",
    "nonnegative_float",
    "nonnegative_int",
    "one_line",
    "output_dir",
    "output_file",
    "positive_float",
    "positive_int",
    "printable",
    "use_threads",
]
