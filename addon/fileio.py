"""Small file helpers shared by the CLI and operators: atomic text writes, writable folders."""
from __future__ import annotations

import contextlib
import json
import os
import tempfile

from .errors import PlateLightError


def ensure_writable_folder(folder: str | os.PathLike) -> str:
    """Create ``folder`` if needed and check that files can be written there."""
    folder = os.path.abspath(os.fspath(folder))
    if os.path.exists(folder) and not os.path.isdir(folder):
        raise PlateLightError(f"Output path exists and is not a folder: {folder}")
    try:
        os.makedirs(folder, exist_ok=True)
    except OSError as exc:
        raise PlateLightError(f"Cannot create output folder {folder}: {exc.strerror}") from None
    if not os.access(folder, os.W_OK | os.X_OK):
        raise PlateLightError(f"Output folder is not writable: {folder}")
    return folder


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, suffix: str = ""):
    """Yield a temporary path in ``path``'s folder; on success it is renamed over ``path`` (a
    reader never sees a half-written file), on any failure it is removed and ``path`` is kept."""
    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix=".tmp-", suffix=suffix, dir=folder)
    os.close(fd)
    try:
        yield tmp
        os.replace(tmp, path)
    except OSError as exc:
        raise PlateLightError(f"Cannot write {path}: {exc.strerror}") from None
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def write_text_atomic(path: str | os.PathLike, text: str) -> None:
    with atomic_path(path) as tmp, open(tmp, "w", encoding="utf-8") as fh:
        fh.write(text)


def write_json_atomic(path: str | os.PathLike, data) -> None:
    write_text_atomic(path, json.dumps(data, indent=1) + "\n")
