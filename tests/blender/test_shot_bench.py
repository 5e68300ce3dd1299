"""The shot benchmark measures what users do: its shadow catcher is the one the docs describe,
and its PlateLight route bakes in the user's order, so the bakes see the plate on the phantoms."""
import ast
import math
import os
import re
import sys

import numpy as np
import pytest

import support
from support import compat
from platelight.addon.exr_io import read_exr, write_exr

sys.path.insert(0, str(support.REPO / "tests" / "bench"))


def documented_catcher_settings():
    """The table under docs/compositing.md's "Cycles' shadow catcher, set up well"."""
    text = (support.REPO / "docs" / "compositing.md").read_text()
    section = text.split("### Cycles' shadow catcher, set up well", 1)[1].split("\n###", 1)[0]
    rows = re.findall(r"^\| `([^`]+)` \| `([^`]+)` \|$", section, re.M)
    assert rows, "the docs' catcher table is missing"
    settings = {}
    for path, value in rows:
        try:
            settings[path] = ast.literal_eval(value)
        except (ValueError, SyntaxError):
            settings[path] = value                  # an enum's identifier
    return settings


def test_the_benchmarks_catcher_is_set_up_as_the_docs_say(bpy_clean):
    import bench_shot
    import shot_catcher

    documented = documented_catcher_settings()
    assert documented == shot_catcher.CATCHER_SETTINGS
    scene, cg, phantoms = bench_shot.build(bpy_clean, bench_shot.SCENES["city, grey floor, mirror + box"])
    shot_catcher.setup_catcher(scene, phantoms, samples=64)
    for path, value in documented.items():
        owner, attribute = shot_catcher.resolve(scene, path)
        assert getattr(owner, attribute) == pytest.approx(value) if isinstance(value, float) \
            else getattr(owner, attribute) == value, path
    assert scene.cycles.samples == 64
    assert all(ob.is_shadow_catcher for ob in phantoms) and not any(ob.is_shadow_catcher for ob in cg)


def _scene_over_a_red_plate(bpy, tmp_path):
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = 64, 48
    world = compat().new_world("Sky")
    compat().node_tree(world).nodes["Background"].inputs[0].default_value = (1.0, 1.0, 1.0, 1.0)
    scene.world = world
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(cam)
    scene.camera = cam
    cam.location, cam.rotation_euler = (0.0, -4.0, 3.0), (math.radians(55), 0.0, 0.0)
    mesh = bpy.data.meshes.new("Floor")
    mesh.from_pydata([(-50, -50, 0), (50, -50, 0), (50, 50, 0), (-50, 50, 0)], [], [(0, 1, 2, 3)])
    material = compat().new_material("Grey floor")
    material.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (0.45, 0.45, 0.45, 1)
    mesh.materials.append(material)
    floor = bpy.data.objects.new("Floor", mesh)
    scene.collection.objects.link(floor)
    floor.platelight.phantom = True
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.5, location=(0.0, 0.0, 0.7), segments=16, ring_count=8)
    sphere = bpy.context.object
    sphere.platelight.enabled = True
    scene.platelight.probe_height = 16
    scene.platelight.probe_samples = 4
    scene.platelight.maps_dir = str(tmp_path / "maps")
    write_exr(tmp_path / "plate.exr", np.tile(np.float32([0.5, 0.08, 0.08]), (48, 64, 1)))
    return scene, sphere


@pytest.mark.parametrize("surface", ["PLATE", "MATERIAL"])
def test_the_bakes_after_the_plate_see_the_plate_on_the_phantoms(bpy_clean, tmp_path, surface):
    """The benchmark's order (plate, Apply SBRDF, Bake Probes): the probe of a sphere over a grey
    floor filmed red sees the floor red; with the phantoms' own materials asked for, grey."""
    bpy = bpy_clean
    scene, sphere = _scene_over_a_red_plate(bpy, tmp_path)
    scene.platelight.phantom_surface = surface
    assert bpy.ops.platelight.setup_plate(filepath=str(tmp_path / "plate.exr")) == {"FINISHED"}
    bpy.context.view_layer.objects.active = sphere
    assert bpy.ops.platelight.apply_sbrdf(preset="NONE") == {"FINISHED"}
    assert bpy.ops.platelight.bake_probes(all_objects=True, cull=False) == {"FINISHED"}
    diffuse = read_exr(os.path.join(bpy.path.abspath(sphere.platelight.probe_dir), "diffuse.exr"))
    below = diffuse[-max(1, diffuse.shape[0] // 8):].reshape(-1, 3).mean(axis=0)   # facing the floor
    red_over_green = below[0] / below[1]
    if surface == "PLATE":
        assert red_over_green > 2.0, below
    else:
        assert red_over_green < 1.2, below


def test_the_catchers_stand_in_colour_is_matched_to_the_plate(bpy_clean, tmp_path):
    """The artist's guess: the grey stand-in, rendered, scaled to the plate; a floor filmed red
    under a white sky gets a red colour of about the plate's value (the sky lights it fully)."""
    import bench_shot
    import shot_catcher

    bpy = bpy_clean
    scene, sphere = _scene_over_a_red_plate(bpy, tmp_path)
    scene.render.engine = "CYCLES"
    scene.render.resolution_x, scene.render.resolution_y = 128, 96
    floor = scene.objects["Floor"]
    shot_catcher.setup_catcher(scene, [floor], samples=8)
    plate = np.tile(np.float32([0.5, 0.08, 0.08]), (96, 128, 1))
    guesses = shot_catcher.guess_albedos(
        bpy, scene, [floor], [sphere], plate,
        lambda s: bench_shot.render_passes(bpy, s, tmp_path / "match.exr",
                                               compat().OBJECT_INDEX_LAYER))
    r, g, b = guesses["Floor"]
    assert r == pytest.approx(0.5, rel=0.15) and g == pytest.approx(0.08, rel=0.15), guesses
    assert floor.is_shadow_catcher and scene.render.film_transparent and scene.cycles.samples == 8
