"""bpy.ops.platelight.bake_shadows(): the shot's shadow panorama for setup_composite's BAKED method
(addon/compositing/baked_shadows.py says why a matte phantom's shadow can be baked once).

From one point above the CG (the probe renderer's equirectangular camera, denoised, one seed),
with the CG there but unseen by camera rays (it still shadows and lights the phantoms), the
ratio of the light each phantom point the panorama sees gets with the CG to the light without
it. CATCHER (the default) renders it in one render: the phantoms are Cycles shadow catchers,
which split each path at the phantom into one that sees the CG and one that does not, and the
Shadow Catcher pass is their ratio, denoised by OIDN as such: by the compositor's Denoise node on
that pass alone (DENOISERS, COMPOSITOR, the default) or by Cycles with Combined and the matte.
TWO_RENDERS renders the light with the CG and without it and divides; undenoised the two give
the same ratio to the bit (same seed, same paths). A distance panorama tells the points seen from hidden ones. The scene is
restored exactly, as after a probe bake."""
from __future__ import annotations

import os
import time

import bpy
import numpy as np
from bpy.props import BoolProperty, EnumProperty, IntProperty

from .. import compat
from ..addon import names
from ..addon.bake.hashing import content_hash
from ..addon.bake.layout import DEFAULT_MAPS_DIR
from ..addon.compositing import baked_shadows as engine
from ..addon.errors import PlateLightError
from ..addon.ibl import distance as distance_maps
from ..node_groups.baked_shadow import baked_shadow_material
from .bake import pass_denoise
from .bake.inputs import Describer, point_inside, world_corners, world_description
from .bake.probe_render import ProbeRenderer, detach_unseen_maps, render_key
from .bake.scene_state import SceneState
from . import motion
from .common import GEOMETRY_TYPES, classify_objects
from .phantoms import apply_phantom_surfaces


def uses_baked_shadows(scene) -> bool:
    """Is the scene's composite the BAKED method (its shadow layer shows the baked material)?"""
    layer = scene.view_layers.get(names.LAYER_SHADOWS)
    override = getattr(layer, "material_override", None) if layer is not None else None
    return bool(layer is not None and layer.use and override is not None
                and override.name == names.BAKED_SHADOW_MATERIAL)


def shadows_folder(scene) -> str:
    maps_dir = scene.platelight.maps_dir or DEFAULT_MAPS_DIR
    if maps_dir.startswith("//") and not bpy.data.filepath:
        raise PlateLightError("Save the .blend file first: the maps folder is relative to it "
                              f"({maps_dir}); or set an absolute Maps Folder.")
    return os.path.normpath(bpy.path.abspath(maps_dir.rstrip("/\\") + "/" + names.SHADOWS_FOLDER))


def moving_cg(scene, cg, phantoms, per_frame) -> dict:
    """{name: Motion} of the CG objects that move or deform over the shot: the bake of the still
    CG leaves them out (their shadows are baked ``per_frame``, else rendered every frame by Set Up
    Composite). Raises where nothing can be baked: a phantom that moves (the bake is a picture of
    the phantoms), or, not baking per frame, no CG that stands still."""
    moving = motion.motions(scene, cg + phantoms)
    phantom_names = {ob.name for ob in phantoms}
    moved_phantoms = [m for name, m in moving.items() if name in phantom_names]
    if moved_phantoms or (len(moving) == len(cg) and not per_frame):
        first = (moved_phantoms or list(moving.values()))[0]
        more = len(moving) - 1
        need = "phantoms" if moved_phantoms else "at least one CG object (or Moving CG: Baked Every Frame)"
        raise PlateLightError(f"{first.sentence()}{f' (and {more} more)' if more else ''}: baked "
                              f"shadows need {need} that stand still; Set Up Composite's Automatic "
                              "method path-traces the shadows every frame instead.")
    return moving


def world_box(objects):
    """(low, high): the world-axis box around the objects' bounding boxes."""
    corners = np.concatenate([world_corners(ob) for ob in objects])
    return corners.min(axis=0), corners.max(axis=0)


def panorama_centre(cg):
    """Above the CG's footprint centre, one bounding radius over its top."""
    low, high = world_box(cg)
    radius = max(float(np.linalg.norm(high - low)) / 2, 1e-3)
    return np.array([(low[0] + high[0]) / 2, (low[1] + high[1]) / 2, high[2] + radius])


