"""Write a derived airframe document as JSON, byte-for-byte reproducible."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any


def to_json(document: dict[str, Any]) -> str:
    """Canonical text: two-space indent, key order as built, trailing newline."""
    return json.dumps(document, indent=2) + "\n"


def write_airframe(document: dict[str, Any], path: str | Path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(to_json(document))
    return path
