"""The AR half of `python -m platelight demo`: CG objects composited into "footage" of a real place.

The real place is a Poly Haven HDRI that ships in the bpy wheel. The footage (plate) is a short
camera move rendered, fully path-traced, in that place: a paved floor and a red box stand in it.
The camera is known (it made the plate). Then, exactly as a user would: the floor and the box
become phantoms, CG objects with several materials are added, and PlateLight's operators set up
the plate, lights from the probe (its sun, sharp) and the differential composite. Outputs:
composites (PNG sequence), a contact sheet (plate | CG | shadows | composite) and stage timings.

Blender runs inside this process (the bpy module); the extension is enabled from this package's
own folder in a throw-away user profile, as the tests do (drivers/headless.py).
"""
from __future__ import annotations

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
from ..addon.imaging import contact_sheet, linear_to_srgb8, write_png
from .headless import EXT_MODULE, blender_with_extension

HDRI = "city"
SIZE = (320, 180)
FRAMES = 4
PLATE_SAMPLES = 32
COMPOSITE_SAMPLES = 16
# the footage's exposure (the camera's): applies to the plate and the CG alike
FILM_EXPOSURE = 0.55
PROBE_SAMPLES = 64   # the bake's default 16 leaves sun fireflies on the floor in the probes
SBRDF_PRESETS = {"CG Plaster Sphere": "marble", "CG Chrome Sphere": "chrome"}


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
    scene.cycles.film_exposure = FILM_EXPOSURE
    scene.render.resolution_x, scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    scene.frame_start, scene.frame_end = 1, frames
    from .. import compat

    world = compat.new_world("Real Place")
    env = world.node_tree.nodes.new("ShaderNodeTexEnvironment")
    env.image = bpy.data.images.load(hdri_path)
    world.node_tree.links.new(env.outputs["Color"], world.node_tree.nodes["Background"].inputs["Color"])
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


def _operator_exists(bpy, name):
    try:
        getattr(bpy.ops.platelight, name).get_rna_type()
        return True
    except (AttributeError, KeyError, RuntimeError):
        return False


def _bake_probes(bpy, objects, force):
    """The scripting contract's bake (the world's own light-importance map is its default, so
    this HDRI's small sun is sampled without fireflies)."""
    bpy.ops.platelight.bake_probes(all_objects=True, force=force)


def _apply_sbrdf_if_available(bpy, objects, timings, maps_dir):
    """Use the PlateLight SBRDF material and per-object probes when that part is installed."""
    if not all(_operator_exists(bpy, name) for name in ("bake_probes", "apply_sbrdf")):
        return False
    scene = bpy.context.scene
    scene.platelight.maps_dir = str(maps_dir)
    scene.platelight.probe_samples = PROBE_SAMPLES
    # materials first: the bake writes only the maps the objects' materials read
    t0 = time.perf_counter()
    for ob in objects:
        ob.platelight.enabled = True
        for other in scene.objects:
            other.select_set(other == ob)
        bpy.context.view_layer.objects.active = ob
        # gold keeps its converted Principled settings; the others take SBRDF presets
        bpy.ops.platelight.apply_sbrdf(preset=SBRDF_PRESETS.get(ob.name, "NONE"))
    timings["apply_sbrdf_s"] = time.perf_counter() - t0
    # Two bakes: in the first, each probe sees the other CG objects with unbound materials; in
    # the second it sees them shaded by their first probes (one bounce of CG-to-CG reflection,
    # as the paper iterates).
    t0 = time.perf_counter()
    for bake_pass in range(2):  # the materials follow each bake (the bake rebinds them)
        _bake_probes(bpy, objects, force=bake_pass > 0)
    timings["bake_probes_s"] = time.perf_counter() - t0
    return True


def run_ar_demo(out_dir, hdri: str = HDRI, frames: int = FRAMES, size=SIZE) -> dict:
    """Run the AR demo into ``out_dir``; returns the timings of every stage (seconds)."""
    out = pathlib.Path(ensure_writable_folder(out_dir))
    hdris = bundled_hdris()
    if hdri not in hdris:
        raise PlateLightError(f"No bundled HDRI named {hdri!r}; choose one of {', '.join(hdris)}.")
    timings = {}
    t_all = time.perf_counter()
    t0 = time.perf_counter()
    bpy = blender_with_extension()
    timings["start_blender_s"] = time.perf_counter() - t0

    # 1. the footage: the real place, filmed (path-traced) along the camera move
    t0 = time.perf_counter()
    scene, real = build_real_place(bpy, hdris[hdri], frames, size)
    scene.cycles.samples = PLATE_SAMPLES
    scene.cycles.use_denoising = True
    scene.view_settings.view_transform = "Standard"
    plate_dir = out / "plate"
    plate_dir.mkdir(exist_ok=True)
    for frame in range(1, frames + 1):
        scene.frame_set(frame)
        _render_still(bpy, scene, str(plate_dir / f"plate_{frame:04d}.exr"))
    timings["film_plate_s"] = time.perf_counter() - t0

    # 2. the user's side: phantoms for the real things, CG objects, plate, lights, composite
    t0 = time.perf_counter()
    for ob in real:
        ob.platelight.phantom = True
    cg = add_cg_objects(bpy, scene)
    scene.platelight.world_probe = hdris[hdri]
    used_sbrdf = _apply_sbrdf_if_available(bpy, cg, timings, out / "probes")
    result = bpy.ops.platelight.setup_plate(filepath=str(plate_dir / "plate_0001.exr"))
    if result != {"FINISHED"}:
        raise PlateLightError("Setting up the demo plate failed.")
    timings["setup_s"] = time.perf_counter() - t0
    # Shadows: the world probe lights the phantoms (the bench, docs/bench/composite.md, measured
    # this faster and closer to the truth in Cycles than lamps from platelight.lights_from_probe)
    bpy.ops.platelight.setup_composite(method="CATCHER", samples=COMPOSITE_SAMPLES, denoise_shadows=True)
    from importlib import import_module

    compositor_tree = import_module(f"{EXT_MODULE}.node_groups.compositor_tree")

    # 3. render the composites (each file appears complete or not at all)
    t0 = time.perf_counter()
    comp_dir = out / "composite"
    comp_dir.mkdir(exist_ok=True)
    rows = []
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
        rows.append([("plate", linear_to_srgb8(passes["Plate"][..., :3])),
                     ("CG", linear_to_srgb8(passes["CG"][..., :3])),
                     ("shadows (ratio)", linear_to_srgb8(np.clip(passes["Shadows"][..., :3], 0, 1))),
                     (f"composite, frame {frame}", linear_to_srgb8(composite))])
    timings["render_composite_s"] = time.perf_counter() - t0
    timings["render_composite_per_frame_s"] = timings["render_composite_s"] / frames

    t0 = time.perf_counter()
    sheet = np.vstack([contact_sheet(row, tile_height=size[1]) for row in rows])
    write_png(out / "contact_sheet.png", sheet)
    timings["contact_sheet_s"] = time.perf_counter() - t0
    timings["total_s"] = time.perf_counter() - t_all
    timings["materials"] = names.SBRDF_GROUP if used_sbrdf else "Principled BSDF (SBRDF part not installed)"
    timings["frames"] = frames
    timings["size"] = list(size)
    write_json_atomic(out / "timings.json", timings)
    print(f"AR demo: {frames} composites in {comp_dir}, contact sheet {out / 'contact_sheet.png'}, "
          f"{timings['total_s']:.1f} s")
    return timings
