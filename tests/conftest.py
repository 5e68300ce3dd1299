"""Shared fixtures. Blender tests run in this same process: bpy is imported once, with a
throw-away user profile, and the extension is enabled from this checkout (design.md) by the
package's own headless starter (drivers/headless.py), as the command-line drivers do."""
from __future__ import annotations

import os
import pathlib

import pytest

from support import EXT_MODULE, REPO
from platelight.drivers import headless


def pytest_collection_modifyitems(config, items):
    for item in items:
        if "tests/blender/" in str(item.fspath).replace(os.sep, "/"):
            item.add_marker(pytest.mark.blender)


def _import_bpy_with_extension():
    """bpy with the extension enabled from this checkout (benchmarks call it too)."""
    return headless.blender_with_extension(REPO)


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