# A phantom's matte albedo in the bake where the plate gives none (its own material)
DEFAULT_MATTE_ALBEDO = 0.5


def matte_albedo(ob) -> tuple:
    """The albedo a phantom is baked with: the plate's estimate of the real surface's (its mean
    over what the camera saw of it, operators/phantoms.py), else DEFAULT_MATTE_ALBEDO. It scales
    the light the CG sends back onto the phantoms (floor to CG to floor), so the ratio in a shadow
    depends on it: a 50 % grey under a sunlit 35 % floor made the shadow 4 % too bright."""
    albedo = ob.get(names.MEAN_ALBEDO_KEY)
    if albedo is None:
        return (DEFAULT_MATTE_ALBEDO,) * 3
    return tuple(round(float(c), 3) for c in list(albedo)[:3])


def _matte(albedo):
    """A plain diffuse material of ``albedo`` for the phantoms during the bake (removed after)."""
    material = compat.new_material(names.BAKED_SHADOW_MATERIAL + " Matte")
    tree = compat.shader_tree(material)
    tree.nodes.clear()
    diffuse = tree.nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = (*albedo, 1.0)
    out = tree.nodes.new("ShaderNodeOutputMaterial")
    tree.links.new(diffuse.outputs["BSDF"], out.inputs["Surface"])
    return material


def shadows_hash(scene, height, samples, method, denoiser, moving=frozenset(), moving_height=0) -> str:
    """The content hash of what the shadow panorama depends on: the world, every renderable
    object (place, shape, materials, visibility) but the ``moving`` CG (names: the bake leaves
    them out, so only which they are counts; ``moving_height`` rows: their shadows are baked at
    each frame of the scene's range, so their place and shape there count too), the bake's settings and
    Cycles' bounces. A
    phantom's materials are left out: the method assumes matte phantoms, whose albedo cancels in
    the ratio but for the light the CG sends back, so each phantom's matte albedo (matte_albedo)
    stands in for them; the plate-albedo material is remade at every composite set-up. The bake hides
    the CG from its camera, so what Cycles' camera sees of an SBRDF metal (setup_composite's
    Metals) is left out too: switching it must not make a bake stale."""
    describer = Describer(camera_blind=True)
    frame = scene.frame_current

    def digest(ob):
        if not ob.platelight.phantom:
            return describer.seen_digest(ob, frame)
        described = describer.seen_object(ob, frame)
        described.pop("materials")
        described["matte_albedo"] = matte_albedo(ob)
        return content_hash(described)

    seen = sorted((ob.name_full, digest(ob)) for ob in scene.objects if ob.name not in moving
                  and not ob.hide_render and (ob.type in GEOMETRY_TYPES or ob.type == "LIGHT"))
    cycles = scene.cycles
    # Cycles' denoiser adds nothing to the hash: a bake whose record names no denoiser stays current
    settings = [int(height), int(samples), str(method)] + ([] if denoiser == "CYCLES" else [str(denoiser)])
    described = {"world": content_hash(world_description(scene)), "seen": seen, "settings": settings,
                 "render": render_key(cycles, bake_diffuse_bounces(cycles))}
    if moving:              # absent when nothing moves: the hash of a still shot's bake is kept
        described["moving"] = sorted(moving)
    if moving and moving_height:
        described["moving_frames"] = _moving_digests(scene, describer, moving)
        described["moving_height"] = int(moving_height)
    return content_hash(described)


def _moving_digests(scene, describer, moving):
    """Per frame of the scene's range, the moving CG's digests there (the scene's frame kept)."""
    frame0, subframe0 = scene.frame_current, scene.frame_subframe
    try:
        described = []
        for frame in moving_frames(scene):
            scene.frame_set(frame)
            described.append([frame] + [describer.seen_digest(scene.objects[name], frame)
                                        for name in sorted(moving)])
    finally:
        scene.frame_set(frame0, subframe=subframe0)
    return described


def moving_frames(scene) -> list[int]:
    """The frames a moving CG's shadows are baked at: every frame of the scene's range."""
    return list(range(scene.frame_start, scene.frame_end + 1))


# The bake's diffuse bounces at most: colour bleeding needs 2, and more biases the catcher's ratio
# light (docs/decisions.md, "The shadow bake's diffuse bounces, its guides unfiltered")
SHADOW_BAKE_DIFFUSE_BOUNCES = 3


