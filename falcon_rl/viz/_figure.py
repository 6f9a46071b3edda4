"""Writing a finished matplotlib figure: the one place every figure of ``falcon_rl.viz`` is saved."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

from ..atomic_files import serialized, write_atomic


def save_figure(fig: plt.Figure, path: str | Path, dpi: int = 110) -> Path:
    """Lay out ``fig``, write it to ``path`` atomically (the format from its suffix, PNG without one;
    parent folders created; :func:`falcon_rl.atomic_files.write_atomic`: a full disk leaves no partial
    image) and close it."""
    path = Path(path)
    image_format = path.suffix.lstrip(".").lower() or "png"
    try:
        fig.tight_layout()
        write_atomic(path, serialized(lambda stream: fig.savefig(stream, format=image_format, dpi=dpi)))
    finally:
        plt.close(fig)
    return path
