"""Files written so that a crash cannot leave half of one: :func:`atomic_write`, and
:func:`check_writable` to say before any work is done that a file cannot be written there.

A low layer (it imports only :mod:`akarm.errors`): telemetry, recordings, plots, robot files and
the CLI's output files all write through it.
"""

from __future__ import annotations

import io
import os
import tempfile
from collections.abc import Callable
from pathlib import Path

from akarm.errors import RecordingError

__all__ = ["atomic_write", "check_writable"]


def check_writable(path: str | os.PathLike[str]) -> Path:
    """``path`` as a Path if a file can be written there (before anything is done that the file is for).

    Raises:
        RecordingError: it is a directory, or its directory cannot be created or written; the
            message says which and what to do.
    """
    target = Path(path)
    if target.is_dir():
        raise RecordingError(f"{target} is a directory, not a file", fix="give a file name, e.g. out/run.csv")
    parent = target.parent if str(target.parent) else Path(".")
    existing = parent
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if not existing.is_dir():
        raise RecordingError(f"cannot create directory {parent}: {existing} is not a directory",
                             fix="choose a path whose directories can exist")
    if not os.access(existing, os.W_OK | os.X_OK) or (target.exists() and not os.access(target, os.W_OK)):
        raise RecordingError(f"cannot write {target}: permission denied", fix="choose a directory you can write to")
    return target


def atomic_write(path: str | os.PathLike[str], write: Callable[[io.BufferedWriter], object]) -> Path:
    """Write a file through ``write(fileobj)`` to a temporary name beside it, then rename it into place.

    Raises:
        RecordingError: the file cannot be written (a directory, no permission, a full disk); no
            half file and no temporary file is left.
    """
    target = check_writable(path)
    tmp: str | None = None
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600; give the file the permissions open() would
        with os.fdopen(fd, "wb") as f:
            write(f)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, target)
    except OSError as e:
        if tmp is not None:
            Path(tmp).unlink(missing_ok=True)
        raise RecordingError(f"cannot write {target}: {e.strerror or e}",
                             fix="check the path, its permissions and the free disk space") from None
    except BaseException:
        if tmp is not None:
            Path(tmp).unlink(missing_ok=True)
        raise
    return target