def bake_diffuse_bounces(cycles) -> int:
    """The diffuse bounces the shadow bake renders with: the scene's, at most the cap."""
    return min(int(cycles.diffuse_bounces), SHADOW_BAKE_DIFFUSE_BOUNCES)


def recorded_denoiser(record) -> str:
    """Who denoised the bake ``record`` describes: Cycles where it names none (TWO_RENDERS, or a
    record written without the field)."""
    return record.get("denoiser") or "CYCLES"


def baked_is_current(scene, moving=None) -> bool | None:
    """Do the baked shadows on disk still fit the scene, whose ``moving`` CG (names; None: found
    here) the bake must have left out? None when there is no readable bake."""
    try:
        record = engine.read_record(shadows_folder(scene))
    except PlateLightError:
        return None
    if record is None:
        return None
    if moving is None:
        cg, phantoms = classify_objects(scene)
        moving = motion.motions(scene, cg + phantoms)
    return record.get("hash") == shadows_hash(scene, record.get("height", 0), record.get("samples", 0),
                                              record.get("method", ""), recorded_denoiser(record),
                                              frozenset(moving), per_frame_height(record))


def per_frame_height(record) -> int:
    """The rows of the moving CG's panoramas where the bake ``record`` describes baked them at
    every frame, else 0."""
    moving = (record or {}).get("moving") or {}
    return int(moving.get("height") or DEFAULT_MOVING_HEIGHT) if moving.get("mode") == "PER_FRAME" else 0


def moving_baked(scene) -> bool:
    """Are the shot's baked shadows those of every frame for the CG that moves (no catcher needed)?"""
    try:
        return per_frame_height(engine.read_record(shadows_folder(scene))) > 0
    except PlateLightError:
        return False


DEFAULT_HEIGHT, DEFAULT_SAMPLES = 512, 16
METHODS = (("CATCHER", "Shadow Catcher", "One render of Cycles' Shadow Catcher pass: the ratio per path, "
            "denoised as such"),
           ("TWO_RENDERS", "Two Renders", "The light with the CG and without it, each denoised, divided"))
DEFAULT_METHOD = "CATCHER"
# Who denoises the CATCHER render (TWO_RENDERS: always Cycles); the compositor gives Cycles' ratio
# sooner, running OIDN on that pass alone (docs/bench/shadow_bake_denoiser_960x540.md)
DENOISERS = (("COMPOSITOR", "Compositor", "Cycles' denoiser off, the compositor's Denoise node on the "
              "Shadow Catcher pass alone (with the scene's denoiser settings)"),
             ("CYCLES", "Cycles", "Cycles' own denoiser, which also denoises the Combined and matte passes"))
DEFAULT_DENOISER = "COMPOSITOR"
# Below this the catcher's per-path ratio is too poor a signal for OIDN
# (docs/bench/shadow_bake_960x540.md)
CATCHER_MIN_SAMPLES = 4


