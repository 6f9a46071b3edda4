"""What every subcommand shares: the bad-input error and the JSON-or-text output convention.

Conventions: ``--json`` prints exactly one JSON document on stdout (messages go to stderr);
exit 0 on success, 2 on bad input (:class:`UsageError`) with a one-line reason on stderr.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any

#: Largest integer a count flag accepts (a 400-digit integer is a typo, not a request).
MAX_COUNT = 10**9


class UsageError(ValueError):
    """Bad user input: printed as one line on stderr, exit code 2."""


def emit(args: argparse.Namespace, document: Any, text: str) -> None:
    """Print ``document`` as JSON with --json, else the human-readable ``text``."""
    if getattr(args, "json", False):
        print(json.dumps(document, indent=2, default=float))
    else:
        print(text)


def _number(text: str, kind: type, what: str) -> float | int:
    try:
        value = kind(text)
    except (ValueError, OverflowError):
        raise argparse.ArgumentTypeError(f"{text!r} is not {what}") from None
    if kind is float and not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text!r} is not a finite number")
    if kind is int and abs(value) > MAX_COUNT:
        raise argparse.ArgumentTypeError(f"{text!r} is out of range (at most {MAX_COUNT})")
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
    return device


def output_dir(path: str | Path, flag: str = "--out") -> Path:
    """``path`` as a directory that exists (created) and is writable, else UsageError."""
    path = Path(path)
    try:
        path.mkdir(parents=True, exist_ok=True)
        probe = path / ".write-test"
        probe.write_bytes(b"")
        probe.unlink()
    except OSError as exc:
        reason = exc.strerror or exc
        raise UsageError(f"{flag} {str(path)!r} is not a writable directory ({reason})") from None
    return path


def inside(root: Path, name: str, flag: str) -> Path:
    """``root / name`` where ``name`` is one plain file name (no folders, no ``..``), else UsageError:
    outputs stay inside ``--out`` whatever a name given on the command line contains."""
    candidate = Path(name)
    if candidate.name != name or name in ("", ".", ".."):
        raise UsageError(f"{flag} {name!r} must be a plain name, not a path")
    return root / name


__all__ = ["MAX_COUNT", "UsageError", "check_device", "emit", "finite_float", "inside", "nonnegative_float",
           "nonnegative_int", "output_dir", "positive_float", "positive_int"]
