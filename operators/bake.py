"""Bake per-object reflection probes (paper section 3.3): ``bpy.ops.platelight.bake_probes``.

For every PlateLight object: hide it, put an equirectangular panoramic camera at its centre,
render the rest of the scene (other CG objects, phantoms, world) with Cycles, turn the panorama
into the four maps with the engine and write them next to the .blend. A bake is skipped when the
content hash of its inputs is unchanged, objects off screen for the whole frame range are skipped,
and objects that see nothing but the world share the world's maps.

The scene is restored exactly (camera, frame, render settings, visibility) in ``finally``, on
success, error and cancel alike. ``ProbeBake`` does the work in small steps so the modal
operator can show progress and stop on Esc; ``bake_probes()`` runs it to the end (CLI, scripts).
"""
from __future__ import annotations

import math
import os
import shutil
import tempfile

import bpy
import numpy as np
from bpy.props import BoolProperty, IntProperty

from .. import compat
from .world_environment import probe_image
from ..addon.bake import culling, layout
from ..addon.bake.hashing import content_hash
from .probe_inputs import (GEOMETRY_TYPES, Describer, maps_for, point_inside,
                           probe_origin, renderable, visible_in_probe, world_bounds,
                           world_description)
from ..addon.errors import PlateLightError
from ..addon.exr_io import read_exr
from ..addon.ibl.maps import (DEFAULT_HEIGHTS, MAP_NAMES, MapSettings, compute_maps, map_filename,
                              write_maps)

PROBE_CAMERA = "PlateLight Probe Camera"
# The PANO camera with this rotation renders the Environment Texture's layout (design.md).
PANO_ROTATION = (math.pi / 2, 0.0, -math.pi / 2)
PROBE_CLIP_START = 1e-3
# Cycles builds the world's light-importance map at each render session. Capping it at 256
# columns (scene.platelight.probe_fast_world) makes a 128x64 probe about 3x faster, but under a
# small bright sun (the city HDRI) it leaves fireflies on sunlit surfaces and their median 22 %
# too dark (docs/compositing.md), so the world's own resolution is the default.
PROBE_WORLD_MAP_RESOLUTION = 256

# Counts Cycles probe renders (tests and benchmarks read it to prove a cache hit renders nothing).
render_count = 0
# An owner baked with its shadows (scene.platelight.probe_owner_shadows) is invisible to these
# rays only: the probe looks through it, but the floor under it lies in its shadow, as seen from
# its surface (the paper hides the owner, so a probe shows a sunlit floor under a ball on it).
SHADOW_ONLY_HIDDEN_RAYS = ("visible_camera", "visible_diffuse", "visible_glossy",
                           "visible_transmission", "visible_volume_scatter")


# --------------------------------------------------------------------------- scene state

class SceneState:
    """Remembers attribute values and puts them back in reverse order (each restore on its own,
    so one failure cannot leave the rest of the scene changed)."""

    def __init__(self):
        self._saved = []

    def set(self, owner, attr, value):
        self._saved.append((owner, attr, getattr(owner, attr)))
        setattr(owner, attr, value)

    def restore(self):
        errors = []
        for owner, attr, value in reversed(self._saved):
            try:
                if getattr(owner, attr) != value:
                    setattr(owner, attr, value)
            except (ReferenceError, AttributeError, TypeError, ValueError) as exc:
                errors.append(f"{attr}: {exc}")
        self._saved.clear()
        return errors


# --------------------------------------------------------------------------- the bake