def bake_shadows(context, height: int | None = None, samples: int | None = None,
                 use_cache: bool = True, method: str | None = None, denoiser: str | None = None,
                 moving_shadows: str | None = None, moving_height: int | None = None) -> dict:
    """Bake the shot's shadow panorama and (re)build the override material; returns a summary
    (``reused``: the bake on disk was current and nothing was rendered). ``height``/``samples``/
    ``method`` (METHODS)/``denoiser`` (DENOISERS)/``moving_shadows`` (MOVING_SHADOWS: a moving CG's
    shadows baked per frame or left to a catcher)/``moving_height`` (the rows of its per-frame
    panoramas) None: those of the bake on disk (a farm's
    re-bake keeps the artist's), else the defaults."""
    scene = context.scene
    if scene.world is None:
        raise PlateLightError("The scene has no world; add one (its environment lights the phantoms) "
                              "before baking shadows.")
    cg, phantoms = classify_objects(scene)
    if not cg:
        raise PlateLightError("There are no CG objects whose shadows could be baked.")
    if not phantoms:
        raise PlateLightError("There are no phantoms to catch the shadows: mark the stand-ins for "
                              "real surfaces as Phantom.")
    folder = shadows_folder(scene)
    record = engine.read_record(folder)
    height = int(height or (record or {}).get("height") or DEFAULT_HEIGHT)
    samples = int(samples or (record or {}).get("samples") or DEFAULT_SAMPLES)
    method = method or (record or {}).get("method") or DEFAULT_METHOD
    kept_moving = ((record or {}).get("moving") or {}).get("mode")
    moving_shadows = moving_shadows or kept_moving or DEFAULT_MOVING_SHADOWS
    moving_height = int(moving_height or per_frame_height(record) or DEFAULT_MOVING_HEIGHT)
    if moving_shadows not in {m[0] for m in MOVING_SHADOWS}:
        raise PlateLightError(f"Unknown way {moving_shadows!r} for a moving CG's shadows: one of "
                              f"{', '.join(m[0] for m in MOVING_SHADOWS)}.")
    moving = moving_cg(scene, cg, phantoms, moving_shadows == "PER_FRAME")
    still = [ob for ob in cg if ob.name not in moving]
    apply_phantom_surfaces(scene, phantoms)     # as the composite will show them (hash and render)
    if method not in {m[0] for m in METHODS}:
        raise PlateLightError(f"Unknown shadow bake method {method!r}: one of {', '.join(m[0] for m in METHODS)}.")
    kept = recorded_denoiser(record) if record and record.get("method") == "CATCHER" else None
    denoiser = denoiser or kept or DEFAULT_DENOISER
    if denoiser not in {d[0] for d in DENOISERS}:
        raise PlateLightError(f"Unknown shadow bake denoiser {denoiser!r}: one of "
                              f"{', '.join(d[0] for d in DENOISERS)}.")
    notes = []
    if method == "CATCHER" and samples < CATCHER_MIN_SAMPLES:
        notes.append(f"At {samples} sample(s) the Shadow Catcher bake's shadow is grainy; bake with "
                     f"{CATCHER_MIN_SAMPLES} or more samples, or with the Two Renders method.")
    if method != "CATCHER":
        denoiser = "CYCLES"
    elif denoiser == "COMPOSITOR" and not pass_denoise.available():
        denoiser = "CYCLES"
        notes.append("This Blender's compositor cannot denoise (no OpenImageDenoise): Cycles denoised "
                     "the shadow bake.")
    per_frame = bool(moving) and moving_shadows == "PER_FRAME"
    frames = moving_frames(scene) if per_frame else []
    if per_frame and len(frames) > MOST_MOVING_FRAMES:
        raise PlateLightError(f"The shot is {len(frames)} frames long: baking a moving CG's shadows at "
                              f"more than {MOST_MOVING_FRAMES} frames is refused; shorten the frame "
                              "range or let the Shadow Catcher render them (Moving CG: Shadow Catcher).")
    elsewhere = ("it is baked at each of the shot's frames" if per_frame else
                 "Set Up Composite renders it every frame")
    notes += [f"{m.sentence()}: its shadow is left out of the bake of the still CG, and {elsewhere}."
              for m in moving.values()]
    digest = shadows_hash(scene, height, samples, method, denoiser, frozenset(moving),
                          moving_height if per_frame else 0)
    if use_cache and record is not None and record.get("hash") == digest and \
            bpy.data.materials.get(names.BAKED_SHADOW_MATERIAL) is not None and \
            os.path.isfile(os.path.join(folder, engine.RATIO_FILE)) and engine.has_moving_frames(folder, frames):
        return {"seconds": 0.0, "folder": folder, "centre": record["centre"], "warnings": [], "reused": True}
    moved = [ob for ob in cg if ob.name in moving]
    # every CG moving, the still panorama is of nothing: looked up from above the first frame's CG
    centre = panorama_centre(still or moved)
    if still:
        check_outside(context, phantoms, centre)
    if record is not None:                      # a bake stopped halfway is never taken as current
        os.remove(os.path.join(folder, engine.RECORD_FILE))
    t0 = time.perf_counter()
    state = SceneState()
    # A view layer of its own: the composite's layers hold things out, exclude the CG or override
    # every material (a farm's bake opens the file on whichever of them was active)
    layer = scene.view_layers.new(names.SHADOW_BAKE_LAYER)
    renderer = ProbeRenderer(context, state, None, denoise=True, samples=samples, view_layer=layer,
                             catcher_denoiser=denoiser)
    mattes = {albedo: _matte(albedo) for albedo in {matte_albedo(ob) for ob in phantoms}}
    frame0, subframe0 = scene.frame_current, scene.frame_subframe
    centres, warnings = [], []
    wm = context.window_manager
    try:
        for other in scene.view_layers:
            if other != layer and other.use:
                state.set(other, "use", False)
        state.set(scene.cycles, "diffuse_bounces", bake_diffuse_bounces(scene.cycles))
        # every render hides the CG from camera rays: no SBRDF map of it is seen
        cg_names = {ob.name for ob in cg}
        detach_unseen_maps(state, cg, [ob for ob in scene.objects if ob.name not in cg_names])
        # Phantoms are rendered matte, one albedo each: it cancels in the ratio but for the
        # light the CG sends back; a textured one (the plate's albedo map) made the two denoised
        # renders differ by up to 5 % far from any shadow (the denoiser sees the whole panorama)
        for ob in phantoms:
            for slot in ob.material_slots:
                state.set(slot, "material", mattes[matte_albedo(ob)])
        boxes = [world_box([ob]) for ob in phantoms]
        # The still CG's shadows, the moving CG not there (none: no change anywhere, nothing rendered)
        if still:
            ratio, distance, said = _render_ratio(renderer, method, centre, moved, still, phantoms, boxes, height)
            warnings += said
        else:
            ratio, distance = np.ones((2, 4, 3)), np.full((2, 4), distance_maps.FAR, np.float32)
        distance_path = distance_maps.write_distance(folder, distance)
        ratio_path = engine.write_ratio(folder, engine.ratio_to_texture(ratio))
        # Each frame's moving CG's shadows from above it, the still CG not there (theirs are above)
        moving_folder = os.path.join(folder, engine.MOVING_FOLDER)
        wm.progress_begin(0, max(1, len(frames)))
        for done, frame in enumerate(frames):
            scene.frame_set(frame)
            centres.append(panorama_centre(moved))
            check_outside(context, phantoms, centres[-1])
            ratio, distance, said = _render_ratio(renderer, method, centres[-1], still, moved, phantoms,
                                                  boxes, moving_height)
            warnings += [f"Frame {frame}: {w}" for w in said]
            distance_maps.write_distance(moving_folder, distance, frame)
            engine.write_ratio(moving_folder, engine.ratio_to_texture(ratio), frame)
            wm.progress_update(done + 1)
    finally:
        wm.progress_end()
        scene.frame_set(frame0, subframe=subframe0)
        errors = state.restore()
        renderer.end()
        for material in mattes.values():
            bpy.data.materials.remove(material)
        scene.view_layers.remove(layer)
    per_frame_record = {"names": sorted(moving), "mode": "PER_FRAME" if per_frame else "CATCHER",
                        "height": moving_height if per_frame else 0, "frames": frames,
                        "centres": [[float(v) for v in c] for c in centres]}
    engine.write_record(folder, centre, height, samples, digest, method, denoiser,
                        per_frame_record if moving else None)
    engine.remove_moving_frames(folder, keep=frames)      # an earlier, longer per-frame bake's
    baked_shadow_material(ratio_path, distance_path, centre,
                          moving_maps(folder, frames, centres) if per_frame else None)
    return {"seconds": time.perf_counter() - t0, "folder": folder, "centre": centre,
            "warnings": notes + warnings + list(errors or []), "reused": False}


