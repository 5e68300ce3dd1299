"""The AR half of `python -m platelight demo`: CG objects composited into "footage" of a real place.

The real place is a Poly Haven HDRI that ships in the bpy wheel. The footage (plate) is a short
camera move rendered, fully path-traced, in that place: a paved floor and a red box stand in it.
The camera is known (it made the plate). The truth is the first frame path-traced again with the
CG objects really there. Then, exactly as the README tells a user: the floor and the box become
phantoms, the CG objects get SBRDF materials and their probes, Set Up Plate, Bake Shadows, and Set
Up Composite with its default method (the baked shadows, the CG standing still). Outputs:
composites (PNG sequence), a contact sheet (plate | CG | shadows | composite), the first composite
beside the truth with their PSNR, and the timings of every stage.

Blender runs inside this process (the bpy module); the extension is enabled from this package's
own folder in a throw-away user profile, as the tests do (drivers/headless.py).
"""
from __future__ import annotations

import contextlib
import math
import os
import pathlib
import time

import numpy as np

from ..addon import names
from ..addon.demo import bundled_hdris
from ..addon.errors import PlateLightError
from ..addon.exr_io import read_exr
from ..addon.fileio import ensure_writable_folder, replace_file, temp_path, write_json_atomic
from ..addon.imaging import LUMA, contact_sheet, linear_to_srgb8, psnr, write_png
from .headless import EXT_MODULE, blender_with_extension

HDRI = "city"
SIZE = (640, 360)
FRAMES = 3
PLATE_SAMPLES = 16      # denoised: the footage's own grain is not what the demo shows
# the HDRI's brightness in the filmed place (its sun would burn the footage out at 1)
WORLD_STRENGTH = 0.55
PROBE_SAMPLES = 64   # the bake's default 16 leaves sun fireflies on the floor in the probes
# the truth's pixels that count as shadow: the CG changes the plate by more than this there
SHADOW_CHANGE = 0.03


def _material(bpy, name, colour, roughness=0.5, metallic=0.0, checker=None):
    from .. import compat     # bpy glue: imported once Blender runs

    mat = compat.new_material(name)
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    bsdf = nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*colour, 1.0)
    bsdf.inputs["Roughness"].default_value = roughness
    bsdf.inputs["Metallic"].default_value = metallic
    if checker:
        tex = nodes.new("ShaderNodeTexChecker")
        tex.inputs["Scale"].default_value = checker[0]
        tex.inputs["Color1"].default_value = (*checker[1], 1.0)
        tex.inputs["Color2"].default_value = (*checker[2], 1.0)
        links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    return mat


def _mesh_object(bpy, scene, name, kind, location, size, material):
    import bmesh

    mesh = bpy.data.meshes.new(name)
    bm = bmesh.new()
    if kind == "sphere":
        bmesh.ops.create_uvsphere(bm, u_segments=64, v_segments=32, radius=size)
    elif kind == "cube":
        bmesh.ops.create_cube(bm, size=size)
    elif kind == "plane":
        bmesh.ops.create_grid(bm, x_segments=1, y_segments=1, size=size / 2)
    elif kind == "monkey":
        bmesh.ops.create_monkey(bm)
        bmesh.ops.scale(bm, vec=(size, size, size), verts=bm.verts)
    bm.to_mesh(mesh)
    bm.free()
    if kind in ("sphere", "monkey"):
        for poly in mesh.polygons:
            poly.use_smooth = True
    mesh.materials.append(material)
    ob = bpy.data.objects.new(name, mesh)
    ob.location = location
    scene.collection.objects.link(ob)
    return ob


def _camera_move(bpy, scene, frames):
    """A slow orbit around the set, keyed on every frame (the camera is known)."""
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.data.lens = 35
    scene.collection.objects.link(cam)
    scene.camera = cam
    target = np.array([-0.3, 0.1, 0.35])
    from mathutils import Vector

    for frame in range(1, frames + 1):
        azimuth = math.radians(-100 + 20 * (frame - 1) / max(1, frames - 1))
        pos = target + np.array([4.2 * math.cos(azimuth), 4.2 * math.sin(azimuth), 1.25])
        cam.location = tuple(pos)
        cam.rotation_euler = Vector(tuple(target - pos)).to_track_quat("-Z", "Y").to_euler()
        cam.keyframe_insert("location", frame=frame)
        cam.keyframe_insert("rotation_euler", frame=frame)
    return cam


def _render_still(bpy, scene, path, file_format="OPEN_EXR"):
    """Render the current frame to ``path`` atomically: an interrupted render leaves nothing."""
    settings = scene.render.image_settings
    settings.file_format = file_format
    if file_format == "OPEN_EXR":
        settings.color_depth = "32"
    else:
        settings.color_depth = "8"
        settings.color_mode = "RGB"
    tmp = temp_path(path)   # hidden (.NAME.partial-PID.EXT): a glob of NAME_*.EXT never sees it
    scene.render.filepath = tmp
    bpy.ops.render.render(write_still=True)
    replace_file(tmp, path)


