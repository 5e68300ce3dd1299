"""Benchmark of AR compositing (issues 6 and 11) against path-traced ground truth, at real sizes.

Scenes: a sphere (diffuse, mirror, glossy, glossy anisotropic, rough metal; and a mirror sphere
beside a red phantom box) on a grey floor under the bundled 'city' HDRI. A 24-frame shot with an orbiting
camera; its first and last frames are path-traced with the sphere (truth) and without (plate),
then the sphere is composited onto the plate by each route: PlateLight (Cycles default,
layered, EEVEE, the paper's model) and Cycles' shadow catcher as Cycles documents it, at 16/64/256
spp with OIDN. PSNR over the object, the shadow and the frame; per-frame time of the shot.
Writes docs/bench/composite.md/.png (480x270) or composite_<W>x<H>.md/.png.

Run: `make bench` (480x270), `make bench-960`, `make bench-1080`, `make bench-gpu` (Cycles on
the GPU, EEVEE on a real GPU; only where one exists). Environment: PLATELIGHT_BENCH_SIZE=WxH,
PLATELIGHT_BENCH_SCENES=diffuse,mirror (a subset), PLATELIGHT_BENCH_TRUTH_SPP,
PLATELIGHT_BENCH_DEVICE=GPU, PLATELIGHT_BENCH_GPU_BACKEND=CUDA (the backend; default the first of
OptiX, CUDA, HIP, oneAPI, Metal with a device), PLATELIGHT_BENCH_LOAD_NOTE (a sentence on the machine's load),
PLATELIGHT_BENCH_EXTRA=layered,ggx (the layered route, the GGX glossy lobes), PLATELIGHT_BENCH_ROUTES=sbrdf,cycles (a
subset of route keys), PLATELIGHT_BENCH_CATCHER_SPP=16,64 (the catcher's sample counts; default
2,4,16,64,256: 2 and 4 are the equal-time points of PlateLight's routes), PLATELIGHT_BENCH_SPP=64
(every other route's sample counts, instead of its own), PLATELIGHT_BENCH_ROWS (the rows file's name beside the report; default <report>_rows.json,
published with it so anyone can re-plot or extend it), PLATELIGHT_BENCH_KEEP_ROWS=1 (re-run a
subset: the rows file's other rows stay, a re-run row replaces its old one, and the report covers
them all).
"""
from __future__ import annotations

import importlib
import json
import math
import os
import pathlib
import sys
import time

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
import support  # noqa: E402
import conftest  # noqa: E402
from platelight.addon.exr_io import read_exr  # noqa: E402
from platelight.addon.ibl import view_lobe  # noqa: E402
from support import compat  # noqa: E402

W, H = 128, 72
TRUTH_SAMPLES = int(os.environ.get("PLATELIGHT_BENCH_TRUTH_SPP", 512))
# A row that does not record its truth's samples was scored against a 256-spp truth.
LEGACY_TRUTH_SAMPLES = 256
HDRI = "city"
CACHE = support.REPO / "bench_out" / "composite"
MATERIALS = {
    "diffuse": dict(colour=(0.7, 0.7, 0.7), roughness=1.0, metallic=0.0),
    "mirror": dict(colour=(0.9, 0.9, 0.9), roughness=0.0, metallic=1.0),
    "glossy": dict(colour=(0.8, 0.5, 0.3), roughness=0.3, metallic=1.0),
    "anisotropic": dict(colour=(0.9, 0.9, 0.9), roughness=0.3, metallic=1.0, anisotropic=0.8),
    # a satin metal: rough lobes are where the maps' shapes depart most from GGX (docs/decisions.md)
    "rough metal": dict(colour=(0.7, 0.7, 0.7), roughness=0.6, metallic=1.0),
}
# setup_composite's arguments per route (the rest are its defaults)
# The defaults path-trace a metal's Principled twin for Cycles' camera; the routes
# about the SBRDF's own shading pin it (metals="SBRDF"), and so do the *(SBRDF)* routes
SBRDF = dict(metals="SBRDF")
SETUP = {"sbrdf": {}, "sbrdf_ggx": SBRDF, "sbrdf_phong": SBRDF, "sbrdf_paper": SBRDF, "lamps": {}, "sunsky": {},
         "cycles": {},
         "sbrdf_layered": dict(method="LAYERED", cg_samples=4, **SBRDF),
         "sbrdf_baked": dict(method="BAKED"),      # listed samples: the CG layer's
         "sbrdf_eevee": dict(engine="EEVEE"),
         "sbrdf_eevee_baked": dict(engine="EEVEE", method="BAKED"),
         "cycles_baked": dict(method="BAKED"),
         "sbrdf_sbrdf": SBRDF, "sbrdf_baked_sbrdf": dict(method="BAKED", **SBRDF),
         "sbrdf_baked_replica": dict(method="BAKED")}
# the shot's shadows baked once
BAKED_ROUTES = ("sbrdf_baked", "sbrdf_eevee_baked", "cycles_baked", "sbrdf_baked_sbrdf", "sbrdf_baked_replica")
# The default route shows the phantoms as a user's scene does by default: the plate on them
# (Phantom Plate; with baked shadows the CG's rays see the filmed plate, shadowed). Every other route keeps the floor's and box's own materials, exact replicas of the truth's.
PLATE_PHANTOM_ROUTES = ("sbrdf_baked",)
# Probes are view-independent: in a shot where the camera moves and the objects stand still (the
# paper's AR case) one bake serves every frame. Times are reported per frame of such a shot too.
SHOT_FRAMES = 24
SPHERE = (np.array([0.0, 0.0, 0.5]), 0.5)