# A moving CG's shadows baked at more frames than this is refused (the catcher renders them)
MOST_MOVING_FRAMES = 10_000
MOVING_SHADOWS = (("CATCHER", "Shadow Catcher", "Set Up Composite renders the moving CG's shadows every "
                   "frame in a shadow-catcher layer of their own (the faster, docs/bench/motion_320x180.md)"),
                  ("PER_FRAME", "Baked Every Frame", "A panorama of the moving CG's shadows from above it "
                   "at each frame of the shot, looked up as the still CG's are"))
# The catcher layer: a panorama a frame cost more than the catcher's whole frame at equal shadow
# PSNR (docs/decisions.md, "Moving CG")
DEFAULT_MOVING_SHADOWS = "CATCHER"
# A moving CG's per-frame panoramas (docs/bench/motion_320x180.md publishes 256 and 512 rows)
DEFAULT_MOVING_HEIGHT = 256


def check_outside(context, phantoms, centre):
    """Raise where the panorama's centre lies inside a phantom (it would see nothing)."""
    depsgraph = context.evaluated_depsgraph_get()
    for ob in phantoms:
        if point_inside(ob, depsgraph, centre):
            raise PlateLightError(f"The point above the CG lies inside '{ob.name}', so the shadows "
                                  "cannot be seen from there; set up the composite with the Shadow Catcher "
                                  "method instead of baked shadows.")