def build_real_place(bpy, hdri_path, frames=FRAMES, size=SIZE):
    """The 'filmed' set: world = the HDRI, a paved floor and a red box, and the camera move."""
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.render.resolution_x, scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    scene.frame_start, scene.frame_end = 1, frames
    from .. import compat

    world = compat.new_world("Real Place")
    env = world.node_tree.nodes.new("ShaderNodeTexEnvironment")
    env.image = bpy.data.images.load(hdri_path)
    background = world.node_tree.nodes["Background"]
    world.node_tree.links.new(env.outputs["Color"], background.inputs["Color"])
    background.inputs["Strength"].default_value = WORLD_STRENGTH
    scene.world = world
    floor_mat = _material(bpy, "Paving", (0.3, 0.3, 0.3), roughness=0.85,
                          checker=(24.0, (0.34, 0.31, 0.27), (0.24, 0.23, 0.22)))
    floor = _mesh_object(bpy, scene, "Floor", "plane", (0, 0, 0), 60.0, floor_mat)
    box = _mesh_object(bpy, scene, "Red Box", "cube", (-1.6, 0.55, 0.35), 0.7,
                       _material(bpy, "Red Paint", (0.55, 0.04, 0.03), roughness=0.6))
    box.rotation_euler = (0, 0, math.radians(20))
    _camera_move(bpy, scene, frames)
    return scene, [floor, box]


def add_cg_objects(bpy, scene):
    """CG objects with three material presets (Principled here; the SBRDF group when available)."""
    presets = [
        ("CG Plaster Sphere", "sphere", (-0.85, 0.05, 0.38), 0.38, dict(colour=(0.8, 0.78, 0.74), roughness=0.9)),
        ("CG Chrome Sphere", "sphere", (0.15, 0.25, 0.38), 0.38, dict(colour=(0.9, 0.9, 0.9), roughness=0.03, metallic=1.0)),
        ("CG Gold Monkey", "monkey", (0.7, -0.7, 0.33), 0.36, dict(colour=(1.0, 0.72, 0.3), roughness=0.25, metallic=1.0)),
    ]
    objects = []
    for name, kind, location, size, mat in presets:
        ob = _mesh_object(bpy, scene, name, kind, location, size, _material(bpy, name + " Material", **mat))
        if kind == "monkey":
            ob.rotation_euler = (0, 0, math.radians(-25))
        objects.append(ob)
    return objects


@contextlib.contextmanager
def _stage(timings, key, say, text):
    """Time one stage into ``timings[key]`` and say it with its seconds."""
    t0 = time.perf_counter()
    yield
    timings[key] = time.perf_counter() - t0
    say(f"  {text}: {timings[key]:.1f} s")


def _shade_with_sbrdf(bpy, objects, maps_dir):
    """Each CG object's Principled material converted to the SBRDF (the truth renders the same
    Principled), then one probe bake per object."""
    scene = bpy.context.scene
    scene.platelight.maps_dir = str(maps_dir)
    scene.platelight.probe_samples = PROBE_SAMPLES
    for ob in objects:          # materials first: the bake writes only the maps they read
        ob.platelight.enabled = True
        for other in scene.objects:
            other.select_set(other == ob)
        bpy.context.view_layer.objects.active = ob
        bpy.ops.platelight.apply_sbrdf(preset="NONE")
    # the scripting contract's bake (the world's light-importance map, so the small sun is
    # sampled without fireflies)
    bpy.ops.platelight.bake_probes(all_objects=True)


def compare_with_truth(composite, truth, plate, cg_alpha):
    """PSNR of the composite (and of the bare plate) against the truth: the whole frame, the
    CG objects (their inside) and their shadows (where the truth differs from the plate, away
    from the CG's edge)."""
    import cv2

    inside = cg_alpha > 0.99
    near = cv2.dilate((cg_alpha > 0).astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)
    change = np.abs(truth @ LUMA - plate @ LUMA) > SHADOW_CHANGE * np.maximum(plate @ LUMA, 1e-3)
    shadow = change & ~near
    # psnr's own peak (the truth's 99.5th percentile) is the same for every score here
    scores = {"frame_db": psnr(composite, truth),
              "object_db": psnr(composite, truth, inside),
              "shadow_db": psnr(composite, truth, shadow) if shadow.any() else None,
              "plate_alone_db": psnr(plate, truth),
              "object_pixels": int(inside.sum()), "shadow_pixels": int(shadow.sum())}
    return scores