class ProbeBake:
    """One bake: ``validate()`` (raises PlateLightError, touches nothing), ``begin()`` (changes
    render settings, adds the probe camera), ``step()`` until it returns False, ``end()``
    (always: restores the scene). ``summary()`` says what was baked, reused and skipped."""

    def __init__(self, context, objects, frames, *, static=True, use_cache=True,
                 reuse_world=True, cull=True, world_map_resolution="scene",
                 check_only=False):
        self.context = context
        self.check_only = check_only          # compare hashes, render nothing, mark "stale"
        if world_map_resolution == "scene":
            world_map_resolution = (PROBE_WORLD_MAP_RESOLUTION if context.scene.platelight.probe_fast_world
                                    else None)
        self.world_map_resolution = world_map_resolution      # None: leave the world's setting
        self.scene = context.scene
        self.view_layer = context.view_layer
        self.objects = list(objects)
        self.frames = list(frames)
        self.static = static                    # single-frame bake: diffuse.exr, not diffuse_0001.exr
        self.use_cache = use_cache
        self.reuse_world = reuse_world
        self.cull = cull
        self.baked = []                          # (object name, frame)
        self.reused = []
        self.skipped = []                        # (object name, why)
        self.world_only = []
        self.stale = []                          # (object name, frame), check_only
        self.world_baked = False
        self.warnings = []
        self.cancelled = False
        self._state = SceneState()
        self._tmpdir = None
        self._camera = None
        self._queue = []
        self._done = 0
        self._describer = Describer()
        self._bounds = {}
        self._render_results = None
        self._bound = {}                         # object name -> (object, maps rewritten?)

    # ---- paths
    def maps_root(self):
        maps_dir = self.scene.platelight.maps_dir or layout.DEFAULT_MAPS_DIR
        if maps_dir.startswith("//") and not bpy.data.filepath:
            raise PlateLightError("Save the .blend file first: the maps folder is relative to it "
                                  f"({maps_dir}); or set an absolute Maps Folder.")
        return maps_dir

    def folder_for(self, name):
        return self.maps_root().rstrip("/\\") + "/" + name + "/"

    @staticmethod
    def abspath(path):
        return os.path.normpath(bpy.path.abspath(path))

    # ---- checks before touching anything
    def validate(self):
        scene = self.scene
        if scene.camera is None:
            raise PlateLightError("The scene has no camera; add one (it decides which objects are on "
                                  "screen) before baking probes.")
        if scene.world is None:
            raise PlateLightError("The scene has no world; add one (its environment lights the probes) "
                                  "before baking probes.")
        if not self.objects:
            raise PlateLightError("No PlateLight objects to bake: select objects with 'PlateLight "
                                  "Object' ticked, or bake all objects.")
        if scene.platelight.world_probe:
            path = self.abspath(scene.platelight.world_probe)
            if not os.path.isfile(path):
                raise PlateLightError(f"The world probe EXR {path} does not exist; choose another in "
                                      "Scene > PlateLight > World Probe or clear it.")
        for ob in self.objects:
            if ob.library is not None:
                raise PlateLightError(f"'{ob.name}' is linked from the library {ob.library.filepath} and "
                                      "cannot be changed; make it local to bake its probe.")
            if ob.type not in GEOMETRY_TYPES or (ob.type == "MESH" and len(ob.data.vertices) == 0):
                raise PlateLightError(f"'{ob.name}' has no geometry; only objects with a surface get "
                                      "a probe.")
            if max(ob.dimensions) <= 0:
                raise PlateLightError(f"'{ob.name}' has zero size; scale it up to bake its probe.")
        root = self.abspath(self.maps_root())
        if not self.check_only:
            layout.check_writable(root)
        self._plan()

    def _plan(self):
        """Per frame: frustum culling and the 'probe origin inside an object' check. An object
        is skipped only when it is off screen in every frame of the range."""
        scene = self.scene
        frame0 = scene.frame_current
        on_screen = {ob.name: False for ob in self.objects}
        sees_any = {ob.name: False for ob in self.objects}
        try:
            for frame in self.frames:
                if frame != scene.frame_current:
                    scene.frame_set(frame)
                depsgraph = self.context.evaluated_depsgraph_get()
                planes = self._camera_planes()
                others = [o for o in scene.objects if renderable(o, self.view_layer)]
                for ob in self.objects:
                    centre, radius = self.bounds(ob)
                    if culling.sphere_in_frustum(planes, centre, radius):
                        on_screen[ob.name] = True
                    origin = probe_origin(ob)
                    for other in others:
                        if other is ob:          # hidden while its own probe renders
                            continue
                        if visible_in_probe(other) and self._in_range(origin, other):
                            sees_any[ob.name] = True
                        if point_inside(other, depsgraph, origin):
                            raise PlateLightError(
                                f"The probe origin of '{ob.name}' lies inside '{other.name}' (frame "
                                f"{frame}), so its probe would see only that object's inside; move "
                                "the object or set a Probe Origin.")
        finally:
            if scene.frame_current != frame0:
                scene.frame_set(frame0)
        self._queue = []
        for ob in self.objects:
            if self.cull and not on_screen[ob.name]:
                self.skipped.append((ob.name, "outside the camera view in every frame"))
                ob.platelight.probe_status = "skipped: off screen"
                continue
            if self.reuse_world and not sees_any[ob.name]:
                self.world_only.append(ob)
                continue
            self._queue.extend((frame, ob) for frame in self.frames)
        # Frames outermost: one frame_set per frame, whatever the number of objects.
        self._queue.sort(key=lambda item: (self.frames.index(item[0]), item[1].name))
        self.total = len(self._queue) + (1 if self.world_only else 0)

    def _camera_planes(self):
        cam = self.scene.camera
        corners = [tuple(c) for c in cam.data.view_frame(scene=self.scene)] if cam.type == "CAMERA" else \
            [(1, 1, -1), (1, -1, -1), (-1, -1, -1), (-1, 1, -1)]
        data = cam.data if cam.type == "CAMERA" else None
        return culling.frustum_planes(
            np.array(cam.matrix_world), corners,
            data.clip_start if data else 0.1, data.clip_end if data else 1000.0,
            orthographic=bool(data and data.type == "ORTHO"))

    def bounds(self, ob):
        """World bounding sphere at the current frame (memoised: planning and hashing ask often)."""
        key = (ob.name_full, self.scene.frame_current)
        if key not in self._bounds:
            self._bounds[key] = world_bounds(ob)
        return self._bounds[key]

    def _in_range(self, origin, other):
        if other.type == "LIGHT" and other.data.type == "SUN":
            return True                  # a sun lights everything, wherever it is placed
        centre, radius = self.bounds(other)
        return float(np.linalg.norm(centre - origin)) - radius <= self.scene.platelight.probe_distance

    # ---- probe rendering
    def begin(self):
        """Set up rendering for probes; everything changed here is put back by ``end()``."""
        scene, state = self.scene, self._state
        self._render_results = {im.name for im in bpy.data.images if im.type == "RENDER_RESULT"}
        self._tmpdir = tempfile.mkdtemp(prefix="platelight-probe-")
        cam_data = bpy.data.cameras.new(PROBE_CAMERA)
        cam_data.type = "PANO"
        cam_data.panorama_type = "EQUIRECTANGULAR"
        cam_data.clip_start = PROBE_CLIP_START
        cam_data.clip_end = scene.platelight.probe_distance
        self._camera = bpy.data.objects.new(PROBE_CAMERA, cam_data)
        self._camera.rotation_euler = PANO_ROTATION
        scene.collection.objects.link(self._camera)
        height = scene.platelight.probe_height
        render, cycles = scene.render, scene.cycles
        state.set(scene, "camera", self._camera)
        state.set(render, "engine", "CYCLES")
        state.set(render, "resolution_x", 2 * height)
        state.set(render, "resolution_y", height)
        state.set(render, "resolution_percentage", 100)
        state.set(render, "use_border", False)
        state.set(render, "film_transparent", False)
        state.set(render, "use_compositing", False)
        state.set(render, "use_sequencer", False)
        state.set(render, "use_persistent_data", True)      # scene sync once, not per probe
        state.set(render, "use_motion_blur", False)
        # Only the active view layer: compositing setups add layers that hold things out.
        state.set(render, "use_single_layer", True)
        state.set(render, "filepath", os.path.join(self._tmpdir, "probe.exr"))
        fmt = render.image_settings
        for attr, value in compat.still_image_format():
            state.set(fmt, attr, value)
        state.set(fmt, "file_format", "OPEN_EXR")
        state.set(fmt, "color_mode", "RGB")
        state.set(fmt, "color_depth", "32")
        state.set(cycles, "device", "CPU")
        state.set(cycles, "samples", scene.platelight.probe_samples)
        state.set(cycles, "use_adaptive_sampling", False)
        state.set(cycles, "use_denoising", False)
        state.set(cycles, "seed", 0)
        state.set(cycles, "use_animated_seed", False)
        # A box the size of one pixel: each texel is its own area, no blur from neighbours.
        state.set(cycles, "pixel_filter_type", "BOX")
        state.set(cycles, "filter_width", 1.0)
        world = scene.world.cycles
        limit = self.world_map_resolution
        if limit and (world.sampling_method == "AUTOMATIC" or
                      world.sampling_method == "MANUAL" and world.sample_map_resolution > limit):
            state.set(world, "sampling_method", "MANUAL")
            state.set(world, "sample_map_resolution", limit)
        prefs = _preferences(self.context)
        if prefs is not None and prefs.threads > 0:
            state.set(render, "threads_mode", "FIXED")
            state.set(render, "threads", prefs.threads)
        # Holdout / indirect-only are compositing devices: a probe sees everything as it is.
        stack = [self.view_layer.layer_collection]
        while stack:
            layer_collection = stack.pop()
            for flag in ("holdout", "indirect_only"):
                if getattr(layer_collection, flag):
                    state.set(layer_collection, flag, False)
            stack.extend(layer_collection.children)
        # Phantoms stand for real things: probes must see them as they are, not as catchers.
        for ob in scene.objects:
            if ob.platelight.phantom:
                if ob.is_shadow_catcher:
                    state.set(ob, "is_shadow_catcher", False)
                if ob.is_holdout:
                    state.set(ob, "is_holdout", False)

    def render_probe(self, origin, hidden=(), shadow_only=()):
        """Render the panorama seen from ``origin`` (world space) with ``hidden`` objects hidden
        and ``shadow_only`` objects invisible to every ray but shadow rays (an owner that still
        shades the floor under itself); returns float32 (H, 2H, 3), first row the top (the
        Environment Texture's layout)."""
        global render_count
        if self._camera is None:            # set up on the first render: cache hits never need it
            self.begin()
        self._camera.location = tuple(float(x) for x in origin)
        restore = []
        try:
            for ob in hidden:
                if not ob.hide_render:
                    restore.append((ob, "hide_render", False))
                    ob.hide_render = True
            for ob in shadow_only:
                for flag in SHADOW_ONLY_HIDDEN_RAYS:
                    if getattr(ob, flag):
                        restore.append((ob, flag, True))
                        setattr(ob, flag, False)
            try:
                bpy.ops.render.render(write_still=True)
            except RuntimeError as exc:
                reason = str(exc).strip().splitlines()[-1] if str(exc).strip() else "unknown error"
                raise PlateLightError(f"Cycles could not render the probe at {tuple(round(float(x), 3) for x in origin)}: "
                                      f"{reason}") from None
            render_count += 1
        finally:
            for ob, flag, value in restore:
                setattr(ob, flag, value)
        return read_exr(self.scene.render.filepath, "RGB")

    def map_settings(self):
        height = self.scene.platelight.probe_height
        # Maps are never larger than the probe they come from.
        heights = {name: min(h, height) for name, h in DEFAULT_HEIGHTS.items()}
        return MapSettings(sampling=self.scene.platelight.sampling, heights=heights)

    # ---- hashing
    def probe_hash(self, ob, origin, maps):
        settings = self.scene.platelight
        frame = self.scene.frame_current
        seen = sorted((o.name_full, self._describer.seen_digest(o, frame)) for o in self.scene.objects
                      if o is not ob and o is not self._camera and renderable(o, self.view_layer)
                      and self._in_range(origin, o))
        return content_hash({
            "origin": np.asarray(origin), "maps": list(maps), "world": self._world_digest,
            "settings": [settings.probe_height, settings.probe_samples, settings.sampling,
                         settings.probe_fast_world, settings.probe_owner_shadows,
                         settings.probe_distance],
            "render": [self.scene.cycles.max_bounces, self.scene.cycles.diffuse_bounces,
                       self.scene.cycles.glossy_bounces, self.scene.cycles.transmission_bounces],
            "seen": seen,
        })

    # ---- steps
    def start(self):
        self.validate()
        self._world_digest = content_hash(world_description(self.scene))
        self._frame0 = self.scene.frame_current
        self._world_pending = bool(self.world_only)
        self._pending = list(self._queue)

    def step(self):
        """Do one unit of work (the world maps, or one object-frame). False when all is done."""
        if self._world_pending:
            self._world_pending = False
            self._bake_world()
            self._done += 1
            return True
        if not self._pending:
            return False
        frame, ob = self._pending.pop(0)
        if self.scene.frame_current != frame:
            self.scene.frame_set(frame)
        self._bake_object(ob, frame)
        self._done += 1
        return bool(self._pending)

    def _bake_object(self, ob, frame):
        key_frame = None if self.static else frame
        folder_rel = self.folder_for(layout.folder_name(ob.name))
        folder = self.abspath(folder_rel)
        maps = maps_for(ob)
        origin = probe_origin(ob)
        digest = self.probe_hash(ob, origin, maps)
        if self.use_cache and layout.is_cached(folder, key_frame, digest, maps):
            self.reused.append((ob.name, frame))
            status = "baked (unchanged)"
        elif self.check_only:
            self.stale.append((ob.name, frame))
            ob.platelight.probe_status = "stale"
            return
        else:
            if self.scene.platelight.probe_owner_shadows:
                env = self.render_probe(origin, shadow_only=[ob])
            else:                                       # the paper: the owner is simply hidden
                env = self.render_probe(origin, hidden=[ob])
            result = compute_maps(env, self.map_settings(), which=maps)
            self.warnings.extend(f"{ob.name}: {w}" for w in result.warnings)
            write_maps(folder, result.maps, frame=key_frame)
            layout.remove_other_maps(folder, key_frame, keep=maps)
            layout.write_record(folder, key_frame, digest, maps, object=ob.name, scene_frame=frame,
                                origin=[float(x) for x in origin],
                                probe_size=[int(env.shape[1]), int(env.shape[0])])
            self.baked.append((ob.name, frame))
            status = "baked"
        if self.check_only:
            if not any(name == ob.name for name, _ in self.stale):
                ob.platelight.probe_status = "up to date"
            return
        if not self.static:
            layout.remove_single_frame(folder)
        if self.scene.platelight.pack_maps:
            self._pack(folder_rel, key_frame, maps, refresh=status == "baked")
        ob.platelight.probe_dir = folder_rel
        self._note_bound(ob, status == "baked")
        ob.platelight.probe_hash = digest
        ob.platelight.probe_status = status if self.static else f"{status} (frames {self.frames[0]}-{self.frames[-1]})"

    def _pack(self, folder_rel, frame, maps, refresh):
        for name in maps:
            filename = map_filename(name, frame)
            pack_map(folder_rel + filename, f"PlateLight {folder_rel.rstrip('/').rsplit('/', 1)[-1]}/{filename}",
                     refresh)

    def world_folder(self):
        return self.folder_for(layout.WORLD_FOLDER)

    def _bake_world(self):
        """The world's own maps: from the World Probe EXR, else the world's environment EXR,
        else a probe render of the world alone. Shared by every object that sees only the world."""
        scene = self.scene
        folder_rel = self.world_folder()
        folder = self.abspath(folder_rel)
        settings = self.map_settings()
        image = probe_image(scene)
        source = image.path if image is not None else None
        if source is not None:
            # Full-resolution maps from the image itself (not capped by the probe height).
            settings.heights = dict(DEFAULT_HEIGHTS)
        digest = content_hash({"world": self._world_digest, "source": source,
                               "strength": image.strength if image else None,
                               "rotation": image.rotation if image else None,
                               "heights": settings.heights,
                               "sampling": settings.sampling,
                               "samples": None if source else scene.platelight.probe_samples,
                               "probe_height": None if source else scene.platelight.probe_height})
        cached = self.use_cache and layout.is_cached(folder, None, digest, MAP_NAMES)
        if self.check_only:
            for ob in self.world_only:
                ob.platelight.probe_status = "up to date (world maps)" if cached else "stale"
                if not cached:
                    self.stale.append((ob.name, None))
            return
        if not cached:
            if image is not None:
                env = image.read()
            else:
                hidden = [o for o in scene.objects if renderable(o, self.view_layer)]
                env = self.render_probe((0.0, 0.0, 0.0), hidden=hidden)
            result = compute_maps(env, settings, which=MAP_NAMES)
            self.warnings.extend(f"world: {w}" for w in result.warnings)
            write_maps(folder, result.maps, frame=None)
            layout.write_record(folder, None, digest, MAP_NAMES, source=source or "render")
            self.world_baked = True
        if scene.platelight.pack_maps:
            self._pack(folder_rel, None, MAP_NAMES, refresh=not cached)
        for ob in self.world_only:
            ob.platelight.probe_dir = folder_rel
            self._note_bound(ob, not cached)
            ob.platelight.probe_hash = digest
            ob.platelight.probe_status = "world maps (sees only the world)"

    def _note_bound(self, ob, rewritten):
        _, before = self._bound.get(ob.name, (ob, False))
        self._bound[ob.name] = (ob, before or rewritten)

    def _follow_materials(self):
        """Materials follow the bake: SBRDF materials of the objects just baked are (re)bound
        to their probe folders and their maps reloaded (issue 5: re-bakes need no re-apply)."""
        from ..node_groups.sbrdf_material import follow_probe

        for ob, rewritten in self._bound.values():
            follow_probe(ob, self.scene, reload=rewritten)
        self._bound = {}

    def cancel(self):
        """Stop after the current step; maps already written stay (each file was replaced whole)."""
        self.cancelled = True
        finished = {name for name, _ in self.baked + self.reused}
        for _, ob in self._pending:
            if ob.name not in finished:
                ob.platelight.probe_status = "cancelled"
        self._pending = []
        self._world_pending = False

    def end(self):
        """Put the scene back as it was (always called, also after errors and cancel)."""
        scene = self.scene
        errors = self._state.restore()
        if self._camera is not None:
            cam_data = self._camera.data
            bpy.data.objects.remove(self._camera, do_unlink=True)
            bpy.data.cameras.remove(cam_data, do_unlink=True)
            self._camera = None
        for image in [im for im in bpy.data.images if im.type == "RENDER_RESULT"]:
            if self._render_results is not None and image.name not in self._render_results:
                bpy.data.images.remove(image)       # the probe renders' result, not the user's
        self._render_results = None
        if getattr(self, "_frame0", None) is not None and scene.frame_current != self._frame0:
            scene.frame_set(self._frame0)
        if self._tmpdir:
            shutil.rmtree(self._tmpdir, ignore_errors=True)
            self._tmpdir = None
        if errors:
            self.warnings.append("Some render settings could not be restored: " + "; ".join(errors))
        self._follow_materials()

    @property
    def progress(self):
        return self._done, max(self.total, 1)

    def summary(self):
        if self.check_only:
            names = sorted({name for name, _ in self.stale})
            fresh = len({ob.name for ob in self.objects} - set(names)) - len(self.skipped)
            text = f"PlateLight: {fresh} probe(s) up to date"
            if names:
                text += f"; {len(names)} stale ({', '.join(names)})"
            if self.skipped:
                text += f"; {len(self.skipped)} off screen"
            return text + "."
        parts = []
        if self.baked:
            parts.append(f"baked {len(self.baked)} probe(s)")
        if self.reused:
            parts.append(f"reused {len(self.reused)} unchanged")
        if self.world_only:
            parts.append(f"{len(self.world_only)} object(s) use the world maps")
        if self.skipped:
            names = ", ".join(name for name, _ in self.skipped)
            parts.append(f"skipped {len(self.skipped)} off screen ({names})")
        text = "PlateLight: " + ("; ".join(parts) if parts else "nothing to bake")
        if self.cancelled:
            text = "PlateLight bake cancelled after " + ("; ".join(parts) if parts else "nothing") + \
                   "; finished maps were kept"
        return text + "."


