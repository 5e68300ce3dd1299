"""Headless Blender inside this Python process: the ONE place that imports bpy for the command-line
drivers (bake, render, demo) and the test fixtures (tests/conftest.py).

bpy is imported with a throw-away user profile (so an installed copy of PlateLight or the user's
own preferences cannot interfere), removed when the process exits."""
from __future__ import annotations

import atexit
import contextlib
import os
import pathlib
import shutil
import sys
import tempfile

from ..addon.errors import PlateLightError

# The extension's module name when enabled from a checkout (the repository "dev", as tests use it).
EXT_MODULE = "bl_ext.dev.platelight"
BLEND_MAGICS = (b"BLENDER", b"\x28\xb5\x2f\xfd", b"\x1f\x8b")   # plain, zstd, gzip
PACKAGE_DIR = pathlib.Path(__file__).resolve().parents[1]

_profile = None


def profile_dir() -> str | None:
    """The throw-away user profile of this process (None when bpy was imported elsewhere)."""
    return _profile


def import_bpy():
    """bpy, imported once per process with a temporary user profile that is removed at exit."""
    global _profile
    if "bpy" not in sys.modules:
        _profile = tempfile.mkdtemp(prefix="platelight-profile-")
        os.environ["BLENDER_USER_RESOURCES"] = _profile
        atexit.register(shutil.rmtree, _profile, ignore_errors=True)
    import bpy

    return bpy


def blender_with_extension(package_dir=PACKAGE_DIR):
    """bpy with the package at ``package_dir`` enabled as the extension ``bl_ext.dev.platelight``
    (a "dev" extension repository inside the temporary profile links to it)."""
    bpy = import_bpy()
    if EXT_MODULE not in bpy.context.preferences.addons:
        repo_dir = pathlib.Path(_profile or _own_temp("platelight-repo-")) / "dev_repo"
        repo_dir.mkdir(parents=True, exist_ok=True)
        link = repo_dir / "platelight"
        if not link.exists():
            link.symlink_to(pathlib.Path(package_dir).resolve(), target_is_directory=True)
        repos = bpy.context.preferences.extensions.repos
        if "dev" not in [r.module for r in repos]:
            repos.new(name="dev", module="dev", custom_directory=str(repo_dir), source="USER")
        bpy.ops.preferences.addon_enable(module=EXT_MODULE)
    if EXT_MODULE not in bpy.context.preferences.addons:
        raise PlateLightError("Could not enable the PlateLight extension inside Blender.")
    return bpy


def _own_temp(prefix):
    path = tempfile.mkdtemp(prefix=prefix)
    atexit.register(shutil.rmtree, path, ignore_errors=True)
    return path


def check_blend(path):
    """Raise PlateLightError unless ``path`` is an existing .blend file (plain or compressed)."""
    if not os.path.isfile(path):
        raise PlateLightError(f"File not found: {path}")
    with open(path, "rb") as fh:
        head = fh.read(7)
    if not any(head.startswith(m) for m in BLEND_MAGICS):
        raise PlateLightError(f"Not a .blend file: {path}")


def open_blend(bpy, path):
    """Open ``path`` in Blender (its log on stderr); Blender's refusal becomes a PlateLightError."""
    try:
        with stdout_to_stderr():
            bpy.ops.wm.open_mainfile(filepath=path, load_ui=False)
    except RuntimeError as exc:
        raise PlateLightError(f"Blender cannot open {path}: {str(exc).strip().splitlines()[-1]}") from None


@contextlib.contextmanager
def stdout_to_stderr():
    """Send what C code prints on stdout (Cycles' 'Saved: ...' lines) to stderr for a while."""
    sys.stdout.flush()
    saved = os.dup(1)
    try:
        os.dup2(2, 1)
        yield
    finally:
        sys.stdout.flush()
        os.dup2(saved, 1)
        os.close(saved)
