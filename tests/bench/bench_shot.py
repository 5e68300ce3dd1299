"""The shot benchmark against Cycles' shadow catcher, in one invocation (issue 47's protocol).

Each scene is a CG object on stand-ins for real surfaces (phantoms) under an environment, filmed
by a camera orbiting 20 degrees over a 24-frame shot; frames 1, 12 and 24 are rendered and scored.
In a moving scene the CG moves over the shot (the sphere rolls across the floor, a textured
Suzanne turns in place, a column bends on an armature), and every frame's work that the route
needs (a per-frame probe or shadow bake) is done for all 24; the default route's samples are then
both its CG layer's and the moving shadows' catcher layer's.
The truth is Cycles path-traced with the CG there, the plate the same without it, each the mean
of two halves of independent seeds: the halves' difference is the truth's own noise, so every
score is judged against the truth's ceiling. The routes follow the user's order (plate first,
then the bakes) and run interleaved: each row of a scene once, then each again, three times, so
the machine's load falls on all alike; times are the median of the repeats, with their spread.
The reference is the shadow catcher as a skilled artist sets it up (tests/shot_catcher.py).

Writes docs/bench/<name>_<W>x<H>.md, .png and _rows.json from this run alone (name: shot, or
PLATELIGHT_BENCH_NAME; `make bench-motion` runs the moving scenes as "motion").

Run: `make bench-shot` (960x540; `make bench-shot-gpu` with Cycles on a GPU). Environment: PLATELIGHT_BENCH_SIZE=WxH,
PLATELIGHT_BENCH_SCENES="a;b" (a subset, by name), PLATELIGHT_BENCH_REPEATS (3),
PLATELIGHT_BENCH_TRUTH_HALF_SPP (each truth half's samples; 1024),
PLATELIGHT_BENCH_CATCHER_SPP=4,16,64,256,1024, PLATELIGHT_BENCH_CG_SPP=1,4,16 (the default route's
samples), PLATELIGHT_BENCH_ROUTES=platelight,catcher (a subset of route keys).
"""
from __future__ import annotations

import dataclasses
import json
import os
import pathlib
import sys
import time

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
sys.path.insert(0, str(HERE))
import bench_composite as bc  # noqa: E402  (the sphere, the box, the camera and render())
import conftest  # noqa: E402
import shot_catcher  # noqa: E402
import shot_protocol as sp  # noqa: E402
import support  # noqa: E402
from platelight.addon.exr_io import read_exr, write_exr  # noqa: E402
from support import compat  # noqa: E402

SIZE = os.environ.get("PLATELIGHT_BENCH_SIZE", "960x540")
REPEATS = int(os.environ.get("PLATELIGHT_BENCH_REPEATS", 3))
TRUTH_HALF_SPP = int(os.environ.get("PLATELIGHT_BENCH_TRUTH_HALF_SPP", 1024))
SHOT_FRAMES = bc.SHOT_FRAMES
SCORED_FRAMES = (1, 12, 24)
CACHE = support.REPO / "bench_out" / "shot"


@dataclasses.dataclass(frozen=True)
class Scene:
    hdri: str              # a bundled HDRI's name, or one of ball_corpus.ANALYTIC
    floor: str             # "grey" (Lambertian), "photo" (a photograph's texture), "tiles" (glossy)
    material: str          # a bench_composite.MATERIALS key
    box: bool = False      # a red phantom box beside the sphere
    noise: float = 0.0     # the plate's sensor noise (standard deviation at mid-grey)
    moves: str = ""        # over the shot the CG "rolls" (the sphere across the floor), "turns"
                           # (a textured Suzanne in place) or "bends" (a column on an armature)

    @property
    def moving(self) -> bool:
        return bool(self.moves)


# in the order they run: a run stopped early reports what it has
SCENES = {
    "hard sun, photo floor, diffuse": Scene("hard_sun", "photo", "diffuse"),
    "city, grey floor, mirror + box": Scene("city", "grey", "mirror", box=True),
    "overcast, glossy tiles, glossy": Scene("overcast", "tiles", "glossy"),
    "lamp room, grey floor, anisotropic": Scene("lamp_room", "grey", "anisotropic"),
    "city, noisy plate, diffuse": Scene("city", "photo", "diffuse", noise=0.01),
    "rolling, hard sun, photo floor, diffuse": Scene("hard_sun", "photo", "diffuse", moves="rolls"),
    "turning Suzanne, hard sun, photo floor, textured": Scene("hard_sun", "photo", "diffuse", moves="turns"),
    "bending column, city, grey floor, diffuse": Scene("city", "grey", "diffuse", moves="bends"),
    "rolling, city, grey floor, mirror + box": Scene("city", "grey", "mirror", box=True, moves="rolls"),
}
MOVING_SCENES = [name for name, spec in SCENES.items() if spec.moving]
# the rolling sphere's path over the shot (m, along x), turning as it rolls
ROLL_FROM, ROLL_TO = -0.6, 0.6


