"""Crash-safe file writes shared by demonstrations and the example's checkpoints."""
from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

import torch

__all__ = ["atomic_save", "atomic_write"]


def atomic_write(path: str | os.PathLike, write: Callable[[IO[bytes]], Any]) -> Path:
    """Writes ``path`` through ``write(file)`` so that a crash never leaves it half-written.

    The bytes go to a temp file in the same folder, are fsynced, and replace ``path`` with
    ``os.replace`` (atomic on POSIX); the folder is fsynced so the rename survives a power
    loss. On any error the temp file is removed and an existing ``path`` is left intact.

    Examples:
        >>> import tempfile, pathlib
        >>> from torchrl_sail._io import atomic_write
        >>> path = pathlib.Path(tempfile.mkdtemp()) / "a.bin"
        >>> _ = atomic_write(path, lambda f: f.write(b"ok"))
        >>> path.read_bytes()
        b'ok'
    """
    path = Path(path)
    directory = path.parent if str(path.parent) else Path(".")
    fd, tmp = tempfile.mkstemp(dir=directory, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            write(f)
            f.flush()
            os.fsync(f.fileno())
        # mkstemp creates 0600 files; give the result the permissions of a normal file.
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise
    try:  # persist the rename itself; not possible on every platform/filesystem
        dir_fd = os.open(directory, os.O_RDONLY)
    except OSError:
        return path
    try:
        os.fsync(dir_fd)
    except OSError:
        pass
    finally:
        os.close(dir_fd)
    return path


def atomic_save(obj: Any, path: str | os.PathLike) -> Path:
    """``torch.save(obj, path)`` through :func:`atomic_write`."""
    return atomic_write(path, lambda f: torch.save(obj, f))
