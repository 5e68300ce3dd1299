"""The phantoms' surface (bpy): what they look like to reflections, bounced light and probes, the
camera-projected plate (default, node_groups/phantom_plate.py) or their own hand-made materials
(``scene.platelight.phantom_surface``, overridden per object by ``object.platelight.phantom_surface``).

The plate material is put on the object's material slots as object-linked materials, so the
mesh's own materials are never touched; object-linked materials it replaces are remembered on
the object and given back when the object goes back to its own material.

The plate's albedo on them is Debevec 1998's local-scene estimate: render the phantoms white
(albedo 1) under the scene's lights, without the CG, from the plate's camera; the real surface's
albedo is then plate / that render, per pixel. A phantom with that albedo, shaded by the scene's
lights, shows the plate where nothing changes and darkens where the CG shadows it, in
reflections and probes as on the catcher.

The map is made in the render camera's frame (undistorted when the scene has a lens) at the
scene's current frame, and the material projects it with that frame's camera pose, frozen, so
the albedo stays on the phantoms when the camera moves."""
import json
import os

import bpy
import numpy as np

from .. import compat
from ..addon import names
from ..addon.compositing import lens
from ..addon.exr_io import read_exr, write_exr
from ..node_groups.distance_material import distance_material, remove_distance_material
from ..node_groups.phantom_plate import build_phantom_plate_material, pinhole_from_camera
from .bake.scene_state import SceneState
from .common import GEOMETRY_TYPES, data_folder, find_plate_image

KEPT_KEY = names.KEPT_MATERIALS_KEY      # on the object: {slot index: object-linked material name}
MATERIAL_NAME = names.PHANTOM_PLATE_MATERIAL

# The white render's samples (then OIDN, its guides unfiltered: a white diffuse's albedo and a
# phantom's normal have no noise to filter): its noise, which the plate's own grain dwarfs, reaches
# the composite only where rays path-trace a phantom the camera did not film (docs/decisions.md,
# "The set-up's white render")
ALBEDO_SAMPLES = 4
# The plate is smoothed by this Gaussian (pixels, within the phantoms) before the CG's rays see it:
# its grain or render noise is no part of the real surface, and a mirror's reflection, which
# minifies the plate, turns it into noise the CG's samples must average (docs/decisions.md,
# "Filmed phantoms")
FILMED_SMOOTHING = 1.5
MIN_SHADING = 1e-4       # below this the white render saw no light: the albedo is unknown there
# Albedos above 1 are kept up to this: a plate brighter than the scene's lights can make (probe
# and plate exposed differently) still comes back as itself; the cap keeps phantoms lighting
# each other from running away.
MAX_ALBEDO = 4.0


def _white(name=names.PHANTOM_WHITE_MATERIAL):
    mat = bpy.data.materials.get(name) or compat.new_material(name)
    tree = compat.node_tree(mat)
    tree.nodes.clear()
    diffuse = tree.nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    tree.links.new(diffuse.outputs[0], tree.nodes.new("ShaderNodeOutputMaterial").inputs["Surface"])
    return mat


