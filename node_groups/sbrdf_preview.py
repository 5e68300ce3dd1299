"""A picture of the presets: a row of spheres, one per preset, lit by maps made from an HDRI
(``render_preset_row``). Used by the demo; renders in its own temporary scene, so the user's
scene is untouched."""
from __future__ import annotations

import math
import os
import shutil
import tempfile

import bpy

from .. import compat
from ..addon import names
from ..addon.exr_io import read_exr
from ..addon.ibl.maps import compute_maps, write_maps
from ..addon.material.presets import preset_label, preset_names
from .probe_maps import find_probe_group
from .sbrdf_material import apply_sbrdf_material


def default_hdri() -> str:
    folder = bpy.utils.system_resource("DATAFILES", path="studiolights/world")
    return os.path.join(folder, "courtyard.exr")


def render_preset_row(out_png: str, hdri: str | None = None, presets=None,
                      sphere_px: int = 160, samples: int = 16) -> str:
    """Render one sphere per preset, side by side, in front of ``hdri`` (default: the bundled
    courtyard), and save ``out_png``. Returns the PNG path."""
    hdri = hdri or default_hdri()
    presets = list(presets or preset_names())
    maps_dir = tempfile.mkdtemp(prefix="platelight-presets-")
    write_maps(maps_dir, compute_maps(read_exr(hdri)).maps)

    scene = bpy.data.scenes.new(names.PRESETS_SCENE)
    world = compat.new_world(names.PRESETS_SCENE)
    scene.world = world
    env = world.node_tree.nodes.new("ShaderNodeTexEnvironment")
    env.image = bpy.data.images.load(hdri, check_existing=True)
    world.node_tree.links.new(env.outputs["Color"],
                              world.node_tree.nodes["Background"].inputs["Color"])
    scene.render.engine = "CYCLES"
    scene.cycles.samples = samples
    scene.cycles.use_denoising = False
    scene.view_settings.view_transform = "AgX"      # a picture for people: HDR highlights roll off
    scene.render.resolution_x = sphere_px * len(presets)
    scene.render.resolution_y = sphere_px
    scene.render.image_settings.file_format = "PNG"
    scene.render.filepath = os.path.abspath(out_png)

    created = [world]
    cam_data = bpy.data.cameras.new(names.PRESETS_SCENE)
    cam_data.type = "ORTHO"
    cam_data.ortho_scale = 2.4 * len(presets)
    cam = bpy.data.objects.new(names.PRESETS_CAMERA, cam_data)
    cam.location = (0.0, -10.0, 0.0)
    cam.rotation_euler = (math.pi / 2, 0.0, 0.0)
    scene.collection.objects.link(cam)
    scene.camera = cam
    created += [cam, cam_data]
    for i, name in enumerate(presets):
        mesh = bpy.data.meshes.new(f"Preset {name}")
        ob = bpy.data.objects.new(f"{preset_label(name)}", mesh)
        _uv_sphere(mesh)
        ob.location = (2.4 * (i - (len(presets) - 1) / 2), 0.0, 0.0)
        ob.rotation_euler = (math.radians(-60), 0.0, 0.0)   # tilt: shows the brushed circles
        scene.collection.objects.link(ob)
        ob.platelight.probe_dir = maps_dir
        created += [apply_sbrdf_material(ob, name, scene=scene), ob, mesh]
    try:
        with bpy.context.temp_override(scene=scene):
            bpy.ops.render.render(write_still=True, scene=scene.name)
    finally:
        for block in created:
            collection = {bpy.types.Object: bpy.data.objects, bpy.types.Mesh: bpy.data.meshes,
                          bpy.types.Camera: bpy.data.cameras, bpy.types.World: bpy.data.worlds,
                          bpy.types.Material: bpy.data.materials}[type(block)]
            collection.remove(block)
        bpy.data.scenes.remove(scene)
        _remove_probe(maps_dir)
    return os.path.abspath(out_png)


def _remove_probe(maps_dir):
    """The preview's temporary maps: their probe group, its images and the folder."""
    group = find_probe_group(maps_dir)
    if group is not None:
        images = {n.image.name for n in group.nodes if getattr(n, "image", None) is not None}
        bpy.data.node_groups.remove(group)
        for name in images:            # each map feeds several nodes: one name, removed once
            image = bpy.data.images.get(name)
            if image is not None and image.users == 0:
                bpy.data.images.remove(image)
    shutil.rmtree(maps_dir, ignore_errors=True)


def _uv_sphere(mesh, segments=64, rings=32):
    import bmesh

    bm = bmesh.new()
    bmesh.ops.create_uvsphere(bm, u_segments=segments, v_segments=rings, radius=1.0)
    for face in bm.faces:
        face.smooth = True
    bm.to_mesh(mesh)
    bm.free()
