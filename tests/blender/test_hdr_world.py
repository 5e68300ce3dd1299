"""Radiance .hdr worlds in Blender: PlateLight's reader agrees with Blender's own loader (on
files written by OpenCV, by Blender's own Radiance writer and with unusual header lines), and
a real .hdr probe is carried through the bake's world maps and lights_from_probe."""
from __future__ import annotations

import cv2
import numpy as np

from bake_scenes import add_sphere, new_scene, probe_renders, read_map
from platelight.addon.exr_io import read_exr
from platelight.addon.hdr_io import read_probe, write_radiance


def _blender_pixels(bpy, path):
    """Float RGB as Blender loads the file, first row on top."""
    image = bpy.data.images.load(str(path))
    w, h = image.size
    px = np.empty(w * h * 4, np.float32)
    image.pixels.foreach_get(px)
    bpy.data.images.remove(image)
    return px.reshape(h, w, 4)[::-1, :, :3]


def _blender_writes_hdr(bpy, exr, out):
    """Blender's own Radiance writer: the EXR's pixels in a float image saved as HDR through
    save_render with the Standard view (Image.save() writes them sRGB-encoded in 5.2:
    measured 7x too bright)."""
    env = read_exr(exr)
    h, w = env.shape[:2]
    image = bpy.data.images.new("to_hdr", w, h, float_buffer=True)
    rgba = np.concatenate([env, np.ones((h, w, 1), np.float32)], axis=-1)[::-1]
    image.pixels.foreach_set(np.ascontiguousarray(rgba).reshape(-1))
    scene = bpy.context.scene
    scene.render.image_settings.file_format = "HDR"
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    image.save_render(str(out), scene=scene)
    bpy.data.images.remove(image)


def test_reader_matches_blenders_loader(bpy_clean, tmp_path, studio_hdris):
    bpy = bpy_clean
    env = read_exr(studio_hdris["courtyard"])
    files = {"opencv": tmp_path / "cv.hdr", "blender": tmp_path / "blender.hdr",
             "unusual header, flat": tmp_path / "odd.hdr"}
    cv2.imwrite(str(files["opencv"]), np.ascontiguousarray(env[..., ::-1]))
    _blender_writes_hdr(bpy, studio_hdris["courtyard"], files["blender"])
    write_radiance(files["unusual header, flat"], env,
                   ["# comment", "EXPOSURE=1.5", "GAMMA=1.0", "PRIMARIES=0.64 0.33 0.30 0.60 0.15 0.06 0.3127 0.329"],
                   rle=False)
    assert files["blender"].read_bytes()[:2] == b"#?"
    for name, path in files.items():
        ours = read_probe(path)
        theirs = _blender_pixels(bpy, path)
        assert ours.shape == theirs.shape, name
        np.testing.assert_array_equal(ours, theirs, err_msg=name)
        rel = np.abs(ours - env) / np.maximum(env, 1e-3)
        assert np.median(rel) < 0.005, name


def test_hdr_world_through_the_bake_and_lights(bpy_clean, tmp_path, studio_hdris):
    """The world's Environment Texture is a .hdr: the bake reads it directly (no render of the
    world) and its world maps equal those of the EXR it was written from; lights_from_probe
    reads it too."""
    bpy = bpy_clean
    from platelight.addon.ibl.maps import MapSettings, compute_maps

    hdr = tmp_path / "sunset.hdr"
    _blender_writes_hdr(bpy, studio_hdris["sunset"], hdr)
    scene = new_scene(bpy, tmp_path, env_exr=hdr, height=32, samples=8)
    add_sphere(bpy, "Probe", (0, 0, 0))
    before = probe_renders()
    assert bpy.ops.platelight.bake_probes(all_objects=True, cull=False) == {"FINISHED"}
    assert probe_renders() == before        # a lone sphere uses the world maps, read from the file
    direct = compute_maps(read_probe(hdr), MapSettings(), which=("diffuse",)).maps["diffuse"]
    np.testing.assert_allclose(read_map(tmp_path, "_world", "diffuse"), direct, rtol=1e-4, atol=1e-6)
    from_exr = compute_maps(read_exr(studio_hdris["sunset"]), MapSettings(), which=("diffuse",)).maps["diffuse"]
    assert np.median(np.abs(direct / from_exr - 1)) < 0.005
    assert bpy.ops.platelight.lights_from_probe(mode="LIGHTS", count=4) == {"FINISHED"}
    suns = [ob for ob in scene.objects if ob.type == "LIGHT"]
    assert len(suns) >= 4 and any(ob.name.endswith("Sun") for ob in suns)