def _render_phantoms(scene, view_layer, phantoms, path, material, samples, denoise):
    """The phantoms rendered with ``material`` from the scene camera, without anything else:
    (H, W, 4)."""
    state = SceneState()
    try:
        for ob in scene.objects:
            if ob.type in GEOMETRY_TYPES and ob not in phantoms and not ob.hide_render:
                state.set(ob, "hide_render", True)
        for ob in phantoms:
            state.set(ob, "is_shadow_catcher", False)
            state.set(ob, "is_holdout", False)
        stack = [view_layer.layer_collection]
        while stack:
            layer_collection = stack.pop()
            for flag in ("holdout", "indirect_only", "exclude"):
                if getattr(layer_collection, flag):
                    state.set(layer_collection, flag, False)
            stack.extend(layer_collection.children)
        state.set(view_layer, "material_override", material)
        render = scene.render
        state.set(render, "engine", "CYCLES")
        state.set(render, "film_transparent", True)
        state.set(render, "use_compositing", False)
        # Only this layer, the others switched off rather than the render told to do one layer:
        # a single-layer render keeps the layers of the render before in its result when the size
        # is unchanged, and the white render's EXR came back as the distance render before it
        # (albedo a seventh of the plate's; operators/bake/probe_render.py met the same)
        state.set(render, "use_single_layer", False)
        for layer in scene.view_layers:
            if layer != view_layer and layer.use:
                state.set(layer, "use", False)
        state.set(view_layer, "use", True)
        state.set(render, "filepath", path)
        fmt = render.image_settings
        for attr, value in compat.still_image_format():
            state.set(fmt, attr, value)
        state.set(fmt, "file_format", "OPEN_EXR")
        state.set(fmt, "color_mode", "RGBA")
        state.set(fmt, "color_depth", "32")
        state.set(scene.cycles, "samples", samples)
        state.set(scene.cycles, "use_denoising", denoise)
        state.set(scene.cycles, "denoising_prefilter", "FAST")       # see ALBEDO_SAMPLES
        state.set(scene.cycles, "use_adaptive_sampling", False)
        # each pixel its own area, like a plate pixel: no blur across pixels
        state.set(scene.cycles, "pixel_filter_type", "BOX")
        state.set(scene.cycles, "filter_width", 1.0)
        bpy.ops.render.render(write_still=True)
        return read_exr(path, "RGBA")
    finally:
        state.restore()


def _same_pixels(path, image):
    try:
        old = read_exr(path, "RGBA")
    except Exception:       # unreadable or another layout: write it again
        return False
    return old.shape == image.shape and np.array_equal(old, image)


def _write_if_changed(path, image):
    # an unchanged map keeps its file (and mtime): the bake's input hash describes images by
    # mtime, so rewriting the same pixels would make every bake redo every probe
    if not (os.path.isfile(path) and _same_pixels(path, image)):
        write_exr(path, image)
    return path


def _smooth_within(image, mask, sigma):
    """``image`` blurred by a Gaussian of ``sigma`` px over the pixels of ``mask`` only (a phantom's
    edge does not take in the sky or the CG beside it). ``sigma`` 0: ``image`` as it is."""
    import cv2

    if sigma <= 0:
        return image

    weight = mask.astype(np.float32)
    total = cv2.GaussianBlur(image.astype(np.float32) * weight[..., None], (0, 0), sigma)
    norm = cv2.GaussianBlur(weight, (0, 0), sigma)[..., None]
    return np.where(norm > 1e-3, total / np.maximum(norm, 1e-3), image)


def _filmed_radiance(pixels, distance, whose, count):
    """The radiance map: RGB the plate smoothed within each phantom, A how far each pixel's filmed
    phantom reaches (0: nothing filmed there).

    Each phantom on its own, its silhouette left out (A 0: path-traced with the phantom's own
    albedo): a pixel there mixes it with what is behind it, so a face the camera saw edge-on (a
    box's side, in a mirror beside it) took the floor's grey, and the distance behind it passed
    hidden points for filmed. The frame's edge is no silhouette."""
    filmed = np.clip(np.nan_to_num(pixels, nan=0.0, posinf=0.0), 0.0, None)    # a plate's bad pixels emit nothing
    reach = np.zeros(whose.shape, np.float32)
    for number in range(1, count + 1):
        own, box = _crop(whose == number, margin=int(3 * FILMED_SMOOTHING) + 2)
        if not own.any():           # out of the frame, or hidden behind other phantoms
            continue
        inner = _inside_silhouette(own)
        farthest = _farthest_around(np.where(inner, distance[box], 0.0))
        reach[box] = np.where(inner, farthest, reach[box])
        smoothed = _smooth_within(filmed[box], inner, FILMED_SMOOTHING)
        filmed[box] = np.where(own[..., None], smoothed, filmed[box])
    return np.concatenate([np.where(whose[..., None] > 0, filmed, 0.0), reach[..., None]], -1).astype(np.float32)


def _crop(mask, margin):
    """``mask`` cut to its bounding box grown by ``margin`` pixels, and the (rows, cols) slices of
    that box: per-phantom work costs its own pixels, not the frame's."""
    rows, cols = np.nonzero(mask.any(1))[0], np.nonzero(mask.any(0))[0]
    if not len(rows):
        return mask[:0, :0], (slice(0, 0), slice(0, 0))
    box = (slice(max(rows[0] - margin, 0), rows[-1] + margin + 1),
           slice(max(cols[0] - margin, 0), cols[-1] + margin + 1))
    return mask[box], box


