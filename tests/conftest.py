"""Shared fixtures. Blender tests run in this same process: bpy is imported once, with a
throw-away user profile, and the extension is enabled from this checkout (design.md)."""
from __future__ import annotations

import atexit
import os
import shutil
import pathlib
import sys
import tempfile

import pytest

from support import EXT_MODULE, REPO

_profile = None


def pytest_collection_modifyitems(config, items):
    for item in items:
        if "tests/blender/" in str(item.fspath).replace(os.sep, "/"):
            item.add_marker(pytest.mark.blender)


def _import_bpy_with_extension():
    """Import bpy with a temporary user profile and enable the extension from the checkout."""
    global _profile
    if "bpy" not in sys.modules:
        _profile = tempfile.mkdtemp(prefix="platelight-profile-")
        os.environ["BLENDER_USER_RESOURCES"] = _profile
        atexit.register(shutil.rmtree, _profile, ignore_errors=True)
    import bpy

    if EXT_MODULE not in bpy.context.preferences.addons:
        repo_dir = pathlib.Path(_profile or tempfile.mkdtemp()) / "dev_repo"
        repo_dir.mkdir(parents=True, exist_ok=True)
        link = repo_dir / "platelight"
        if not link.exists():
            link.symlink_to(REPO, target_is_directory=True)
        repos = bpy.context.preferences.extensions.repos
        if "dev" not in [r.module for r in repos]:
            repos.new(name="dev", module="dev", custom_directory=str(repo_dir), source="USER")
        bpy.ops.preferences.addon_enable(module=EXT_MODULE)
    return bpy


@pytest.fixture(scope="session")
def bpy_module():
    """The bpy module with PlateLight enabled."""
    return _import_bpy_with_extension()


@pytest.fixture
def bpy_clean(bpy_module):
    """A fresh empty scene for each test (the extension stays enabled)."""
    bpy = bpy_module
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    if EXT_MODULE not in bpy.context.preferences.addons:
        bpy.ops.preferences.addon_enable(module=EXT_MODULE)
    return bpy


@pytest.fixture(scope="session")
def studio_hdris(bpy_module):
    """Paths of the eight CC0 HDRIs that ship inside the bpy wheel."""
    folder = pathlib.Path(bpy_module.utils.system_resource("DATAFILES", path="studiolights/world"))
    return {p.stem: p for p in sorted(folder.glob("*.exr"))}