def pack_map(rel_path, label, refresh):
    """Pack one map file into the .blend as the image ``label`` (its filepath the Blender-relative
    file, so a material loading that file with check_existing finds it). Re-packing updates the
    same image: never a duplicate."""
    image = bpy.data.images.get(label)
    if image is None:
        image = bpy.data.images.load(rel_path, check_existing=True)
        image.name = label
    elif refresh or image.packed_file is None or image.filepath != rel_path:
        if image.packed_file is not None:
            image.unpack(method="REMOVE")
        image.filepath = rel_path
        image.reload()
    else:
        return image
    image.pack()
    return image


def _preferences(context):
    root = __package__.rsplit(".", 1)[0]
    addon = context.preferences.addons.get(root)
    return addon.preferences if addon is not None else None


def target_objects(context, all_objects):
    """PlateLight objects to bake: all in the scene, or the selected ones."""
    pool = context.scene.objects if all_objects else (context.selected_objects or [])
    return [ob for ob in pool if ob.platelight.enabled and not ob.platelight.phantom]


def bake_probes(context, objects, frames, *, static=True, use_cache=True, reuse_world=True,
                cull=True, progress=None) -> ProbeBake:
    """Run a whole bake (scripts, CLI). Raises PlateLightError; the scene is restored either way."""
    job = ProbeBake(context, objects, frames, static=static, use_cache=use_cache,
                    reuse_world=reuse_world, cull=cull)
    try:
        job.start()
        while job.step():
            if progress:
                progress(*job.progress)
    finally:
        job.end()
    return job