def _render_ratio(renderer, method, centre, hidden, casting, phantoms, boxes, height):
    """(ratio, distance, warnings) of the panorama from ``centre``: the ``casting`` CG there but
    unseen by camera rays (it shadows and lights the phantoms), the ``hidden`` CG not there. The
    catchers' paths also go on without it (CATCHER), or a second render does (TWO_RENDERS).
    Only the rows that see a phantom are rendered: under a floor's CG about half the panorama."""
    rows = engine.panorama_rows(centre, boxes, height)
    if method == "CATCHER":
        caught = renderer.render(centre, hidden=hidden, camera_hidden=casting, catchers=phantoms,
                                 height=height, distance=True, rows=rows)
        distance, warnings = renderer.distance
        return engine.catcher_ratio(caught, rows), distance, list(warnings)
    lit_with = renderer.render(centre, hidden=hidden, camera_hidden=casting, height=height,
                               distance=True, rows=rows)
    distance, warnings = renderer.distance
    lit_without = renderer.render(centre, hidden=list(hidden) + list(casting), height=height, rows=rows)
    return engine.shadow_ratio(lit_with, lit_without), distance, list(warnings)


def moving_maps(folder, frames, centres):
    """What the baked ratio group reads of a per-frame bake: the ratio and distance sequences' first
    files and each frame's panorama centre."""
    moving_folder = os.path.join(folder, engine.MOVING_FOLDER)
    return {"ratio": os.path.join(moving_folder, engine.ratio_filename(frames[0])),
            "distance": os.path.join(moving_folder, distance_maps.distance_filename(frames[0])),
            "centres": dict(zip(frames, centres))}


class PLATELIGHT_OT_bake_shadows(bpy.types.Operator):
    """Render the shot's CG shadows on the phantoms once, from above, for the Baked Shadows
    composite (a CG that moves gets a panorama of its shadows at every frame, or a catcher layer;
    the phantoms must stand still, the camera may move)"""

    bl_idname = "platelight.bake_shadows"
    bl_label = "Bake Shadows"
    bl_options = {"REGISTER", "UNDO"}

    force: BoolProperty(name="Force", description="Bake even when the shadows on disk are up to date",
                        default=False)
    height: IntProperty(name="Resolution", description="Height of the shadow panorama in pixels "
                        "(width twice)", default=DEFAULT_HEIGHT, min=16, max=8192)
    samples: IntProperty(name="Samples", description="Cycles samples of each render (denoised)",
                         default=DEFAULT_SAMPLES, min=1, max=65536)
    method: EnumProperty(name="Method", description="How the ratio of the light with the CG to the "
                         "light without it is rendered", items=METHODS, default=DEFAULT_METHOD)
    denoiser: EnumProperty(name="Denoiser", description="Who denoises the Shadow Catcher method's render",
                           items=DENOISERS, default=DEFAULT_DENOISER)
    moving_shadows: EnumProperty(name="Moving CG", description="How the shadows of a CG that moves or "
                                 "deforms during the shot are made (it is left out of the still CG's bake)",
                                 items=MOVING_SHADOWS, default=DEFAULT_MOVING_SHADOWS)
    moving_height: IntProperty(name="Moving Resolution", description="Height in pixels of each frame's "
                               "shadow panorama of a moving CG (Baked Every Frame; width twice)",
                               default=DEFAULT_MOVING_HEIGHT, min=16, max=8192)

    @classmethod
    def poll(cls, context):
        if context.scene is None or context.scene.world is None:
            cls.poll_message_set("The scene needs a world (its environment lights the phantoms)")
            return False
        return True

    def execute(self, context):
        try:
            summary = bake_shadows(context, self.height, self.samples, use_cache=not self.force,
                                   method=self.method, denoiser=self.denoiser,
                                   moving_shadows=self.moving_shadows, moving_height=self.moving_height)
        except PlateLightError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        for warning in summary["warnings"]:
            self.report({"WARNING"}, str(warning))
        if summary["reused"]:
            self.report({"INFO"}, f"The baked shadows in {summary['folder']} are up to date.")
        else:
            self.report({"INFO"}, f"Shadows baked in {summary['seconds']:.1f} s into {summary['folder']}.")
        return {"FINISHED"}


classes = (PLATELIGHT_OT_bake_shadows,)
