"""Probes sized to the object on screen (issue 11): a mirror's probe and specular map at twice its
width in pixels, a matte object's at Probe Height; a cache that follows the size; the setting off."""
from __future__ import annotations

import json

from bake_scenes import add_plane, add_sphere, maps_folder, material, new_scene, probe_renders, read_map
from platelight.addon.exr_io import read_exr
from platelight.addon.ibl import distance as dm


def bake(bpy):
    assert bpy.ops.platelight.bake_probes(all_objects=True) == {"FINISHED"}


def probe_size(tmp_path, name):
    return json.loads((maps_folder(tmp_path, name) / "bake.json").read_text())["probe_size"]


def test_mirror_probe_follows_its_size_on_screen_and_matte_keeps_probe_height(bpy_clean, tmp_path):
    bpy = bpy_clean
    scene = new_scene(bpy, tmp_path, world_color=(0.6, 0.7, 0.8), height=32, samples=4)
    scene.render.resolution_x, scene.render.resolution_y = 320, 180
    mirror = add_sphere(bpy, "Mirror", (0, 0, 0), radius=0.5)
    chrome = material(bpy, "Chrome", (0.9, 0.9, 0.9))
    chrome.node_tree.nodes["Principled BSDF"].inputs["Roughness"].default_value = 0.0
    chrome.node_tree.nodes["Principled BSDF"].inputs["Metallic"].default_value = 1.0
    mirror.data.materials.append(chrome)
    add_sphere(bpy, "Matte", (1.5, 0, 0), radius=0.5, color=(0.5, 0.5, 0.5)).platelight.enabled = True
    add_plane(bpy, "Floor", (0, 0, -0.5), size=20, color=(0.4, 0.4, 0.4), phantom=True)

    # 50 mm on a 36 mm sensor, 320 px wide: f = 444 px; the mirror 10 m away is ~45 px across,
    # so its probe is 2 x 45 -> 128 px high; the matte sphere keeps Probe Height (32).
    bake(bpy)
    assert probe_size(tmp_path, "Mirror") == [256, 128]
    assert probe_size(tmp_path, "Matte") == [64, 32]
    assert read_map(tmp_path, "Mirror", "specular").shape == (128, 256, 3)
    distance = read_exr(maps_folder(tmp_path, "Mirror") / dm.distance_filename(), "RGB")
    assert distance.shape[:2] == (512, 1024)      # 4x the probe, as at Probe Height

    renders = probe_renders()
    bake(bpy)
    assert probe_renders() == renders, "an unchanged scene must reuse its probes"

    # Twice as close: ~100 px across -> 256; only the mirror's probe depends on the camera.
    scene.camera.location.y = -5.0
    bake(bpy)
    assert probe_renders() == renders + 2           # its panorama, and the layer behind the matte ball
    assert probe_size(tmp_path, "Mirror") == [512, 256]
    assert read_map(tmp_path, "Mirror", "specular").shape == (256, 512, 3)

    scene.platelight.probe_max_height = 64          # the cap wins
    bake(bpy)
    assert probe_size(tmp_path, "Mirror") == [128, 64]
    scene.platelight.probe_auto_size = False        # off: Probe Height for every object
    bake(bpy)
    assert probe_size(tmp_path, "Mirror") == [64, 32]
    assert scene.render.resolution_x == 320 and scene.render.resolution_y == 180