# --------------------------------------------------------------------------- operator

class _ProbeOperator:
    """What bake_probes and check_probes share: targets, frames, options, running the job."""
    check_only = False

    all_objects: BoolProperty(name="All Objects", default=False,
                              description="Bake every PlateLight object in the scene, not only the selected ones")
    use_frame_range: BoolProperty(name="Frame Range", default=False,
                                  description="Bake every frame from Start to End (per-frame maps)")
    frame_start: IntProperty(name="Start", default=1, description="First frame of the range")
    frame_end: IntProperty(name="End", default=1, description="Last frame of the range")
    force: BoolProperty(name="Re-bake Unchanged", default=False,
                        description="Render probes even when nothing that affects them changed")
    cull: BoolProperty(name="Skip Off-screen Objects", default=True,
                       description="Skip objects outside the camera view in every frame")
    reuse_world: BoolProperty(name="Share World Maps", default=True,
                              description="Objects that see nothing but the world use the world's maps")

    _job = None
    _timer = None

    @classmethod
    def poll(cls, context):
        if context.scene is None:
            return False
        if context.mode != "OBJECT":
            cls.poll_message_set("Switch to Object Mode to bake probes")
            return False
        return True

    def _frames(self, context):
        """(frames, static): the range when asked for (frame_start/frame_end given or Frame
        Range ticked), else the current frame with single-frame file names."""
        props = self.properties
        if self.use_frame_range or props.is_property_set("frame_start") or props.is_property_set("frame_end"):
            start = self.frame_start
            end = self.frame_end if props.is_property_set("frame_end") or self.use_frame_range else start
            if end < start:
                raise PlateLightError(f"The frame range ends ({end}) before it starts ({start}).")
            return list(range(start, end + 1)), False
        return [context.scene.frame_current], True

    def _make_job(self, context):
        frames, static = self._frames(context)
        prefs = _preferences(context)
        use_cache = not self.force and (prefs is None or prefs.cache_bakes)
        return ProbeBake(context, target_objects(context, self.all_objects), frames, static=static,
                         use_cache=use_cache or self.check_only, reuse_world=self.reuse_world,
                         cull=self.cull, check_only=self.check_only)

    def execute(self, context):
        wm = context.window_manager
        try:
            job = self._make_job(context)
        except PlateLightError as err:
            self.report({"ERROR"}, str(err))
            return {"CANCELLED"}
        wm.progress_begin(0, 1)
        try:
            job.start()
            while job.step():
                done, total = job.progress
                wm.progress_update(done / total)
        except PlateLightError as err:
            self.report({"ERROR"}, str(err))
            return {"CANCELLED"}
        finally:
            job.end()
            wm.progress_end()
        return self._finish(job)

    def _finish(self, job):
        for warning in job.warnings:
            self.report({"WARNING"}, warning)
        self.report({"INFO"}, job.summary())
        return {"CANCELLED"} if job.cancelled else {"FINISHED"}

    def invoke(self, context, event):
        if bpy.app.background or context.window is None or self.check_only:
            return self.execute(context)
        try:
            self._job = self._make_job(context)
            self._job.start()
        except PlateLightError as err:
            if self._job is not None:
                self._job.end()
            self.report({"ERROR"}, str(err))
            return {"CANCELLED"}
        wm = context.window_manager
        wm.progress_begin(0, 1)
        self._timer = wm.event_timer_add(0.01, window=context.window)
        wm.modal_handler_add(self)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        job = self._job
        if event.type == "ESC":
            job.cancel()
            return self._stop(context)
        if event.type != "TIMER":
            return {"RUNNING_MODAL"}
        try:
            more = job.step()
        except PlateLightError as err:
            self._stop(context, finish=False)
            self.report({"ERROR"}, str(err))
            return {"CANCELLED"}
        except Exception:
            self._stop(context, finish=False)      # a bug: still give the user their scene back
            raise
        done, total = job.progress
        context.window_manager.progress_update(done / total)
        context.workspace.status_text_set(f"PlateLight: baking probe {done}/{total} (Esc to cancel)")
        return {"RUNNING_MODAL"} if more else self._stop(context)

    def _stop(self, context, finish=True):
        wm = context.window_manager
        if self._timer is not None:
            wm.event_timer_remove(self._timer)
            self._timer = None
        self._job.end()
        wm.progress_end()
        context.workspace.status_text_set(None)
        return self._finish(self._job) if finish else {"CANCELLED"}


class PLATELIGHT_OT_bake_probes(_ProbeOperator, bpy.types.Operator):
    """Render each PlateLight object's surroundings from its centre and bake its four maps"""
    bl_idname = "platelight.bake_probes"
    bl_label = "Bake PlateLight Probes"
    bl_options = {"REGISTER", "UNDO"}


class PLATELIGHT_OT_check_probes(_ProbeOperator, bpy.types.Operator):
    """Tell which probes are stale (their inputs changed since the bake) without rendering"""
    bl_idname = "platelight.check_probes"
    bl_label = "Check PlateLight Probes"
    bl_options = {"REGISTER", "UNDO"}
    check_only = True


def menu_entry(self, context):
    self.layout.separator()
    self.layout.operator(PLATELIGHT_OT_bake_probes.bl_idname, icon="LIGHTPROBE_SPHERE")


classes = (PLATELIGHT_OT_bake_probes, PLATELIGHT_OT_check_probes)


def register_extra():
    bpy.types.VIEW3D_MT_object.append(menu_entry)
    bpy.types.TOPBAR_MT_render.append(menu_entry)


def unregister_extra():
    bpy.types.VIEW3D_MT_object.remove(menu_entry)
    bpy.types.TOPBAR_MT_render.remove(menu_entry)
