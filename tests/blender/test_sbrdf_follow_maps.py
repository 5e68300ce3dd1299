"""Materials follow their probe: an image sequence renders each frame's maps, and a re-bake
(new files + refresh) changes the render without touching the material."""
from __future__ import annotations

import numpy as np

import sbrdf_scene as sc
from platelight.addon.material.params import SBRDFParams

DIFFUSE = SBRDFParams(diffuse_albedo=(1.0, 1.0, 1.0), specular_albedo=(0.0, 0.0, 0.0),
                      glossiness=0.0, fresnel_falloff=0.0)


def _setup(bpy, folder):
    from bl_ext.dev.platelight.node_groups import sbrdf_material as sm

    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    (ob,), _ = sc.setup_scene(bpy, 1, size=24)
    ob.platelight.probe_dir = str(folder)
    sm.apply_sbrdf_material(ob, params=DIFFUSE)
    return sm


def _interior(image):
    return image[..., :3][sc.interior_mask(image[..., 3])]


def test_image_sequence_renders_each_frame(bpy_module, tmp_path):
    bpy = bpy_module
    maps = sc.synthetic_maps()
    for frame in (1, 2, 3):
        sc.write_maps(tmp_path / "seq", {k: v * frame for k, v in maps.items()}, frame=frame)
    _setup(bpy, tmp_path / "seq")
    scene = bpy.context.scene
    frames = {}
    for frame in (1, 3):
        scene.frame_set(frame)
        frames[frame] = _interior(sc.render(bpy, tmp_path / f"f{frame}.exr"))
    assert frames[1].size > 100
    np.testing.assert_allclose(frames[3], 3.0 * frames[1], rtol=1e-5)


def test_rebake_and_refresh_updates_the_render(bpy_module, tmp_path):
    bpy = bpy_module
    maps = sc.synthetic_maps()
    sc.write_maps(tmp_path / "probe", maps)
    sm = _setup(bpy, tmp_path / "probe")
    before = _interior(sc.render(bpy, tmp_path / "a.exr"))
    sc.write_maps(tmp_path / "probe", {k: v * 2.0 for k, v in maps.items()})   # the re-bake
    assert sm.refresh_probe_maps() == 1
    after = _interior(sc.render(bpy, tmp_path / "b.exr"))
    np.testing.assert_allclose(after, 2.0 * before, rtol=1e-5)
