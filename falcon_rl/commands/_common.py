"""What every subcommand shares: the bad-input error and the JSON-or-text output convention.

Conventions: ``--json`` prints exactly one JSON document on stdout (messages go to stderr);
exit 0 on success, 2 on bad input (:class:`UsageError`) with a one-line reason on stderr.
"""

from __future__ import annotations

import argparse
import json
from typing import Any


class UsageError(ValueError):
    """Bad user input: printed as one line on stderr, exit code 2."""


def emit(args: argparse.Namespace, document: Any, text: str) -> None:
    """Print ``document`` as JSON with --json, else the human-readable ``text``."""
    if getattr(args, "json", False):
        print(json.dumps(document, indent=2, default=float))
    else:
        print(text)


__all__ = ["UsageError", "emit"]
