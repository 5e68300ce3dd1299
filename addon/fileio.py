"""Small file helpers shared by the CLI, the drivers and operators: writable folders, and whole
files only: every file is written under a hidden temporary name in its own folder and renamed into
place (one rename on the same file system), so a reader or a killed job never sees half of it."""
from __future__ import annotations

import contextlib
import glob
import json
import os

from .errors import PlateLightError

PARTIAL = ".partial-"


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


def read_magic(path: str | os.PathLike, kind: str, size: int = 4) -> bytes:
    """The first ``size`` bytes of an existing file; a missing path or a folder is one sentence
    (``kind`` names what was expected, e.g. "an EXR file")."""
    path = os.fspath(path)
    if not os.path.exists(path):
        raise PlateLightError(f"File not found: {path}")
    if os.path.isdir(path):
        raise PlateLightError(f"Expected {kind} but got a folder: {path}")
    with open(path, "rb") as fh:
        return fh.read(size)


def temp_path(final: str | os.PathLike) -> str:
    """A hidden name beside ``final`` (``.NAME.partial-PID.EXT``: the rename never crosses file
    systems, a glob of NAME_*.EXT never sees it, the extension tells writers the format), unique
    to this process."""
    folder, base = os.path.split(os.fspath(final))
    stem, ext = os.path.splitext(base)
    return os.path.join(folder, f".{stem}{PARTIAL}{os.getpid()}{ext}")


def stale_temps(final: str | os.PathLike) -> list[str]:
    """Temporary files left for ``final`` by earlier, interrupted processes."""
    folder, base = os.path.split(os.fspath(final))
    stem, ext = os.path.splitext(base)
    return glob.glob(os.path.join(glob.escape(folder), f".{glob.escape(stem)}{PARTIAL}*{ext}"))


def _fsync(path, directory=False):
    fd = os.open(path, os.O_RDONLY | (os.O_DIRECTORY if directory else 0))
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def replace_file(tmp: str, final: str, durable: bool = False) -> None:
    """Rename the finished ``tmp`` over ``final``; ``durable`` flushes the file to disk first and
    the folder's entry after, so a machine that dies right then keeps the old or the new file."""
    if durable:
        _fsync(tmp)
    os.replace(tmp, final)
    if durable:
        _fsync(os.path.dirname(os.path.abspath(final)), directory=True)


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike, durable: bool = False):
    """Yield a temporary path beside ``path`` (temp_path); on success it is renamed over ``path``,
    on any failure it is removed and ``path`` is kept."""
    path = os.fspath(path)
    tmp = temp_path(os.path.abspath(path))
    try:
        yield tmp
        replace_file(tmp, path, durable)
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


def remove_if_present(path: str | os.PathLike) -> None:
    """Remove a file the product wrote and no longer wants; a file already gone is fine."""
    try:
        os.remove(path)
    except FileNotFoundError:
        pass
