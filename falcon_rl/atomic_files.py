"""Files written whole or not at all: one place for every output the package writes atomically.

:func:`write_atomic` writes the bytes (or text) to a temporary file of a unique name in the target's
folder (``.<name>.<random>.tmp``, so two writers of the same file never share a temporary), flushes and
syncs it, gives it the permissions of an ordinary new file (``0o666`` less the umask, as ``open`` would:
``tempfile`` alone would leave ``0o600``) and moves it over the target with ``os.replace`` (atomic on
POSIX). Any failure on the way, a full disk included, removes the temporary and re-raises: the target
keeps its earlier content, and no ``.tmp`` file is left behind.

Serialisers that write to a file object (``torch.save``, ``torch.jit.save``) serialise to memory first
(:func:`serialized`), so that a full disk is a Python ``OSError`` raised by the write here, never an
abort inside a C++ writer.
"""

from __future__ import annotations

import glob
import io
import os
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import BinaryIO

#: Suffix of every temporary file :func:`write_atomic` makes.
TEMPORARY_SUFFIX = ".tmp"


def default_file_mode() -> int:
    """The permission bits ``open(path, "w")`` gives a new file here: ``0o666`` less the umask."""
    mask = os.umask(0)
    os.umask(mask)
    return 0o666 & ~mask


def temporary_prefix(path: str | os.PathLike[str]) -> str:
    """The name prefix of :func:`write_atomic`'s temporaries for ``path`` (``.<name>.``)."""
    return f".{Path(path).name}."


def write_atomic(path: str | os.PathLike[str], data: bytes | str) -> Path:
    """Write ``data`` (text is UTF-8 encoded) to ``path`` atomically (see the module docstring); the
    folder is created when missing. Returns ``path``; raises the ``OSError`` of a failed write (full
    disk, no permission; named after ``path`` when the system named no file) after removing the
    temporary."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    payload = data.encode() if isinstance(data, str) else bytes(data)
    handle, temporary = tempfile.mkstemp(dir=path.parent, prefix=temporary_prefix(path),
                                         suffix=TEMPORARY_SUFFIX)
    try:
        with os.fdopen(handle, "wb") as stream:
            stream.write(payload)
            stream.flush()
            os.fsync(stream.fileno())
        os.chmod(temporary, default_file_mode())
        os.replace(temporary, path)
    except OSError as error:
        Path(temporary).unlink(missing_ok=True)
        if error.filename is None:  # a write to the descriptor: name the file it was for
            raise OSError(error.errno, error.strerror, str(path)) from error
        raise
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise
    return path


def serialized(save: Callable[[BinaryIO], object]) -> bytes:
    """The bytes ``save(buffer)`` writes to an in-memory buffer (e.g. ``lambda f: torch.save(obj, f)``)."""
    buffer = io.BytesIO()
    save(buffer)
    return buffer.getvalue()


def remove_temporaries(path: str | os.PathLike[str]) -> list[Path]:
    """Remove the temporaries that writers of ``path`` killed mid-write left in its folder (and the
    fixed ``<name>.tmp`` of earlier versions); returns what was removed. Call it only while no other
    process writes ``path`` (e.g. under the run folder's lock)."""
    path = Path(path)
    if not path.parent.is_dir():
        return []
    found = [*path.parent.glob(f"{glob.escape(temporary_prefix(path))}*{TEMPORARY_SUFFIX}"),
             path.with_name(path.name + TEMPORARY_SUFFIX)]
    removed = []
    for candidate in found:
        if candidate.is_file() or candidate.is_symlink():
            candidate.unlink(missing_ok=True)
            removed.append(candidate)
    return removed


__all__ = ["TEMPORARY_SUFFIX", "default_file_mode", "remove_temporaries", "serialized", "temporary_prefix",
           "write_atomic"]