def run_ar_demo(out_dir, hdri: str = HDRI, frames: int = FRAMES, size=SIZE, say=print) -> dict:
    """Run the AR demo into ``out_dir``; returns the timings of every stage (seconds), the method
    Set Up Composite chose and the scores against the truth. ``say`` prints progress."""
    out = pathlib.Path(ensure_writable_folder(out_dir))
    hdris = bundled_hdris()
    if hdri not in hdris:
        raise PlateLightError(f"No bundled HDRI named {hdri!r}; choose one of {', '.join(hdris)}.")
    if not 1 <= int(frames) <= 1000:
        raise PlateLightError(f"The demo shot has 1 to 1000 frames, not {frames}.")
    timings = {}
    t_all = time.perf_counter()
    with _stage(timings, "start_blender_s", say, "start Blender"):
        bpy = blender_with_extension()
    from importlib import import_module

    compositor_tree = import_module(f"{EXT_MODULE}.node_groups.compositor_tree")
    baked_shadows = import_module(f"{EXT_MODULE}.operators.baked_shadows")

    # 1. the footage: the real place, filmed (path-traced) along the camera move
    with _stage(timings, "film_plate_s", say, f"film the plate ({frames} frames, {size[0]}x{size[1]})"):
        scene, real = build_real_place(bpy, hdris[hdri], frames, size)
        scene.cycles.samples = PLATE_SAMPLES
        scene.cycles.use_denoising = True
        scene.view_settings.view_transform = "Standard"
        plate_dir = out / "plate"
        plate_dir.mkdir(exist_ok=True)
        for frame in range(1, frames + 1):
            scene.frame_set(frame)
            _render_still(bpy, scene, str(plate_dir / f"plate_{frame:04d}.exr"))
    # the truth: frame 1 filmed again with the CG objects really there
    cg = add_cg_objects(bpy, scene)
    with _stage(timings, "truth_s", say, "path-trace the truth (frame 1 with the CG there)"):
        scene.frame_set(1)
        _render_still(bpy, scene, str(out / "truth_0001.exr"))

    # 2. the user's side, in the README's order
    with _stage(timings, "bake_probes_s", say, f"SBRDF materials and probes for {len(cg)} CG objects"):
        for ob in real:
            ob.platelight.phantom = True
        scene.platelight.world_probe = hdris[hdri]
        _shade_with_sbrdf(bpy, cg, out / "probes")
        if bpy.ops.platelight.setup_plate(filepath=str(plate_dir / "plate_0001.exr")) != {"FINISHED"}:
            raise PlateLightError("Setting up the demo plate failed.")
    with _stage(timings, "bake_shadows_s", say, "bake the shot's shadows"):
        bpy.ops.platelight.bake_shadows()
    bpy.ops.platelight.setup_composite()            # the default method
    method = "BAKED" if baked_shadows.uses_baked_shadows(scene) else "CATCHER"

    # 3. render the composites (each file appears complete or not at all)
    comp_dir = out / "composite"
    comp_dir.mkdir(exist_ok=True)
    rows, first = [], None
    with _stage(timings, "render_composite_s", say, f"render {frames} composites ({method.lower()} shadows)"):
        for frame in range(1, frames + 1):
            scene.frame_set(frame)
            pass_dir = out / "passes" / f"{frame:04d}"
            pass_dir.mkdir(parents=True, exist_ok=True)
            compositor_tree.add_pass_outputs(scene, str(pass_dir) + "/")
            exr = comp_dir / f"composite_{frame:04d}.exr"
            _render_still(bpy, scene, str(exr))
            composite = read_exr(exr)
            write_png(comp_dir / f"composite_{frame:04d}.png", linear_to_srgb8(composite))
            passes = {n: read_exr(compositor_tree.pass_output_path(scene, str(pass_dir), n), "RGBA")
                      for n in ("Plate", "CG", "Shadows")}
            first = first or (composite, passes)
            rows.append([("plate", linear_to_srgb8(passes["Plate"][..., :3])),
                         ("CG", linear_to_srgb8(passes["CG"][..., :3])),
                         ("shadows (ratio)", linear_to_srgb8(np.clip(passes["Shadows"][..., :3], 0, 1))),
                         (f"composite, frame {frame}", linear_to_srgb8(composite))])
    timings["render_composite_per_frame_s"] = timings["render_composite_s"] / frames

    sheet = np.vstack([contact_sheet(row, tile_height=min(size[1], 180)) for row in rows])
    write_png(out / "contact_sheet.png", sheet)
    truth = read_exr(out / "truth_0001.exr")
    composite, passes = first
    scores = compare_with_truth(composite, truth, passes["Plate"][..., :3], passes["CG"][..., 3])
    difference = np.clip(4 * np.abs(composite - truth), 0, 1)
    shadow_db = scores["shadow_db"]
    shadow = f", shadows {shadow_db:.1f}" if shadow_db is not None else ""
    its_shadows = f", its shadows {shadow_db:.1f} dB" if shadow_db is not None else ""
    write_png(out / "truth_comparison.png", contact_sheet(
        [(f"composite: {scores['frame_db']:.1f} dB (CG {scores['object_db']:.1f}{shadow})",
          linear_to_srgb8(composite)),
         ("path-traced truth", linear_to_srgb8(truth)),
         ("difference x4", linear_to_srgb8(difference))], tile_height=size[1]))
    timings["total_s"] = time.perf_counter() - t_all
    summary = {"timings": timings, "method": method, "frames": frames, "size": list(size),
               "hdri": hdri, "materials": names.SBRDF_GROUP, "truth": scores}
    write_json_atomic(out / "timings.json", summary)
    say(f"  against the path-traced truth, frame 1: {scores['frame_db']:.1f} dB (the CG "
        f"{scores['object_db']:.1f} dB{its_shadows}; the plate alone "
        f"{scores['plate_alone_db']:.1f} dB)")
    return summary
