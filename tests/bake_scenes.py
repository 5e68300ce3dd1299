"""Small scenes for the bake tests and benchmark (tiny renders: 2 shared CPU cores)."""
from __future__ import annotations

import math
import os
import sys

import numpy as np

from support import EXT_MODULE
from support import compat


def bake_module(part="job"):
    """operators/bake/<part>.py of the enabled extension (job: ProbeBake, bake_probes;
    probe_render: the panorama; None: the operators' package)."""
    return sys.modules[f"{EXT_MODULE}.operators.bake" + (f".{part}" if part else "")]


def probe_renders():
    """Cycles probe renders so far (a cache hit renders nothing)."""
    return bake_module("probe_render").render_count


def new_scene(bpy, tmp_path, *, world_color=(1.0, 1.0, 1.0), env_exr=None, save=True,
              height=32, samples=8):
    """Empty scene with a camera looking at the origin and a world (uniform colour or an EXR)."""
    scene = bpy.context.scene
    world = compat().new_world("World")
    scene.world = world
    tree = world.node_tree
    background = tree.nodes["Background"]
    if env_exr is not None:
        env = tree.nodes.new("ShaderNodeTexEnvironment")
        env.image = bpy.data.images.load(str(env_exr))
        tree.links.new(env.outputs["Color"], background.inputs["Color"])
    else:
        background.inputs["Color"].default_value = (*world_color, 1.0)
    cam_data = bpy.data.cameras.new("Camera")
    cam = bpy.data.objects.new("Camera", cam_data)
    scene.collection.objects.link(cam)
    cam.location = (0.0, -10.0, 1.0)
    cam.rotation_euler = (math.radians(90), 0.0, 0.0)
    scene.camera = cam
    scene.platelight.probe_height = height
    scene.platelight.probe_samples = samples
    if save:
        bpy.ops.wm.save_as_mainfile(filepath=str(tmp_path / "scene.blend"))
    return scene


def add_sphere(bpy, name, location, radius=0.5, enabled=True, color=None, emission=None):
    bpy.ops.mesh.primitive_uv_sphere_add(radius=radius, location=location, segments=16, ring_count=8)
    ob = bpy.context.object
    ob.name = name
    ob.platelight.enabled = enabled
    if color is not None or emission is not None:
        ob.data.materials.append(material(bpy, name + "Mat", color or (0, 0, 0), emission))
    return ob


def add_plane(bpy, name, location, size=6.0, color=None, phantom=False):
    bpy.ops.mesh.primitive_plane_add(size=size, location=location)
    ob = bpy.context.object
    ob.name = name
    ob.platelight.phantom = phantom
    if color is not None:
        ob.data.materials.append(material(bpy, name + "Mat", color))
    return ob


def material(bpy, name, color, emission=None):
    mat = compat().new_material(name)
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*color, 1.0)
    bsdf.inputs["Roughness"].default_value = 1.0
    if emission is not None:
        bsdf.inputs["Emission Color"].default_value = (*emission, 1.0)
        bsdf.inputs["Emission Strength"].default_value = 1.0
    return mat


def maps_folder(tmp_path, name):
    return tmp_path / "platelight_maps" / name


def read_map(tmp_path, name, map_name="diffuse", frame=None):
    from platelight.addon.exr_io import read_exr

    suffix = "" if frame is None else f"_{frame:04d}"
    return read_exr(maps_folder(tmp_path, name) / f"{map_name}{suffix}.exr")


def scene_snapshot(bpy):
    """What a failed or finished bake must leave exactly as it was."""
    scene = bpy.context.scene
    render = scene.render
    return {
        "camera": scene.camera.name if scene.camera else None,
        "frame": scene.frame_current,
        "engine": render.engine,
        "resolution": (render.resolution_x, render.resolution_y, render.resolution_percentage),
        "filepath": render.filepath,
        "format": render.image_settings.file_format,
        "samples": scene.cycles.samples,
        "denoise": scene.cycles.use_denoising,
        "film_transparent": render.film_transparent,
        "objects": sorted(o.name for o in bpy.data.objects),
        "images": sorted(im.name for im in bpy.data.images),
        "cameras": sorted(c.name for c in bpy.data.cameras),
        "hide_render": {o.name: o.hide_render for o in bpy.data.objects},
        "catchers": {o.name: o.is_shadow_catcher for o in bpy.data.objects},
        "world_map": ((scene.world.cycles.sampling_method, scene.world.cycles.sample_map_resolution)
                      if scene.world else None),
        "active": bpy.context.view_layer.objects.active.name if bpy.context.view_layer.objects.active else None,
    }


def direction_texel(height, direction):
    """Row, column of the lat-long texel holding a world direction (Environment Texture layout)."""
    d = np.asarray(direction, dtype=float)
    d = d / np.linalg.norm(d)
    u = math.atan2(-d[1], d[0]) / (2 * math.pi) + 0.5
    v = math.atan2(d[2], math.hypot(d[0], d[1])) / math.pi + 0.5
    return min(int((1 - v) * height), height - 1), int(u * 2 * height) % (2 * height)


def bright_direction(channel):
    """Brightness-weighted mean direction of a lat-long channel (no argmax: the noise of a few
    samples decides which texel of a uniform disk is brightest)."""
    from platelight.addon.ibl.equirect import texel_directions, texel_solid_angles

    h, w = channel.shape
    weights = np.maximum(channel, 0) * texel_solid_angles(h, w)
    mean = (texel_directions(h, w) * weights[..., None]).sum(axis=(0, 1))
    return mean / np.linalg.norm(mean)


def angle_deg(a, b):
    a = np.asarray(a, float) / np.linalg.norm(a)
    b = np.asarray(b, float) / np.linalg.norm(b)
    return math.degrees(math.acos(np.clip(a @ b, -1, 1)))
