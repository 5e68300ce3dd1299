"""The probe's distance map (addon/ibl/distance.py): rendered right after the probe's panorama,
from the same centre with the same objects hidden.

Blender 5.2 writes no Depth pass into the probe's EXR (checked: even a multilayer EXR held only
Combined), so the distance is rendered as a colour: one 1-spp render where every surface emits
Camera Data's View Distance (for a panoramic camera the radial distance from its centre) and the
sky (transparent film) reads as FAR, at DISTANCE_SCALE times the probe's size (sharper
silhouettes for almost nothing: a box's reflection IoU 0.81 at the probe's size, 0.87 at 4x), but no larger than
DISTANCE_MAX_HEIGHT unless the probe is: a probe sized to a large mirror on screen (1024 px
high) would otherwise make a 4096 x 8192 map of 128 MiB."""
from __future__ import annotations

import os

import bpy
import numpy as np

from ...addon.exr_io import read_exr
from ...addon.ibl import distance as distance_maps
from ...node_groups.distance_material import distance_material

DISTANCE_SCALE = 4
DISTANCE_MAX_HEIGHT = 1024


def distance_height(probe_height: int) -> int:
    """The distance map's height for a probe ``probe_height`` px high."""
    return max(probe_height, min(DISTANCE_SCALE * probe_height, DISTANCE_MAX_HEIGHT))


def render_distance(scene, view_layer, folder, clip_end, material=None):
    """Render the distance panorama with the probe's set-up (camera, hidden objects) as it is now;
    returns (distance map (H, W) float32, warnings). ``material``: the override that emits the
    distance (default ``distance_material()``; the layer behind passes its peeled copy).

    The world stays the scene's and the sky is told by the film's alpha: swapping in a world
    that emits FAR made Cycles rebuild the scene world's light-importance map at the next probe,
    about 1 s per probe under a 2k HDRI (docs/bench/bake.md), more than the probe itself."""
    material = material or distance_material()
    render = scene.render
    fmt = render.image_settings
    saved = [(view_layer, "material_override", view_layer.material_override),
             (scene.cycles, "samples", scene.cycles.samples),
             (scene.cycles, "use_denoising", scene.cycles.use_denoising), (render, "filepath", render.filepath),
             (render, "resolution_x", render.resolution_x), (render, "resolution_y", render.resolution_y),
             (render, "film_transparent", render.film_transparent), (fmt, "color_mode", fmt.color_mode)]
    path = os.path.join(folder, material.name.replace(" ", "_") + ".exr")
    try:
        view_layer.material_override = material
        scene.cycles.samples = 1
        scene.cycles.use_denoising = False          # a denoised distance is no distance
        render.film_transparent = True              # the sky: alpha 0, read as FAR
        fmt.color_mode = "RGBA"
        render.filepath = path
        height = distance_height(render.resolution_y)
        render.resolution_x, render.resolution_y = 2 * height, height
        bpy.ops.render.render(write_still=True)      # the probe renderer left this layer alone enabled
    finally:
        for owner, attr, value in reversed(saved):
            setattr(owner, attr, value)
    rgba = read_exr(path, "RGBA")
    # one sample per texel: alpha is 0 or 1
    depth = np.where(rgba[..., 3] < 0.5, np.float32(distance_maps.FAR), rgba[..., 0])
    return distance_maps.distance_map(depth, clip_end)


def write_probe_distance(distance, folder, frame, offsets):
    """Write the distance map next to the probe's maps; returns its warnings (zero-distance
    texels; an object reaching past what its probe sees)."""
    dist, warnings = distance
    sentence = distance_maps.coverage_warning(dist, offsets)
    distance_maps.write_distance(folder, dist, frame)
    return warnings + ([sentence] if sentence else [])


def surface_points(ob, depsgraph, limit=20000):
    """World positions of the evaluated mesh's vertices (at most ``limit``; the bounding box's
    corners for objects without a mesh)."""
    evaluated = ob.evaluated_get(depsgraph)
    mesh = getattr(evaluated, "data", None)
    if ob.type == "MESH" and mesh is not None and len(mesh.vertices):
        co = np.empty(len(mesh.vertices) * 3, dtype=np.float64)
        mesh.vertices.foreach_get("co", co)
        co = co.reshape(-1, 3)[:: max(1, len(mesh.vertices) // limit)]
    else:
        co = np.array([tuple(c) for c in ob.bound_box], dtype=np.float64)
    m = np.array(ob.matrix_world, dtype=np.float64)
    return co @ m[:3, :3].T + m[:3, 3]