# (location, point looked at, lens mm): the benchmark's view, and a low telephoto one that sees
# the floor in front of the contact point (from 23 degrees up the sphere hides the floor within
# 0.2 m of its contact; below ~15 degrees the near side shows)
CAMERA = ((-2.2, -4.6, 2.2), (-0.3, 0.3, 0.3), 50.0)
LOW_CAMERA = ((0.0, -3.2, 0.7), (0.0, 0.0, 0.15), 100.0)


# a coloured box beside the sphere: a nearby real thing its reflection must show where it is
BOX = dict(centre=(1.0, -0.75, 0.35), size=0.7, colour=(0.8, 0.08, 0.05))


def add_box(bpy, scene, centre, size, colour):
    mesh = bpy.data.meshes.new("Box")
    h = size / 2
    verts = [(x * h, y * h, z * h) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    mesh.from_pydata(verts, [], faces)
    mat = compat().new_material("Box")
    mat.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (*colour, 1)
    mat.node_tree.nodes["Principled BSDF"].inputs["Roughness"].default_value = 0.8
    mesh.materials.append(mat)
    box = bpy.data.objects.new("Box", mesh)
    box.location = centre
    scene.collection.objects.link(box)
    return box


def build(bpy, hdri_path, material, camera=None, box=None):
    bpy.ops.wm.read_homefile(use_empty=True, use_factory_startup=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.render.resolution_x, scene.render.resolution_y = W, H
    scene.render.resolution_percentage = 100
    scene.cycles.use_adaptive_sampling = False
    scene.cycles.seed = 7
    scene.view_settings.view_transform = "Standard"
    # The phantoms here are exact replicas of the real floor and box (the truth renders them), so
    # they keep their own materials, as Cycles' documented catcher set-up does; the default route
    # takes the plate on them, as a user's scene does (PLATE_PHANTOM_ROUTES, composite_shot).
    scene.platelight.phantom_surface = "MATERIAL"
    world = compat().new_world("Probe")
    env = world.node_tree.nodes.new("ShaderNodeTexEnvironment")
    env.image = bpy.data.images.load(hdri_path)
    world.node_tree.links.new(env.outputs["Color"], world.node_tree.nodes["Background"].inputs["Color"])
    scene.world = world
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    scene.collection.objects.link(cam)
    scene.camera = cam
    from mathutils import Vector

    location, target, cam.data.lens = camera or CAMERA
    cam.location = location
    cam.rotation_euler = (Vector(target) - Vector(location)).to_track_quat("-Z", "Y").to_euler()
    floor_mat = compat().new_material("Floor")
    floor_mat.node_tree.nodes.clear()
    diffuse = floor_mat.node_tree.nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = (0.45, 0.45, 0.45, 1)
    out = floor_mat.node_tree.nodes.new("ShaderNodeOutputMaterial")
    floor_mat.node_tree.links.new(diffuse.outputs[0], out.inputs["Surface"])
    mesh = bpy.data.meshes.new("Floor")
    mesh.from_pydata([(-200, -200, 0), (200, -200, 0), (200, 200, 0), (-200, 200, 0)], [], [(0, 1, 2, 3)])
    mesh.materials.append(floor_mat)
    floor = bpy.data.objects.new("Floor", mesh)
    scene.collection.objects.link(floor)
    import bmesh

    smesh = bpy.data.meshes.new("Sphere")
    bm = bmesh.new()
    bmesh.ops.create_uvsphere(bm, u_segments=96, v_segments=48, radius=SPHERE[1])
    bm.to_mesh(smesh)
    bm.free()
    for poly in smesh.polygons:
        poly.use_smooth = True
    mat = compat().new_material("Sphere")
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    bsdf.inputs["Base Color"].default_value = (*material["colour"], 1)
    bsdf.inputs["Roughness"].default_value = material["roughness"]
    bsdf.inputs["Metallic"].default_value = material["metallic"]
    bsdf.inputs["Anisotropic"].default_value = material.get("anisotropic", 0.0)
    smesh.materials.append(mat)
    sphere = bpy.data.objects.new("Sphere", smesh)
    sphere.location = tuple(SPHERE[0])
    scene.collection.objects.link(sphere)
    if box is not None:
        add_box(bpy, scene, **box)
    return scene, floor, sphere


def render(bpy, scene, path):
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.render.filepath = str(path)
    t0 = time.perf_counter()
    bpy.ops.render.render(write_still=True)
    return read_exr(path), time.perf_counter() - t0


def truth_and_plate(bpy, hdri_path, material, folder, samples, camera=None, box=None):
    """One view's path-traced truth (sphere there) and plate (sphere absent) at ``samples`` spp,
    no denoiser, Filter Glossy 0 (Cycles' 1.0 biases mirrors); written to folder/truth.exr and
    folder/plate.exr. The scene is left built (without the sphere hidden) for masks()."""
    images = {}
    for name, with_sphere in (("truth", True), ("plate", False)):
        scene, _floor, sphere = build(bpy, hdri_path, material, camera, box)
        scene.cycles.samples = samples
        scene.cycles.use_denoising = False
        scene.cycles.blur_glossy = 0.0
        sphere.hide_render = not with_sphere
        images[name], _ = render(bpy, scene, pathlib.Path(folder) / f"{name}.exr")
    build(bpy, hdri_path, material, camera, box)
    return images["truth"], images["plate"]


def composite(bpy, hdri_path, material, plate_path, route, samples, out_path, camera=None, box=None):
    """(composite image, seconds of the probe bake, seconds of everything else for one frame)."""
    scene, floor, sphere = build(bpy, hdri_path, material, camera, box)
    floor.platelight.phantom = True
    if box is not None:
        scene.objects["Box"].platelight.phantom = True
    bake_s = 0.0
    t0 = time.perf_counter()
    if route == "lamps":
        scene.platelight.world_probe = hdri_path
        assert bpy.ops.platelight.lights_from_probe(mode="LIGHTS", count=16) == {"FINISHED"}
    elif route == "sunsky":
        assert bpy.ops.platelight.lights_from_probe(mode="SUN_SKY") == {"FINISHED"}
    else:
        bake_s = bake_route(bpy, scene, sphere, route, out_path)
    assert bpy.ops.platelight.setup_plate(filepath=str(plate_path)) == {"FINISHED"}
    assert bpy.ops.platelight.setup_composite(**setup_arguments(route, samples)) == {"FINISHED"}
    setup = time.perf_counter() - t0 - bake_s
    image, render_time = render(bpy, scene, out_path)
    return image, bake_s, setup + render_time


def maps_folder(out_path):
    """Where a route rendering ``out_path`` keeps its probes and baked shadows."""
    return str(pathlib.Path(out_path).with_suffix("")) + "_probes"


def bake_route(bpy, scene, sphere, route, out_path):
    """The route's bakes, into maps_folder(out_path): the sphere's SBRDF and probe for the sbrdf
    routes, the shot's shadows for the baked ones; their seconds."""
    scene.platelight.maps_dir = maps_folder(out_path)
    bake_s = 0.0
    if route.startswith("sbrdf"):
        bake_s = sbrdf_sphere(bpy, scene, sphere, out_path, paper=route == "sbrdf_paper", route=route)
    return bake_s + bake_route_shadows(bpy, route)


def bake_route_shadows(bpy, route):
    """The baked route's one shadow bake for the shot (the operator's defaults); its seconds."""
    if route not in BAKED_ROUTES:
        return 0.0
    t0 = time.perf_counter()
    assert bpy.ops.platelight.bake_shadows() == {"FINISHED"}
    return time.perf_counter() - t0


def setup_arguments(route, samples):
    """setup_composite's arguments for ``route`` at ``samples`` (the baked route's CG layer's)."""
    arguments = dict(SETUP[route], samples=samples, denoise_shadows=True)
    if route in BAKED_ROUTES:
        arguments["cg_samples"] = samples
    return arguments


def sbrdf_sphere(bpy, scene, sphere, out_path, paper=False, route="sbrdf", frame_range=False):
    """The paper's CG: the sphere's Principled settings converted to the PlateLight SBRDF, shaded
    from its own probe (baked from its centre: floor + world). ``paper``: the paper's model as
    written (cosine falloff g', diffuse and specular added in full, the owner hidden in its probe)
    instead of PlateLight's defaults; ``frame_range``: a probe for every frame of the scene's range
    (a moving sphere's). Returns the seconds the bake took."""
    from bl_ext.dev.platelight.node_groups import ray_twin, sbrdf_material

    scene.platelight.maps_dir = maps_folder(out_path)
    scene.platelight.probe_owner_shadows = not paper
    scene.platelight.probe_sun_lobe = not paper        # the paper's maps hold their sun
    # the product's default (View-Dependent GGX) unless the route names the lobes; the paper's are Phong
    scene.platelight.glossy_lobes = GLOSSY_LOBES.get(route, "phong" if paper else view_lobe.MODE)
    sphere.platelight.enabled = True
    bpy.context.view_layer.objects.active = sphere
    sphere.select_set(True)
    assert bpy.ops.platelight.apply_sbrdf(preset="NONE") == {"FINISHED"}
    if paper:
        material = sphere.active_material
        params = sbrdf_material.read_params(material)
        params.paper_falloff = 1.0
        sbrdf_material.write_params(material, params)
        ray_twin.set_emission_for_all_rays(material, True)   # the emission lights the phantoms
    t0 = time.perf_counter()
    # the scripting contract's bake, with the world's full importance map (its default)
    assert bpy.ops.platelight.bake_probes(all_objects=True, force=True, use_frame_range=frame_range) == {"FINISHED"}
    return time.perf_counter() - t0


def psnr(a, b, mask, peak):
    err = np.mean((np.clip(a, 0, peak) - np.clip(b, 0, peak))[mask] ** 2)
    return float(10 * np.log10(peak ** 2 / max(err, 1e-20)))


def masks(truth, plate, centre=SPHERE[0]):
    """object: pixels whose centre ray meets the sphere at ``centre`` (analytic, eroded a pixel);
    shadow: floor pixels the truth shows more than 3 % darker than the plate."""
    import cv2
    import bpy

    scene = bpy.context.scene
    bpy.context.view_layer.update()  # matrix_world of a camera just placed
    cam = scene.camera
    tr, br, bl, tl = (np.array(cam.matrix_world @ v) for v in cam.data.view_frame(scene=scene))
    u = (np.arange(W) + 0.5) / W
    v = (np.arange(H) + 0.5) / H
    top = tl + u[:, None] * (tr - tl)
    bottom = bl + u[:, None] * (br - bl)
    pts = top[None] + v[:, None, None] * (bottom - top)[None]
    origin = np.array(cam.matrix_world.translation)
    d = pts - origin
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    oc = origin - np.asarray(centre)
    b = d @ oc
    hit = b * b - (oc @ oc - SPHERE[1] ** 2) >= 0
    obj = cv2.erode(hit.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    near = cv2.dilate(hit.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)
    lum = np.array([0.2126, 0.7152, 0.0722])
    darker = (truth @ lum) < 0.97 * (plate @ lum)
    shadow = darker & ~near
    return obj, shadow


def contact_mask(radius=0.2):
    """Visible floor pixels whose centre ray meets z = 0 within ``radius`` m of the sphere's
    contact point (the ring a resting object darkens most), away from the sphere's silhouette."""
    import cv2
    import bpy

    scene = bpy.context.scene
    bpy.context.view_layer.update()
    cam = scene.camera
    tr, br, bl, tl = (np.array(cam.matrix_world @ v) for v in cam.data.view_frame(scene=scene))
    u = (np.arange(W) + 0.5) / W
    v = (np.arange(H) + 0.5) / H
    top = tl + u[:, None] * (tr - tl)
    bottom = bl + u[:, None] * (br - bl)
    pts = top[None] + v[:, None, None] * (bottom - top)[None]
    origin = np.array(cam.matrix_world.translation)
    d = pts - origin
    t = -origin[2] / d[..., 2]
    ground = origin + t[..., None] * d
    contact = SPHERE[0] - np.array([0.0, 0.0, SPHERE[1]])
    near_contact = (t > 0) & (np.linalg.norm(ground - contact, axis=-1) < radius)
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    oc = origin - SPHERE[0]
    b = d @ oc
    hit = b * b - (oc @ oc - SPHERE[1] ** 2) >= 0
    near = cv2.dilate(hit.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    return near_contact & ~near


def darkening(image, plate, mask):
    """1 - (mean luminance of ``image`` / mean luminance of the plate) over ``mask``."""
    lum = np.array([0.2126, 0.7152, 0.0722])
    return float(1.0 - (image[mask] @ lum).mean() / (plate[mask] @ lum).mean())


# ------------------------------------------------------------------ the shot benchmark (issue 11)

SIZE = os.environ.get("PLATELIGHT_BENCH_SIZE", "480x270")
# Scenes of the shot benchmark: (material, with the coloured phantom box beside the sphere)
SHOT_SCENES = {       # in the order they run: a run stopped early reports what it has
    "mirror + box": ("mirror", True), "mirror": ("mirror", False), "glossy": ("glossy", False),
    "diffuse": ("diffuse", False), "anisotropic": ("anisotropic", False),
    "rough metal": ("rough metal", False),
}
SHOT_ROUTES = (("platelight", "sbrdf", (4, 16)), ("platelight baked", "sbrdf_baked", (1, 4, 16, 64)),
               ("platelight eevee", "sbrdf_eevee", (4,)),
               ("platelight eevee baked", "sbrdf_eevee_baked", (4,)),
               ("platelight (paper)", "sbrdf_paper", (16,)), ("catcher", "cycles", (2, 4, 16, 64, 256)))
# measured at 96x54 and left out of the default run: no better than the one-layer default there
EXTRA_ROUTES = {"layered": ("platelight layered", "sbrdf_layered", (16,)),
                # the glossy maps blurred with GGX's lobes (scene setting Glossy Lobes)
                "ggx": ("platelight ggx lobes", "sbrdf_ggx", (4, 16)),
                # the four Phong maps read round (the paper's lobes)
                "phong": ("platelight phong lobes", "sbrdf_phong", (4, 16)),
                # the Principled sphere path-traced in the CG layer over the baked shadows
                "principled": ("principled baked", "cycles_baked", (4, 16)),
                # a metal shaded by its SBRDF (a dielectric's default)
                "sbrdf": ("platelight (SBRDF)", "sbrdf_sbrdf", (4, 16)),
                "sbrdf_baked": ("platelight baked (SBRDF)", "sbrdf_baked_sbrdf", (1, 4, 16)),
                # the phantoms' own (replica) materials, path-traced
                "replica": ("platelight baked (replica phantoms)", "sbrdf_baked_replica", (1, 4, 16, 64))}
GLOSSY_LOBES = {"sbrdf_ggx": "ggx", "sbrdf_phong": "phong"}     # the routes that set Glossy Lobes
SHOT_REFERENCE = "catcher"
# The shot: the camera orbits 20 degrees about the sphere over 24 frames; rendered and scored are
# its first and last frames (scene frames 1 and 2 of the benchmark's plate sequence).
ORBIT_DEGREES = 20.0
RENDER_FRAMES = (1, SHOT_FRAMES)
# Scored against path-traced truth: the last (a warm frame). On this 2-core machine a 480x270
# truth takes 10+ minutes under load; the first frame is rendered for its time only.
SCORED_FRAMES = (SHOT_FRAMES,)
TIMING_PLATE_SAMPLES = 32
BOX_VIEW = ((-0.9, -4.4, 1.4), (0.25, -0.2, 0.45), 50.0)


def shot_camera(frame, box):
    """(location, target, lens) of shot frame 1..24: the orbit about the sphere's vertical axis."""
    location, target, lens = BOX_VIEW if box else CAMERA
    angle = math.radians(ORBIT_DEGREES) * (frame - 1) / (SHOT_FRAMES - 1)
    c, s = math.cos(angle), math.sin(angle)
    x, y, z = location
    return ((c * x - s * y, s * x + c * y, z), target, lens)


def key_shot_camera(scene, box, frames=None):
    """Key the camera at scene frames 1, 2, ... to the shot frames ``frames`` (RENDER_FRAMES)."""
    frames = frames or RENDER_FRAMES
    from mathutils import Vector

    cam = scene.camera
    for index, frame in enumerate(frames, start=1):
        location, target, lens = shot_camera(frame, box)
        cam.location = location
        cam.rotation_euler = (Vector(target) - Vector(location)).to_track_quat("-Z", "Y").to_euler()
        cam.data.lens = lens
        cam.keyframe_insert("location", frame=index)
        cam.keyframe_insert("rotation_euler", frame=index)
    scene.frame_start, scene.frame_end = 1, len(frames)
    scene.frame_set(1)


def shot_truths(bpy, hdri_path, name, material, box, folder):
    """Path-traced truth (sphere there) and plate (sphere absent) of the scored shot frames,
    cached; plates as the sequence plate_0001.exr... for setup_plate. Frames rendered for timing
    only get a cheap plate (TIMING_PLATE_SAMPLES + OIDN) and no truth."""
    folder.mkdir(parents=True, exist_ok=True)
    truths, plates = [], []
    plate_dir = folder / ("plates_box" if box else "plates")
    for index, frame in enumerate(RENDER_FRAMES, start=1):
        scored = frame in SCORED_FRAMES
        for kind, with_sphere in (("truth", True), ("plate", False)):
            if with_sphere and not scored:
                continue
            path = (folder / f"truth_{name.replace(' + ', '_')}_{index:04d}.exr" if with_sphere
                    else plate_dir / f"plate_{index:04d}.exr")
            if not path.exists():
                path.parent.mkdir(parents=True, exist_ok=True)
                scene, _floor, sphere = build(bpy, hdri_path, material, shot_camera(frame, box),
                                              BOX if box else None)
                scene.cycles.samples = TRUTH_SAMPLES if scored else TIMING_PLATE_SAMPLES
                scene.cycles.use_denoising = not scored
                scene.cycles.blur_glossy = 0.0        # Filter Glossy 0: Cycles' 1.0 biases mirrors
                set_device(scene)
                sphere.hide_render = not with_sphere
                _, took = render(bpy, scene, path)
                print(f"{path.name}: {took:.1f} s", flush=True)     # a stalled run shows where
            if scored:
                (truths if with_sphere else plates).append(read_exr(path))
    return truths, plates, plate_dir / "plate_0001.exr"


def composite_shot(bpy, hdri_path, material, box, route, samples, plate_path, out_dir):
    """Set up the route once (the bake serves the shot), then render the shot's frames in one
    Blender session with persistent data. Returns (images, bake_s, setup_s, [seconds per frame])."""
    scene, floor, sphere = build(bpy, hdri_path, material, shot_camera(1, box), BOX if box else None)
    if route in PLATE_PHANTOM_ROUTES:
        scene.platelight.phantom_surface = "PLATE"
    key_shot_camera(scene, box)
    scene.render.use_persistent_data = True
    set_device(scene)
    floor.platelight.phantom = True
    if box:
        scene.objects["Box"].platelight.phantom = True
    out_dir.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    bake_s = bake_route(bpy, scene, sphere, route, out_dir / "frame")
    assert bpy.ops.platelight.setup_plate(filepath=str(plate_path)) == {"FINISHED"}
    assert bpy.ops.platelight.setup_composite(**setup_arguments(route, samples)) == {"FINISHED"}
    setup_s = time.perf_counter() - t0 - bake_s
    images, seconds = [], []
    for index in range(1, len(RENDER_FRAMES) + 1):
        scene.frame_set(index)
        image, took = render(bpy, scene, out_dir / f"frame_{index:04d}.exr")
        images.append(image)
        seconds.append(took)
    return images, bake_s, setup_s, seconds


DEVICE = os.environ.get("PLATELIGHT_BENCH_DEVICE", "CPU")
# Tried in this order; PLATELIGHT_BENCH_GPU_BACKEND=CUDA picks one (on a GPU without RT cores,
# or one Blender ships no binary kernel for, CUDA skips OptiX's own compile of its kernels).
GPU_BACKENDS = tuple(b for b in os.environ.get("PLATELIGHT_BENCH_GPU_BACKEND", "OPTIX,CUDA,HIP,ONEAPI,METAL").split(",") if b)


def use_gpu(bpy) -> str | None:
    """Switch Cycles to the first GPU backend with a device; its name, or None without one."""
    prefs = bpy.context.preferences.addons["cycles"].preferences
    for backend in GPU_BACKENDS:
        try:
            prefs.compute_device_type = backend
        except TypeError:
            continue
        prefs.get_devices()
        gpus = [d for d in prefs.devices if d.type == backend]
        if gpus:
            for d in prefs.devices:
                d.use = d.type == backend
            return backend
    return None


def set_device(scene):
    scene.cycles.device = "GPU" if DEVICE == "GPU" else "CPU"


def pooled_psnr(images, truths, masks_, peak):
    err = np.concatenate([((np.clip(a, 0, peak) - np.clip(b, 0, peak))[m] ** 2).ravel()
                          for a, b, m in zip(images, truths, masks_)])
    return float(10 * np.log10(peak ** 2 / max(float(err.mean()), 1e-20)))


def main(out_dir: pathlib.Path) -> None:
    global W, H
    W, H = (int(v) for v in SIZE.split("x"))
    bpy = conftest._import_bpy_with_extension()
    backend = use_gpu(bpy) if DEVICE == "GPU" else "CPU"
    if backend is None:
        raise SystemExit("make bench-gpu: Cycles finds no GPU on this machine (OptiX, CUDA, HIP, "
                         "oneAPI, Metal); run `make bench` for the CPU benchmark.")
    # The probe groups' templates are built once per machine and add-on version, and cached on
    # disk: a user's shots do not pay that build, so no row should
    importlib.import_module(f"{support.EXT_MODULE}.node_groups.probe_maps").prepare_templates()
    hdri_path = str(pathlib.Path(bpy.utils.system_resource("DATAFILES", path="studiolights/world")) / f"{HDRI}.exr")
    folder = CACHE / (SIZE if DEVICE == "CPU" else f"{SIZE}_{DEVICE.lower()}")
    only = os.environ.get("PLATELIGHT_BENCH_SCENES")
    out_dir.mkdir(parents=True, exist_ok=True)
    rows_file = out_dir / os.environ.get("PLATELIGHT_BENCH_ROWS", f"{report_stem()}_rows.json")
    rows = json.loads(rows_file.read_text()) if os.environ.get("PLATELIGHT_BENCH_KEEP_ROWS") \
        and rows_file.exists() else []
    for name, (material_name, box) in SHOT_SCENES.items():
        if only and name not in only.split(","):
            continue
        material = MATERIALS[material_name]
        truths, plates, plate_path = shot_truths(bpy, hdri_path, name, material, box, folder)
        obj_masks, shadow_masks = [], []
        for index, frame in enumerate(SCORED_FRAMES):
            build(bpy, hdri_path, material, shot_camera(frame, box), BOX if box else None)
            obj, shadow = masks(truths[index], plates[index])
            obj_masks.append(obj)
            shadow_masks.append(shadow)
        peak = float(np.percentile(np.concatenate([t.ravel() for t in truths]), 99.5))
        everything = [np.ones_like(m) for m in obj_masks]
        extra = [EXTRA_ROUTES[k] for k in os.environ.get("PLATELIGHT_BENCH_EXTRA", "").split(",") if k]
        keys = os.environ.get("PLATELIGHT_BENCH_ROUTES")          # e.g. "sbrdf_layered": a subset
        catcher_spp = os.environ.get("PLATELIGHT_BENCH_CATCHER_SPP")   # e.g. "16,64": a subset
        only_spp = os.environ.get("PLATELIGHT_BENCH_SPP")              # e.g. "64": every other route's, instead
        for route, key, sample_counts in (*SHOT_ROUTES, *extra):
            if keys and key not in keys.split(","):
                continue
            if key == "cycles" and catcher_spp:
                sample_counts = tuple(int(v) for v in catcher_spp.split(","))
            elif only_spp:
                sample_counts = tuple(int(v) for v in only_spp.split(","))
            for samples in sample_counts:
                tag = f"{name.replace(' + ', '_')}_{key}_{samples}"
                images, bake_s, setup_s, seconds = composite_shot(
                    bpy, hdri_path, material, box, key, samples, plate_path, folder / tag)
                warm = seconds[-1]
                images = [image for image, frame in zip(images, RENDER_FRAMES) if frame in SCORED_FRAMES]
                row = dict(material=name, route=route, samples=samples, bake_s=bake_s,
                           setup_s=setup_s, first_s=seconds[0], warm_s=warm,
                           shot_s=(bake_s + setup_s + seconds[0] + (SHOT_FRAMES - 1) * warm) / SHOT_FRAMES,
                           psnr_object=pooled_psnr(images, truths, obj_masks, peak),
                           psnr_shadow=pooled_psnr(images, truths, shadow_masks, peak),
                           psnr_all=pooled_psnr(images, truths, everything, peak),
                           object_px=int(obj_masks[0].sum()), shadow_px=int(shadow_masks[0].sum()),
                           truth_spp=TRUTH_SAMPLES, load=os.getloadavg()[0], device=backend)
                _put_row(rows, row)
                print(row, flush=True)
                rows_file.write_text(json.dumps(rows, indent=1))
        write_report(out_dir, rows)          # after each scene: a long run reports what it has


def write_table(out_dir, stem, title, doc, script, header, lines):
    """docs/bench/<stem>.md of a benchmark that reuses this one's scene: its title, the second
    paragraph of its docstring ``doc``, who produced it and the load, then the table."""
    text = [title, "", " ".join(doc.split("\n\n")[1].split()), "",
            f"Produced by `tests/bench/{script}`; load average when it finished: {os.getloadavg()[0]:.1f}.", "",
            *header, *lines]
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / f"{stem}.md").write_text("\n".join(text) + "\n")


def _put_row(rows, row):
    """Replace the row of the same scene, route and samples (a re-run), else append."""
    same = [i for i, r in enumerate(rows)
            if (r["material"], r["route"], r["samples"]) == (row["material"], row["route"], row["samples"])]
    if same:
        rows[same[0]] = row
    else:
        rows.append(row)


def equal_time_and_error(rows, material, route, key):
    """Against the reference route (Cycles' catcher), per material and for one PSNR ``key``:
    the most dB this route gains at equal per-frame time (the catcher's PSNR interpolated in log
    time; before its fastest point its fastest point is used, which favours the catcher), and the
    largest speed-up at equal error (the catcher's time to reach this route's PSNR, interpolated).
    A speed-up is a string when it is a bound: "≤ N×" where this route is worse than the
    catcher's fastest point (the catcher would get there with fewer samples than were measured),
    "> N×" where it is better than the catcher's best (the catcher does not get there within its
    slowest measured point, so it needs more than N× this route's time)."""
    ours = [r for r in rows if r["material"] == material and r["route"] == route]
    if not ours:
        return None, None
    truth = truth_samples(ours[0])          # only rows scored against the same truth compare
    ref = sorted((r["shot_s"], r[key]) for r in rows if r["material"] == material
                 and r["route"] == SHOT_REFERENCE and truth_samples(r) == truth)
    ours = [(r["shot_s"], r[key]) for r in ours if truth_samples(r) == truth]
    if not ref:
        return None, None
    ref_t = np.log([t for t, _ in ref])
    ref_p = np.array([p for _, p in ref])
    best = np.maximum.accumulate(ref_p)                 # the catcher's best so far, by time
    gains, speedups = [], []                            # speed-ups: (value, "exact" | "upper" | "lower")
    for t, p in ours:
        gains.append(p - float(np.interp(np.log(t), ref_t, ref_p)))
        if p > best[-1]:
            speedups.append((float(np.exp(ref_t[-1])) / t, "lower"))
        elif p <= best[0]:
            speedups.append((float(np.exp(ref_t[0])) / t, "upper"))
        else:
            speedups.append((float(np.exp(np.interp(p, best, ref_t))) / t, "exact"))
    known = [s for s in speedups if s[1] != "upper"]
    value, kind = max(known or speedups)
    return max(gains), {"exact": value, "upper": f"≤ {value:.2f}×", "lower": f"> {value:.2f}×"}[kind]


def truth_samples(row) -> int:
    return row.get("truth_spp", LEGACY_TRUTH_SAMPLES)


LOAD_NOTE = os.environ.get("PLATELIGHT_BENCH_LOAD_NOTE", "")


def report_stem() -> str:
    """The report's file name without suffix: composite[_<W>x<H>][_gpu]."""
    stem = "composite" if SIZE == "480x270" else f"composite_{SIZE}"
    return stem if DEVICE == "CPU" else f"{stem}_{DEVICE.lower()}"


def write_report(out_dir, rows):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir.mkdir(parents=True, exist_ok=True)
    stem = report_stem()
    lines = [
        f"# Compositing benchmark at {SIZE.replace('x', '×')} (issue 11)",
        "",
        f"A sphere on a grey floor under the bundled `{HDRI}` HDRI, as diffuse, mirror, glossy copper, "
        "glossy anisotropic metal, and a mirror sphere beside a red phantom box (a nearby real thing). "
        f"The shot: {SHOT_FRAMES} frames, the camera orbiting {ORBIT_DEGREES:.0f}° about the sphere; its "
        f"frames {RENDER_FRAMES[0]} and {RENDER_FRAMES[-1]} are rendered in one Blender session (timed), frame(s) "
        f"{', '.join(map(str, SCORED_FRAMES))} scored. Truth: Cycles "
        f"path-traced with the sphere there ({TRUTH_SAMPLES} spp in this run; each row's *truth spp* column "
        "says which truth it was scored against), no denoiser, Filter Glossy 0; plate: the "
        "same without the sphere. PSNR (dB, peak = the truth's 99.5th percentile) over the sphere, "
        "over its shadow on the floor (truth > 3 % darker than the plate) and over the frame.",
        "",
        "Routes. *catcher*: what Blender users do today, as Cycles documents it: Principled sphere, "
        "the floor (and box) as shadow catchers, the plate times the Shadow Catcher pass, then the CG "
        "over it, OIDN on the catcher pass and on the CG where it covers the pixel (PlateLight's compositor group does exactly "
        "this). *platelight*: `setup_composite`'s defaults with the sphere converted to the "
        "PlateLight SBRDF (those defaults show Cycles' camera a metal's Principled twin, "
        "path-traced and denoised; *platelight (SBRDF)* and *platelight baked (SBRDF)* pin the SBRDF, "
        "`metals='SBRDF'`) and shaded from its own probe (one bake at the scene's default probe "
        "samples, sized to the sphere on screen, serves the shot): camera rays see the SBRDF, every other ray its Principled twin; parallax-corrected "
        "specular look-ups; shadow pass denoised, the CG only where it covers the pixel and only for the sharp mirror (a smooth SBRDF is not). *platelight baked*: the same sphere, the shot's "
        "shadows baked once (`bake_shadows()` defaults: a 512-row panorama at 16 spp, only its rows that see a "
        "phantom, one render of Cycles' Shadow Catcher pass, that pass "
        "alone denoised, at most 3 diffuse bounces; "
        "its time is in *bake*), `setup_composite(method='BAKED')` with the listed samples for the "
        "CG layer and its default one sample for the baked shadows' layer; no path tracing per frame; "
        "with the phantoms' default surface, the plate (a user's scene has no replica of the real floor): the CG "
        "layer's rays meet the phantoms as the camera filmed them, times the baked ratio (docs/decisions.md, "
        "\"Filmed phantoms\"). *platelight baked (replica phantoms)* (`PLATELIGHT_BENCH_EXTRA=replica`): the same "
        "with the floor's and box's own materials, exact replicas of the truth's, path-traced in the CG's reflections "
        "(the replicas a user's scene lacks). Every other route keeps the replicas. *platelight layered*: the CG in its own layer at "
        "4 spp, the shadows in a catcher layer at the listed samples. *platelight eevee*: "
        "`setup_composite(engine='EEVEE')`, Debevec's three layers rasterised (software GL here), "
        "listed samples = TAA samples. *platelight eevee baked*: the shot's shadows baked as for "
        "*platelight baked*, then `setup_composite(engine='EEVEE', method='BAKED')`: EEVEE renders "
        "the two emission-only layers. *platelight (paper)*: the paper's model as written (cosine "
        "falloff, diffuse and specular added in full, owner hidden in its probe, the emission "
        "lighting the phantoms), still with parallax. *principled baked* (`PLATELIGHT_BENCH_EXTRA=principled`): "
        "the catcher's Principled sphere, not converted, path-traced in the CG layer at the listed "
        "samples (OIDN where it covers the pixel) over the shadows baked as for *platelight baked*.",
        "",
        "Times (s): *bake* the probe bake (and the baked route's shadow bake), *setup* plate + composite set-up, *first* the first "
        "frame's render (scene sync, shader compilation), *warm* a later frame (persistent data), "
        f"*per frame* = (bake + setup + first + {SHOT_FRAMES - 1} × warm) / {SHOT_FRAMES}. "
        "Produced by `tests/bench/bench_composite.py` (`make bench`; "
        "`PLATELIGHT_BENCH_SIZE=960x540` for `make bench-960`).",
    ]
    loads = [r["load"] for r in rows if "load" in r]
    if LOAD_NOTE or loads:
        runs = ("the rows were timed in separate runs, and identical runs differ by about 15 %, so read "
                "speed-ups within that. " if os.environ.get("PLATELIGHT_BENCH_KEEP_ROWS")
                else "every row was timed in this run. ")
        lines += ["", f"**Machine load.** A shared {os.cpu_count()}-core machine, Cycles on the {DEVICE}; "
                  + runs + (LOAD_NOTE + " " if LOAD_NOTE else "") + (
            f"The 1-minute load average (2 cores) when each row finished: median "
            f"{np.median(loads):.1f}, range {min(loads):.1f}–{max(loads):.1f}." if loads else "")]
    lines += ["", "| scene | route | spp | bake | setup | first | warm | per frame | PSNR object | PSNR shadow | PSNR frame | truth spp |",
              "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {r['material']} | {r['route']} | {r['samples']} | {r['bake_s']:.1f} | "
                     f"{r['setup_s']:.1f} | {r['first_s']:.1f} | {r['warm_s']:.1f} | {r['shot_s']:.1f} | "
                     f"{r['psnr_object']:.1f} | {r['psnr_shadow']:.1f} | {r['psnr_all']:.1f} | {truth_samples(r)} |")
    if rows:
        lines += ["", f"Mask sizes (frame 1 of the first scene): object {rows[0]['object_px']} px, "
                  f"shadow {rows[0]['shadow_px']} px."]
    catcher_spp = [r["samples"] for r in rows if r["route"] == SHOT_REFERENCE] or [0]
    fewest = min(catcher_spp)
    lines += ["", "## Against Cycles' shadow catcher (the issue's goal)", "",
              "Per scene and route: the most dB gained over the catcher at equal time per frame "
              "(its PSNR interpolated in log time; before its fastest point, its fastest point), "
              "and the largest speed-up at equal PSNR (> N× where the route is better than the catcher "
              "at the most samples measured for that scene, so the catcher needs more than N× its time; "
              f"≤ N× where the route is worse than the catcher at {fewest} spp, so N is "
              "only an upper bound). Goal: ≥ 10× faster at equal error on object and shadow, mirror "
              "≥ 40 dB and glossy ≥ 38 dB object PSNR.", "",
              "| scene | route | gain object | gain shadow | gain frame | speed-up object | speed-up shadow | speed-up frame |",
              "|---|---|---:|---:|---:|---:|---:|---:|"]
    scenes = list(dict.fromkeys(r["material"] for r in rows))
    routes = list(dict.fromkeys(r["route"] for r in rows))
    fmt = (lambda x: "—" if x is None else x if isinstance(x, str) else f"{x:.2f}×")   # — : no catcher rows
    for scene_name in scenes:
        for route in routes:
            if route == SHOT_REFERENCE:
                continue
            cells = [equal_time_and_error(rows, scene_name, route, key)
                     for key in ("psnr_object", "psnr_shadow", "psnr_all")]
            if cells[0][0] is None:
                continue
            lines.append(f"| {scene_name} | {route} | " + " | ".join(f"{g:+.1f}" for g, _ in cells)
                         + " | " + " | ".join(fmt(sp) for _, sp in cells) + " |")
    (out_dir / f"{stem}.md").write_text("\n".join(lines) + "\n")
    fig, axes = plt.subplots(1, 3, figsize=(16, 4.6))
    palette = ("tab:red", "tab:orange", "tab:green", "tab:purple", "tab:blue", "tab:brown", "tab:gray",
               "tab:olive", "tab:cyan", "tab:pink", "black", "gold")
    colours = {route: palette[i % len(palette)] for i, route in enumerate(routes)}
    for ax, key, title in ((axes[0], "psnr_object", "object"), (axes[1], "psnr_shadow", "shadow"),
                           (axes[2], "psnr_all", "frame")):
        for scene_name, marker in zip(scenes, "osD^vP"):
            for route in routes:
                pts = sorted((r["shot_s"], r[key]) for r in rows if r["material"] == scene_name and r["route"] == route)
                if pts:
                    xs, ys = zip(*pts)
                    ax.plot(xs, ys, marker=marker, color=colours[route], label=f"{route}, {scene_name}")
        ax.set_xscale("log")
        ax.set_xlabel(f"seconds per frame of the {SHOT_FRAMES}-frame shot")
        ax.set_ylabel("PSNR vs path-traced truth (dB)")
        ax.set_title(f"{title}, {SIZE}")
        ax.grid(True, alpha=0.3)
    axes[2].legend(fontsize=5.5, ncol=2)
    fig.tight_layout()
    fig.savefig(out_dir / f"{stem}.png", dpi=110)


if __name__ == "__main__":
    main(support.REPO / "docs" / "bench")