def _inside_silhouette(mask):
    """``mask`` less its pixels next to a pixel outside it (8-neighbours); the image's border
    counts as inside."""
    import cv2

    return cv2.erode(mask.astype(np.uint8), np.ones((3, 3), np.uint8), borderType=cv2.BORDER_CONSTANT,
                     borderValue=1).astype(bool)


def _farthest_around(distance):
    """Each pixel's largest distance over it and its 8 neighbours: one sample's distance stands for
    the whole pixel, and a floor receding towards the horizon spans more than the test's 5 % within
    one pixel. (On the benchmark's mirror it changed nothing measurable: the band of path-traced far
    floor it was meant for lay outside the frame, docs/decisions.md, "Filmed phantoms".)"""
    import cv2

    return cv2.dilate(distance.astype(np.float32), np.ones((3, 3), np.uint8))


def phantom_albedo(scene, view_layer, phantoms, plate, calib):
    """Write the albedo map and the radiance map; returns (albedo path, radiance path,
    world-to-camera 4x4 of the frame they were made at, fallback albedo, each phantom's hidden
    albedo, each phantom's mean albedo). ``calib`` = (fx, fy, cx, cy, dist, width, height) of the plate's lens.

    Where the camera did not see a phantom (behind another, or outside the frame) its albedo is
    unknown: each phantom gets the median albedo of what the camera saw of it (the floor behind a
    red box stays the floor's grey, not the box's red), one it did not see at all the fallback.
    The mean over the same pixels is the energy it sends back (the shadow bake's matte albedo).

    The radiance map is what the camera filmed where it saw a phantom: the plate's RGB, and in A
    the farthest distance from the camera to a phantom around that pixel (0 where it saw none), so
    the material can tell a point the camera saw from one hidden behind it."""
    from .grain import plate_frame_pixels

    folder = data_folder(scene, "phantoms")
    os.makedirs(folder, exist_ok=True)
    white = _render_phantoms(scene, view_layer, phantoms, os.path.join(folder, "white.exr"), _white(),
                             ALBEDO_SAMPLES, True)
    # one sample a pixel, undenoised: a distance, not an average of two surfaces' distances
    ours = bpy.data.materials.get(names.PROBE_DISTANCE) is None
    indices = SceneState()      # each phantom's pass index: G of the distance render says whose pixel
    try:
        for number, ob in enumerate(phantoms, start=1):
            indices.set(ob, "pass_index", number)
        distance = _render_phantoms(scene, view_layer, phantoms, os.path.join(folder, "distance.exr"),
                                    distance_material(), 1, False)
    finally:
        indices.restore()
        if ours:
            remove_distance_material()
    pixels = plate_frame_pixels(plate, scene)[..., :3].astype(np.float32)
    fx, fy, cx, cy, dist, width, height = calib
    if lens.has_distortion(dist):
        frame = lens.render_frame(fx, fy, cx, cy, dist, width, height)
        pixels = lens.undistort_to_render(pixels, fx, fy, cx, cy, dist, frame)
    seen = (white[..., 3] > 0.5) & (white[..., :3].min(-1) > MIN_SHADING)
    albedo = np.zeros_like(pixels)
    albedo[seen] = np.clip(pixels[seen] / white[..., :3][seen], 0.0, MAX_ALBEDO)
    fallback = np.median(albedo[seen], axis=0) if seen.any() else np.full(3, 0.5)
    albedo[~seen] = fallback
    albedo_path = _write_if_changed(os.path.join(folder, "albedo.exr"),
                                    np.concatenate([albedo, seen[..., None].astype(np.float32)], -1))
    phantom_there = distance[..., 3] > 0.5
    whose = np.where(phantom_there, np.rint(distance[..., 1]), 0).astype(np.int64)
    hidden, means = [], []
    for number in range(1, len(phantoms) + 1):
        own = seen & (whose == number)
        hidden.append(np.median(albedo[own], axis=0) if own.any() else fallback)
        means.append(albedo[own].mean(axis=0) if own.any() else fallback)
    radiance_path = _write_if_changed(os.path.join(folder, "radiance.exr"),
                                      _filmed_radiance(pixels, distance[..., 0], whose, len(phantoms)))
    return albedo_path, radiance_path, np.array(scene.camera.matrix_world.inverted()), fallback, hidden, means