def scene_frames(spec: Scene) -> tuple:
    """The scene frames the scored frames are: a still shot is keyed at 1, 2, 3 (nothing is done
    between them); a moving one runs the whole shot, so its per-frame work is all there."""
    return SCORED_FRAMES if spec.moving else tuple(range(1, len(SCORED_FRAMES) + 1))


def counts(variable, default):
    return tuple(int(v) for v in os.environ.get(variable, default).split(",") if v)


# route key: (label, runs it, sample counts)
ROUTES = {
    "platelight": ("platelight (default)", "platelight", counts("PLATELIGHT_BENCH_CG_SPP", "1,4,16")),
    "paper": ("platelight (paper's model)", "paper", (16,)),
    # a moving CG's probe reused while it moves less than a quarter of its bounding radius
    "probe_reuse": ("platelight, Probe Reuse 0.25", "platelight", (4,)),
    # a CG that shadows itself shaded by its SBRDF, as the paper does, where the default path-traces it
    "sbrdf_self_shadowing": ("platelight, the paper's SBRDF on a CG that shadows itself", "platelight", (4,)),
    # a moving CG's shadows baked at every frame, at 256 rows and at the still bake's 512
    "moving_256": ("platelight, moving shadows baked per frame at 256 rows", "platelight", (4,)),
    "moving_512": ("platelight, moving shadows at 512 rows", "platelight", (4,)),
    "catcher": ("catcher", "catcher", counts("PLATELIGHT_BENCH_CATCHER_SPP", "4,16,64,256,1024")),
    # PlateLight's shadow bake caps diffuse bounces at 3: the catcher is offered the same cap
    "catcher_3": ("catcher, 3 diffuse bounces", "catcher", (16, 64)),
}
REFERENCE = "catcher"


# ------------------------------------------------------------------ scene building

def environment_path(name: str) -> str:
    """A bundled HDRI's path, or an analytic one written once into the cache."""
    import ball_corpus

    if name not in ball_corpus.ANALYTIC:
        return str(ball_corpus.bundled_hdris()[name])
    path = CACHE / "hdri" / f"{name}.exr"
    if not path.exists():
        path.parent.mkdir(parents=True, exist_ok=True)
        write_exr(path, ball_corpus.environment(name, 1024))
    return str(path)


