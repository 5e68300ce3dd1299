"""The extension installs, registers and unregisters cleanly, twice."""
import pytest

from support import EXT_MODULE


def test_enable_disable_twice(bpy_clean):
    bpy = bpy_clean
    for _ in range(2):
        bpy.ops.preferences.addon_disable(module=EXT_MODULE)
        assert EXT_MODULE not in bpy.context.preferences.addons
        assert not hasattr(bpy.types.Object, "platelight")
        bpy.ops.preferences.addon_enable(module=EXT_MODULE)
        assert EXT_MODULE in bpy.context.preferences.addons
        assert hasattr(bpy.types.Object, "platelight")
    ob = bpy.data.objects.new("Empty", None)
    ob.platelight.phantom = True
    assert ob.platelight.phantom
    assert bpy.context.scene.platelight.probe_height == 64