def phantom_surface(scene, ob):
    mode = ob.platelight.phantom_surface
    return scene.platelight.phantom_surface if mode == "SCENE" else mode


def plate_intrinsics(scene, camera):
    """The plate camera's (fx, fy, cx, cy, dist, width, height): the calibrated lens when the
    scene has one (operators/lens.py), else the Blender camera's pinhole."""
    from .lens import scene_lens

    calibrated = scene_lens(scene)
    if calibrated is not None:
        return calibrated
    fx, fy, cx, cy = pinhole_from_camera(scene, camera)
    return fx, fy, cx, cy, (0.0,) * 5, scene.render.resolution_x, scene.render.resolution_y


def apply_phantom_surfaces(scene, phantoms, view_layer=None):
    """Give each phantom the surface its setting asks for; returns how many show the plate.
    Without a plate or a camera every phantom keeps its own material. Showing the plate renders
    the phantoms once, white, to estimate their albedo (phantom_albedo)."""
    plate = find_plate_image(scene)
    camera = scene.camera
    usable = plate is not None and camera is not None and camera.type == "CAMERA"
    wanted = [ob for ob in phantoms if usable and phantom_surface(scene, ob) == "PLATE"]
    for ob in phantoms:          # the white render must not see the plate material
        if ob not in wanted:
            _give_back(ob)
    if not wanted:
        return 0
    layer = view_layer or bpy.context.view_layer
    albedo_path, radiance_path, world_to_camera, fallback, hidden, means = phantom_albedo(
        scene, layer, wanted, plate, plate_intrinsics(scene, camera))
    albedo = _load_map(names.PHANTOM_ALBEDO_IMAGE, albedo_path, "STRAIGHT")
    # RGB and A are separate facts (the plate, the distance): neither may scale the other
    radiance = _load_map(names.PHANTOM_RADIANCE_IMAGE, radiance_path, "CHANNEL_PACKED")
    # the maps are in the render camera's frame: its own pinhole, no lens
    material = build_phantom_plate_material(albedo, radiance, world_to_camera, pinhole_from_camera(scene, camera),
                                            (scene.render.resolution_x, scene.render.resolution_y), fallback)
    for ob, hidden_albedo, mean_albedo in zip(wanted, hidden, means):
        _show_plate(ob, material)
        ob[names.HIDDEN_ALBEDO_KEY] = [*(float(c) for c in hidden_albedo), 1.0]
        ob[names.MEAN_ALBEDO_KEY] = [float(c) for c in mean_albedo]
    return len(wanted)


def _load_map(name, path, alpha_mode):
    image = bpy.data.images.get(name)
    if image is not None:
        bpy.data.images.remove(image)
    image = bpy.data.images.load(path, check_existing=False)
    image.name = name
    image.colorspace_settings.name = "Non-Color"
    image.alpha_mode = alpha_mode
    return image


def _show_plate(ob, material):
    if not hasattr(ob.data, "materials"):
        return
    if not ob.material_slots:
        ob.data.materials.append(None)
    kept = json.loads(ob.get(KEPT_KEY, "{}"))
    for index, slot in enumerate(ob.material_slots):
        if slot.link == "OBJECT" and slot.material is not None and slot.material.name != MATERIAL_NAME:
            kept[str(index)] = slot.material.name
        slot.link = "OBJECT"
        slot.material = material
    ob[KEPT_KEY] = json.dumps(kept)


def _give_back(ob):
    if KEPT_KEY not in ob:
        return
    kept = json.loads(ob[KEPT_KEY])
    for index, slot in enumerate(ob.material_slots):
        if slot.link == "OBJECT" and (slot.material is None or slot.material.name == MATERIAL_NAME):
            name = kept.get(str(index))
            slot.material = bpy.data.materials.get(name) if name else None
            if name is None:
                slot.link = "DATA"
    del ob[KEPT_KEY]
    for key in (names.HIDDEN_ALBEDO_KEY, names.MEAN_ALBEDO_KEY):
        if key in ob:
            del ob[key]