def floor_photo_path() -> str:
    """A floor texture from a photograph: the paving below the horizon of the bundled
    'courtyard' HDRI, flattened to a square and scaled to a mean albedo of 0.35."""
    import cv2
    import ball_corpus

    path = CACHE / "floor_photo.exr"
    if not path.exists():
        image = read_exr(ball_corpus.bundled_hdris()["courtyard"])
        h, w = image.shape[:2]
        crop = image[int(0.78 * h):int(0.95 * h), : w // 2]
        crop = cv2.resize(crop, (512, 512), interpolation=cv2.INTER_AREA)
        crop *= 0.35 / float((crop @ sp.LUMINANCE).mean())
        path.parent.mkdir(parents=True, exist_ok=True)
        write_exr(path, np.clip(crop, 0, 0.95))
    return str(path)


def floor_material(bpy, kind: str):
    mat = compat().new_material("Floor")
    nt = mat.node_tree
    bsdf = nt.nodes["Principled BSDF"]
    bsdf.inputs["Roughness"].default_value = 1.0 if kind != "tiles" else 0.15
    if kind == "grey":
        bsdf.inputs["Base Color"].default_value = (0.45, 0.45, 0.45, 1)
    else:
        coords = nt.nodes.new("ShaderNodeTexCoord")
        mapping = nt.nodes.new("ShaderNodeMapping")
        mapping.inputs["Scale"].default_value = (0.8, 0.8, 0.8)       # a tile 1.25 m across
        nt.links.new(coords.outputs["Object"], mapping.inputs["Vector"])
        if kind == "photo":
            tex = nt.nodes.new("ShaderNodeTexImage")
            tex.image = bpy.data.images.load(floor_photo_path())
        else:
            tex = nt.nodes.new("ShaderNodeTexChecker")
            tex.inputs["Color1"].default_value = (0.55, 0.52, 0.48, 1)
            tex.inputs["Color2"].default_value = (0.18, 0.2, 0.24, 1)
            tex.inputs["Scale"].default_value = 2.0
        nt.links.new(mapping.outputs["Vector"], tex.inputs["Vector"])
        nt.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    return mat


def build(bpy, spec: Scene, frame: int = 1):
    """The scene with its CG sphere, floor (and box) and the camera keyed at scene_frames to the
    shot's scored frames (a rolling sphere keyed with it); (scene, cg, phantoms)."""
    width, height = (int(v) for v in SIZE.split("x"))
    bc.W, bc.H = width, height
    scene, floor, sphere = bc.build(bpy, environment_path(spec.hdri), bc.MATERIALS[spec.material],
                                    camera=bc.shot_camera(1, spec.box), box=bc.BOX if spec.box else None)
    scene.cycles.seed = 0
    floor.data.materials[0] = floor_material(bpy, spec.floor)
    floor.active_material = floor.data.materials[0]
    floor.data.uv_layers.new()
    phantoms = [floor] + ([scene.objects["Box"]] if spec.box else [])
    if spec.moving:
        scene.frame_start, scene.frame_end = 1, SHOT_FRAMES
        cg = MOVING_CG[spec.moves](bpy, scene, sphere)
        key_moving_shot(scene, cg, spec)
        return _at(scene, frame), [cg], phantoms
    else:
        bc.key_shot_camera(scene, spec.box, SCORED_FRAMES)
    return _at(scene, frame), [sphere], phantoms


def _at(scene, frame):
    scene.frame_set(frame)
    bc.set_device(scene)
    return scene


def suzanne(bpy, scene, sphere):
    """The sphere's place taken by Suzanne (subdivided once, smooth), resting on the floor, her
    base colour a checker on her own coordinates (the texture turns with her)."""
    import bmesh

    mesh = bpy.data.meshes.new("Suzanne")
    bm = bmesh.new()
    bmesh.ops.create_monkey(bm)
    bmesh.ops.subdivide_edges(bm, edges=bm.edges[:], cuts=1, use_grid_fill=True, smooth=1.0)
    bmesh.ops.scale(bm, vec=(0.5, 0.5, 0.5), verts=bm.verts)
    lowest = min(v.co.z for v in bm.verts)
    bmesh.ops.translate(bm, vec=(0.0, 0.0, -lowest), verts=bm.verts)
    bm.to_mesh(mesh)
    bm.free()
    for poly in mesh.polygons:
        poly.use_smooth = True
    mat = sphere.active_material
    nt = mat.node_tree
    checker = nt.nodes.new("ShaderNodeTexChecker")
    checker.inputs["Color1"].default_value = (0.75, 0.35, 0.12, 1)
    checker.inputs["Color2"].default_value = (0.12, 0.3, 0.6, 1)
    checker.inputs["Scale"].default_value = 6.0
    nt.links.new(nt.nodes.new("ShaderNodeTexCoord").outputs["Object"], checker.inputs["Vector"])
    nt.links.new(checker.outputs["Color"], nt.nodes["Principled BSDF"].inputs["Base Color"])
    mesh.materials.append(mat)
    ob = bpy.data.objects.new("Suzanne", mesh)
    scene.collection.objects.link(ob)
    bpy.data.objects.remove(sphere)
    return ob


def column(bpy, scene, sphere):
    """The sphere's place taken by a column 1.3 m tall and 0.45 m wide on the floor, skinned to a
    two-bone armature whose upper bone bends it over the shot."""
    import bmesh

    mesh = bpy.data.meshes.new("Column")
    bm = bmesh.new()
    bmesh.ops.create_cube(bm, size=1.0)
    bmesh.ops.scale(bm, vec=(0.45, 0.45, 1.3), verts=bm.verts)
    bmesh.ops.translate(bm, vec=(0.0, 0.0, 0.65), verts=bm.verts)
    bmesh.ops.subdivide_edges(bm, edges=[e for e in bm.edges if abs(e.verts[0].co.z - e.verts[1].co.z) > 1e-6],
                              cuts=15, use_grid_fill=True)
    bm.to_mesh(mesh)
    bm.free()
    mesh.materials.append(sphere.active_material)
    ob = bpy.data.objects.new("Column", mesh)
    scene.collection.objects.link(ob)
    bpy.data.objects.remove(sphere)
    import composite_scene

    rig = composite_scene.add_armature(bpy, scene, [("Lower", (0, 0, 0), (0, 0, 0.65), None),
                                                    ("Upper", (0, 0, 0.65), (0, 0, 1.3), "Lower")])
    heights = np.array([v.co.z for v in mesh.vertices])
    weight_upper = np.clip((heights - 0.45) / 0.4, 0.0, 1.0)    # a smooth knee 0.45-0.85 m up
    for name, weights in (("Lower", 1.0 - weight_upper), ("Upper", weight_upper)):
        group = ob.vertex_groups.new(name=name)
        for index, weight in enumerate(weights):
            if weight > 0:
                group.add([index], float(weight), "REPLACE")
    ob.modifiers.new("Armature", "ARMATURE").object = rig
    ob.location = rig.location = tuple(bc.SPHERE[0] * (1, 1, 0))
    return ob


# how each moving CG is keyed at a scored frame, from t = 0 (the shot's first frame) to 1 (its last)
def _roll(cg, t):
    centre, radius = bc.SPHERE
    x = ROLL_FROM + (ROLL_TO - ROLL_FROM) * t
    cg.location = (centre[0] + x, centre[1], centre[2])
    cg.rotation_euler = (0.0, x / radius, 0.0)          # turning by the distance over its radius
    return [(cg, "location"), (cg, "rotation_euler")]


def _turn(cg, t):
    cg.rotation_euler = (0.0, 0.0, np.radians(TURN_DEGREES) * t)
    return [(cg, "rotation_euler")]


def _bend(cg, t):
    bone = cg.modifiers["Armature"].object.pose.bones["Upper"]
    bone.rotation_mode = "XYZ"
    bone.rotation_euler = (np.radians(BEND_DEGREES) * t, 0.0, 0.0)
    return [(bone, "rotation_euler")]


MOVING_CG = {"rolls": lambda bpy, scene, sphere: sphere, "turns": suzanne, "bends": column}
TURN_DEGREES = 180.0       # Suzanne turns half round over the shot
BEND_DEGREES = 60.0        # the column's upper half bends towards the camera
KEYS = {"rolls": _roll, "turns": _turn, "bends": _bend}


def cg_words(spec) -> str:
    """The scene's CG and its motion, as the report names them."""
    return {"": f"{spec.material} sphere", "rolls": f"{spec.material} sphere rolling {ROLL_TO - ROLL_FROM:g} m",
            "turns": f"{spec.material} Suzanne with a checker texture, turning {TURN_DEGREES:g} degrees in place",
            "bends": f"{spec.material} column bent {BEND_DEGREES:g} degrees by an armature"}[spec.moves]


def key_moving_shot(scene, cg, spec):
    """Key the orbiting camera and the CG's motion (KEYS) at each scored frame of the shot."""
    from mathutils import Vector

    cam = scene.camera
    for frame in SCORED_FRAMES:
        location, target, lens = bc.shot_camera(frame, spec.box)
        cam.location = location
        cam.rotation_euler = (Vector(target) - Vector(location)).to_track_quat("-Z", "Y").to_euler()
        cam.data.lens = lens
        cam.keyframe_insert("location", frame=frame)
        cam.keyframe_insert("rotation_euler", frame=frame)
        for owner, path in KEYS[spec.moves](cg, (frame - 1) / (SHOT_FRAMES - 1)):
            owner.keyframe_insert(path, frame=frame)


# ------------------------------------------------------------------ truths, plates, masks

def truth_set(bpy, name: str, spec: Scene):
    """Per scored frame, cached: the truth's two halves, the plate's two halves (the same seeds:
    their noise cancels in the ratio where the CG changes nothing), the CG's coverage (alpha).
    Returns dict of lists."""
    folder = CACHE / SIZE / slug(name)
    folder.mkdir(parents=True, exist_ok=True)
    out = {"truth": [], "plate": [], "halves": ([], []), "alpha": []}
    for index, frame in enumerate(scene_frames(spec), start=1):
        halves = {}
        for kind, with_cg in (("truth", True), ("plate", False)):
            for half in (1, 2):
                path = folder / f"{kind}_{index}_{half}_{TRUTH_HALF_SPP}.exr"
                if not path.exists():
                    scene, cg, _ = build(bpy, spec, frame)
                    scene.cycles.samples = TRUTH_HALF_SPP
                    scene.cycles.use_denoising = False
                    scene.cycles.blur_glossy = 0.0
                    scene.cycles.seed = half
                    for ob in cg:
                        ob.hide_render = not with_cg
                    _, took = bc.render(bpy, scene, path)
                    print(f"{name}: {path.name} {took:.0f} s", flush=True)
                halves[kind, half] = read_exr(path)
        path = folder / f"alpha_{index}.exr"
        if not path.exists():
            scene, cg, phantoms = build(bpy, spec, frame)
            scene.render.film_transparent = True
            scene.cycles.samples, scene.cycles.max_bounces = 16, 0
            scene.cycles.use_denoising = False
            for ob in phantoms:
                ob.hide_render = True
            bc.render(bpy, scene, path)
        out["alpha"].append(read_exr(path, "RGBA")[..., 3])
        out["truth"].append((halves["truth", 1] + halves["truth", 2]) / 2)
        out["plate"].append((halves["plate", 1] + halves["plate", 2]) / 2)
        out["halves"][0].append(halves["truth", 1])
        out["halves"][1].append(halves["truth", 2])
    # footage's noise: the plate and the truth (the same camera) carry the same grain
    for index in range(len(SCORED_FRAMES)):
        grain = sp.sensor_noise(out["plate"][index], spec.noise, seed=100 + index)
        out["plate"][index] = out["plate"][index] + grain
        out["truth"][index] = out["truth"][index] + grain
    plate_dir = folder / f"plates_{TRUTH_HALF_SPP}"
    plate_dir.mkdir(exist_ok=True)
    # one file a scene frame; a moving shot's frames between the scored ones hold the nearest
    frames = scene_frames(spec)
    for frame in range(1, frames[-1] + 1):
        nearest = int(np.argmin([abs(frame - f) for f in frames]))
        write_exr(plate_dir / f"plate_{frame:04d}.exr", out["plate"][nearest])
    out["plate_path"] = plate_dir / "plate_0001.exr"
    return out


def masks_of(data):
    """(object, shadow, frame) masks per scored frame."""
    import cv2

    objects, shadows, frames = [], [], []
    for alpha, truth, plate in zip(data["alpha"], data["truth"], data["plate"]):
        covered = alpha > 0.999
        objects.append(cv2.erode(covered.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool))
        near = cv2.dilate((alpha > 0.001).astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)
        shadows.append(sp.shadow_mask(truth, plate, near))
        frames.append(np.ones_like(covered))
    return objects, shadows, frames


def slug(name: str) -> str:
    return "".join(c if c.isalnum() else "_" for c in name).strip("_")


# ------------------------------------------------------------------ the routes

def run_platelight(bpy, spec, data, samples, out_dir, paper=False, shadow_bake=None, composite=None,
                   probe_reuse=None):
    """The README's order: plate, Apply SBRDF, Bake Probes, Bake Shadows, Set Up Composite
    (``shadow_bake``, ``composite``, ``probe_reuse``: those operators' and that setting's values,
    else their defaults)."""
    scene, cg, phantoms = build(bpy, spec)
    if probe_reuse is not None:
        scene.platelight.probe_reuse = probe_reuse
    scene.platelight.property_unset("phantom_surface")     # a user's scene: the plate on the phantoms
    for ob in phantoms:
        ob.platelight.phantom = True
    t0 = time.perf_counter()
    assert bpy.ops.platelight.setup_plate(filepath=str(data["plate_path"])) == {"FINISHED"}
    # a rolling sphere's probe follows it: baked at every frame, as the bake's warning asks
    bake_s = bc.sbrdf_sphere(bpy, scene, cg[0], out_dir / "frame", paper=paper,
                             route="sbrdf_paper" if paper else "sbrdf", frame_range=spec.moving)
    t1 = time.perf_counter()
    try:
        assert bpy.ops.platelight.bake_shadows(**(shadow_bake or {})) == {"FINISHED"}
    except RuntimeError as refusal:      # every CG moves: nothing to bake, as the user is told
        assert "need at least one CG object" in str(refusal), refusal
    bake_s += time.perf_counter() - t1
    # a moving CG's shadows are path-traced every frame (the catcher layer): at the route's samples too
    frame_samples = {"samples": samples} if spec.moving else {}
    assert bpy.ops.platelight.setup_composite(cg_samples=samples, **frame_samples, **(composite or {})) == {"FINISHED"}
    setup_s = time.perf_counter() - t0 - bake_s
    images, seconds = [], []
    for index, frame in enumerate(scene_frames(spec), start=1):
        scene.frame_set(frame)
        image, took = bc.render(bpy, scene, out_dir / f"frame_{index:04d}.exr")
        images.append(image)
        seconds.append(took)
    return images, bake_s, setup_s, seconds


def run_catcher(bpy, spec, data, samples, out_dir, diffuse_bounces=None):
    """The skilled artist's shadow catcher (tests/shot_catcher.py), composited as Blender's
    manual does; the composite's arithmetic is timed with the frame."""
    scene, cg, phantoms = build(bpy, spec)
    t0 = time.perf_counter()
    shot_catcher.setup_catcher(scene, phantoms, samples)
    if diffuse_bounces is not None:
        scene.cycles.diffuse_bounces = diffuse_bounces
    shot_catcher.guess_albedos(bpy, scene, phantoms, cg, data["plate"][0],
                               lambda s: render_passes(bpy, s, out_dir / "match.exr", compat().OBJECT_INDEX_LAYER))
    setup_s = time.perf_counter() - t0
    images, seconds = [], []
    for index, frame in enumerate(scene_frames(spec), start=1):
        scene.frame_set(frame)
        t1 = time.perf_counter()
        combined, catcher = render_passes(bpy, scene, out_dir / f"frame_{index:04d}.exr", "Shadow Catcher")
        images.append(shot_catcher.composite(combined, catcher, data["plate"][index - 1]))
        seconds.append(time.perf_counter() - t1)
    return images, 0.0, setup_s, seconds


def render_passes(bpy, scene, path, second):
    """Render ``scene`` to a multilayer EXR; (Combined RGBA, the ``second`` pass)."""
    settings = scene.render.image_settings
    for attribute, value in compat().multilayer_exr_format():
        setattr(settings, attribute, value)
    settings.color_depth = "32"
    scene.render.filepath = str(path)
    bpy.ops.render.render(write_still=True)
    return read_exr(path, "RGBA", layer="Combined"), read_exr(path, layer=second)


def run_route(bpy, key, spec, data, samples, out_dir):
    out_dir.mkdir(parents=True, exist_ok=True)
    if key == "platelight":
        return run_platelight(bpy, spec, data, samples, out_dir)
    if key == "paper":
        return run_platelight(bpy, spec, data, samples, out_dir, paper=True)
    if key == "probe_reuse":
        return run_platelight(bpy, spec, data, samples, out_dir, probe_reuse=0.25)
    if key == "sbrdf_self_shadowing":
        return run_platelight(bpy, spec, data, samples, out_dir, composite={"self_shadowing": "SBRDF"})
    if key in ("moving_256", "moving_512"):
        return run_platelight(bpy, spec, data, samples, out_dir,
                              shadow_bake={"moving_shadows": "PER_FRAME", "moving_height": int(key[7:])})
    return run_catcher(bpy, spec, data, samples, out_dir, diffuse_bounces=3 if key == "catcher_3" else None)


# ------------------------------------------------------------------ the run

def main(out_dir: pathlib.Path) -> None:
    bpy = conftest._import_bpy_with_extension()
    if bc.DEVICE == "GPU" and bc.use_gpu(bpy) is None:
        raise SystemExit("PLATELIGHT_BENCH_DEVICE=GPU: Cycles finds no GPU on this machine.")
    header = sp.run_header(support.REPO, bpy.app.version_string)
    import importlib

    # built once per machine and add-on version: a user's shot does not pay it
    importlib.import_module(f"{support.EXT_MODULE}.node_groups.probe_maps").prepare_templates()
    bench_name = os.environ.get("PLATELIGHT_BENCH_NAME", "shot")
    # the still shot's table and the moving shot's are each their own run
    only = os.environ.get("PLATELIGHT_BENCH_SCENES") or ";".join(
        n for n in SCENES if (n in MOVING_SCENES) == (bench_name == "motion"))
    keys = os.environ.get("PLATELIGHT_BENCH_ROUTES")
    routes = {k: v for k, v in ROUTES.items() if not keys or k in keys.split(",")}
    stem = (f"{bench_name}_{SIZE}"
            + ("" if bc.DEVICE == "CPU" else f"_{bc.DEVICE.lower()}"))
    rows = []
    for name, spec in SCENES.items():
        if only and name not in only.split(";"):
            continue
        data = truth_set(bpy, name, spec)
        masks = masks_of(data)
        peak = sp.peak_of(data["truth"])
        ceiling = [sp.truth_ceiling(*data["halves"], m, peak) for m in masks]
        plan = {(key, samples): [] for key, (_, _, sample_counts) in routes.items() for samples in sample_counts}
        scores = {}
        for repeat, (key, samples) in sp.interleaved(plan, REPEATS):
            folder = CACHE / SIZE / slug(name) / f"{key}_{samples}"
            images, bake_s, setup_s, seconds = run_route(bpy, key, spec, data, samples, folder)
            warm = float(np.median(seconds[1:]))
            plan[key, samples].append((bake_s, setup_s, seconds[0], warm))
            if repeat == 0:
                scores[key, samples] = [sp.pooled_psnr(images, data["truth"], m, peak) for m in masks]
            print(f"{name} | {key} {samples} | repeat {repeat + 1}: bake {bake_s:.1f} setup {setup_s:.1f} "
                  f"first {seconds[0]:.1f} warm {warm:.1f} | dB {scores[key, samples]}", flush=True)
        for (key, samples), timings in plan.items():
            per_frame = [sp.per_frame_seconds(*t, SHOT_FRAMES) for t in timings]
            median, spread = sp.median_and_spread(per_frame)
            bake, setup, first, warm = (float(np.median(column)) for column in zip(*timings))
            rows.append(dict(
                scene=name, route=routes[key][0], key=key, samples=samples, repeats=len(timings),
                per_frame_s=median, per_frame_spread=spread, per_frame_all=per_frame,
                bake_s=bake, setup_s=setup, first_s=first, warm_s=warm,
                psnr_object=scores[key, samples][0], psnr_shadow=scores[key, samples][1],
                psnr_frame=scores[key, samples][2], truth_psnr_object=ceiling[0],
                truth_psnr_shadow=ceiling[1], truth_psnr_frame=ceiling[2],
                truth_half_spp=TRUTH_HALF_SPP, size=SIZE, object_px=int(sum(m.sum() for m in masks[0])),
                shadow_px=int(sum(m.sum() for m in masks[1])), load=os.getloadavg()[0], **header))
        out_dir.mkdir(parents=True, exist_ok=True)
        (out_dir / f"{stem}_rows.json").write_text(json.dumps(rows, indent=1))
        write_report(out_dir, stem, rows, header)       # after each scene: a stopped run says what it has


# ------------------------------------------------------------------ the report

def comparison(rows, scene, key, score):
    """Against the reference on one score: its converged PSNR and time, our fastest time reaching
    it (the speed-up), and our best row's gain at equal time."""
    ref_rows = sorted((r for r in rows if r["scene"] == scene and r["key"] == REFERENCE), key=lambda r: r["samples"])
    ours = sorted((r for r in rows if r["scene"] == scene and r["key"] == key), key=lambda r: r["samples"])
    if not ref_rows or not ours:
        return None
    reference = [(r["per_frame_s"], r[score]) for r in ref_rows]
    best, ref_s, converged = sp.reference_convergence(reference)
    reaching = [r for r in ours if r[score] >= best]
    gains = [g for g in (sp.gain_at_equal_time((r["per_frame_s"], r[score]), reference) for r in ours)
             if g is not None]
    return dict(converged_psnr=best, converged_s=ref_s, converged=converged,
                best_ours=max(r[score] for r in ours),
                speedup=ref_s / min(r["per_frame_s"] for r in reaching) if reaching else None,
                gain=max(gains) if gains else None, ceiling=ours[0]["truth_" + score])


def write_report(out_dir, stem, rows, header):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    width, height = SIZE.split("x")
    lines = [f"# Shot benchmark against Cycles' shadow catcher at {width}×{height}", "",
             " ".join(__doc__.split("\n\n")[1].split()), "",
             f"**This run.** Commit `{header['commit']}`, run `{header['run']}` (its date is in the rows file), "
             f"Blender {header['blender']}, {header['cpu']} ({header['cores']} cores), Cycles on the "
             f"{bc.DEVICE}; load average {header['load_at_start']:.1f} at the start, "
             f"{rows[-1]['load']:.1f} at the last row. Every row below was timed in this run, "
             f"{REPEATS} times each, interleaved. Truth: 2 × {TRUTH_HALF_SPP} spp, no denoiser, Filter Glossy 0. "
             "Produced by `tests/bench/bench_shot.py`; nothing here is written by hand.", "",
             "Scenes: " + "; ".join(f"*{n}*: {s.hdri} environment, {s.floor} floor, {cg_words(s)}"
                                    + (", a red phantom box" if s.box else "")
                                    + (f", plate noise {s.noise:g}" if s.noise else "")
                                    for n, s in SCENES.items() if any(r["scene"] == n for r in rows)) + ".", "",
             "Per frame = (bake + setup + first + 23 × warm) / 24, the median of the repeats; *spread* = "
             "(slowest − fastest) / median. PSNR in dB over the object, its shadow and the frame, pooled "
             "over the three scored frames; *ceiling*: the truth's own noise (its two halves), beyond "
             "which no score can be told apart.", "",
             "| scene | route | spp | per frame (s) | spread | bake | setup | first | warm | object | shadow | frame |",
             "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {r['scene']} | {r['route']} | {r['samples']} | {r['per_frame_s']:.2f} | "
                     f"{100 * r['per_frame_spread']:.0f} % | {r['bake_s']:.1f} | {r['setup_s']:.1f} | "
                     f"{r['first_s']:.1f} | {r['warm_s']:.1f} | {r['psnr_object']:.2f} | "
                     f"{r['psnr_shadow']:.2f} | {r['psnr_frame']:.2f} |")
    scenes = list(dict.fromkeys(r["scene"] for r in rows))
    lines += ["", "| scene | truth ceiling object | shadow | frame | object px | shadow px |",
              "|---|---:|---:|---:|---:|---:|"]
    for scene in scenes:
        r = next(r for r in rows if r["scene"] == scene)
        lines.append(f"| {scene} | {r['truth_psnr_object']:.1f} | {r['truth_psnr_shadow']:.1f} | "
                     f"{r['truth_psnr_frame']:.1f} | {r['object_px']} | {r['shadow_px']} |")
    lines += ["", "## Against the catcher", "",
              "Per scene and route, on each score: the catcher's converged PSNR (its best; *not converged* "
              "where its last step in samples still gained 0.3 dB or more) and the time it first gets "
              "within 0.3 dB of it; the route's best PSNR; the speed-up where the route reaches the "
              "catcher's converged PSNR (its fastest such row), else *not reached*; the most dB the "
              "route gains at equal time within the catcher's measured times. A PSNR within 1 dB of "
              "the truth's ceiling is marked *(ceiling)*: there no route can be told better.", "",
              "| scene | route | score | catcher converged | at s/frame | route best | speed-up | gain at equal time |",
              "|---|---|---|---:|---:|---:|---:|---:|"]
    mark = lambda p, c: f"{p:.2f}" + (" (ceiling)" if sp.at_ceiling(p, c) else "")  # noqa: E731
    for scene in scenes:
        for key in dict.fromkeys(r["key"] for r in rows if r["scene"] == scene):
            if key == REFERENCE:
                continue
            for score in ("psnr_object", "psnr_shadow"):
                c = comparison(rows, scene, key, score)
                if c is None:
                    continue
                label = next(r["route"] for r in rows if r["key"] == key)
                lines.append(
                    f"| {scene} | {label} | {score[5:]} | {mark(c['converged_psnr'], c['ceiling'])}"
                    f"{'' if c['converged'] else ' (not converged)'} | {c['converged_s']:.2f} | "
                    f"{mark(c['best_ours'], c['ceiling'])} | "
                    + (f"{c['speedup']:.2f}×" if c["speedup"] is not None else "not reached") + " | "
                    + (f"{c['gain']:+.2f}" if c["gain"] is not None else "outside the catcher's times") + " |")
    (out_dir / f"{stem}.md").write_text("\n".join(lines) + "\n")
    fig, axes = plt.subplots(len(scenes), 2, figsize=(12, 3.6 * len(scenes)), squeeze=False)
    for row_axes, scene in zip(axes, scenes):
        for ax, score in zip(row_axes, ("psnr_object", "psnr_shadow")):
            for key in dict.fromkeys(r["key"] for r in rows):
                pts = sorted((r["per_frame_s"], r[score], r["per_frame_spread"]) for r in rows
                             if r["scene"] == scene and r["key"] == key)
                if pts:
                    xs, ys, spread = zip(*pts)
                    ax.errorbar(xs, ys, xerr=[np.array(xs) * np.array(spread) / 2] * 2, marker="o",
                                label=next(r["route"] for r in rows if r["key"] == key), capsize=2)
            ceiling = next(r["truth_" + score] for r in rows if r["scene"] == scene)
            ax.axhline(ceiling, color="grey", linestyle="--", label="truth's ceiling")
            ax.set_xscale("log")
            ax.set_xlabel("seconds per frame of the 24-frame shot")
            ax.set_ylabel("PSNR (dB)")
            ax.set_title(f"{scene}: {score[5:]}", fontsize=9)
            ax.grid(True, alpha=0.3)
    axes[0][0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out_dir / f"{stem}.png", dpi=100)
    plt.close(fig)


if __name__ == "__main__":
    main(support.REPO / "docs" / "bench")
