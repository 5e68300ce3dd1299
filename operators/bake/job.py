"""One bake of per-object reflection probes (paper section 3.3), run by the operators of
__init__.py, by ``python -m platelight bake`` (drivers/bake.py) and by scripts (bake_probes()).

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

import os

import bpy
import numpy as np

from ...addon.bake import culling, layout, needs, probe_reuse, probe_size
from ...addon.bake.frames import sample_frames
from ...addon.bake.hashing import content_hash
from ...addon.errors import PlateLightError
from ...addon.ibl import distance as distance_maps
from ...addon.ibl import irradiance_grid, sun_lobe, view_lobe
from ...addon.ibl.maps import (DEFAULT_HEIGHTS, DIFFUSE_LMAX_EXACT, MAP_NAMES, MapSettings, compute_maps,
                               prepare_environment, write_maps)
from .. import motion
from ..common import GEOMETRY_TYPES, addon_preferences, classify_objects
from .inputs import (Describer, maps_for, owner_visibility, point_inside, probe_origin, wants_behind_layer,
                     renderable, visible_in_probe, wants_sharp_probe, world_bounds, world_description)
from .distance_render import distance_height, surface_points, write_probe_distance
from .probe_render import PROBE_WORLD_MAP_RESOLUTION, ProbeRenderer, detach_unseen_maps
from .records import pack_maps, probe_hash, world_maps_hash
from .scene_state import SceneState
from ..world_environment import probe_image

REUSE_KEY = "reused"          # in a frame's record: {"frame": whose probe it took, "tolerance": Probe Reuse}

# needs.owner_visibility's answer -> the ProbeRenderer.render argument that places the owner.
OWNER_RENDER_ARGUMENT = {needs.OWNER_HIDDEN: "hidden", needs.OWNER_SHADOWS: "shadow_only",
                         needs.OWNER_INDIRECT: "camera_hidden"}


class ProbeBake:
    """One bake: ``start()`` (validates and plans: raises PlateLightError, changes nothing but the
    objects' status), ``step()`` until it returns False (the first probe render changes the render
    settings and adds the probe camera, probe_render.py), ``end()`` (always: restores the scene).
    ``summary()`` says what was baked, reused and skipped."""

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
        self.reused_near = []                    # (object name, frame, the frame whose probe it took)
        self._rendered = {}                      # object name -> its last rendered probe (probe_reuse)
        self.skipped = []                        # (object name, why)
        self.world_only = []
        self.stale = []                          # (object name, frame), check_only
        self.world_baked = False
        self.warnings = []
        self.cancelled = False
        self._state = SceneState()
        self._renderer = ProbeRenderer(context, self._state, world_map_resolution)
        self._queue = []
        self._done = 0
        self._describer = Describer()
        self._bounds = {}
        self._bound = {}                         # object name -> (object, maps rewritten?)
        self.heights = {}                        # object name -> probe height (px)

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
            # before any hash: the plate projected onto phantoms (or their own materials)
            from ..phantoms import apply_phantom_surfaces   # phantoms imports this package's SceneState
            apply_phantom_surfaces(scene, [ob for ob in scene.objects if ob.platelight.phantom])
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
        self.heights = self._probe_heights()
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

    # Frames sampled to size a static probe, which serves every frame of the scene's range.
    SIZE_SAMPLE_FRAMES = 48

    def _probe_heights(self):
        """Object name -> probe height for the objects with a sharp reflection (probe_auto_size):
        twice their largest width on screen over the frames the probe serves, within Probe Height
        and Max Probe Height (addon/bake/probe_size.py). Other objects use Probe Height."""
        settings = self.scene.platelight
        heights = {}                     # only the sized ones; the rest render at Probe Height
        sharp = [ob for ob in self.objects if settings.probe_auto_size and wants_sharp_probe(ob)]
        if not sharp:
            return heights
        scene = self.scene
        if self.static:
            frames = sorted({*sample_frames(scene.frame_start, scene.frame_end, self.SIZE_SAMPLE_FRAMES),
                             scene.frame_current})
        else:
            frames = self.frames
        render = scene.render
        width_px = render.resolution_x * render.resolution_percentage / 100.0
        widest = {ob.name: 0.0 for ob in sharp}
        frame0 = scene.frame_current
        try:
            for frame in frames:
                if frame != scene.frame_current:
                    scene.frame_set(int(frame))
                cam = scene.camera
                if cam.type != "CAMERA":
                    continue
                corners = [tuple(c) for c in cam.data.view_frame(scene=scene)]
                depsgraph = self.context.evaluated_depsgraph_get()
                for ob in sharp:
                    points = surface_points(ob, depsgraph)
                    widest[ob.name] = max(widest[ob.name], probe_size.projected_extent(
                        np.array(cam.matrix_world), corners, width_px, points,
                        orthographic=cam.data.type == "ORTHO"))
        finally:
            if scene.frame_current != frame0:
                scene.frame_set(frame0)
        for ob in sharp:
            heights[ob.name] = probe_size.auto_probe_height(widest[ob.name], settings.probe_height,
                                                            max(settings.probe_height, settings.probe_max_height))
        return heights

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
    def render_probe(self, origin, hidden=(), shadow_only=(), distance=False, height=None, camera_hidden=(),
                     behind=None):
        """The panorama seen from ``origin`` (probe_render.ProbeRenderer.render)."""
        return self._renderer.render(origin, hidden=hidden, shadow_only=shadow_only, distance=distance,
                                     height=height, camera_hidden=camera_hidden, behind=behind)

    def map_settings(self, sized_height=None):
        """Map sizes: never larger than the probe; a probe sized to its object on screen
        (``sized_height``) keeps its full height in the specular map (the default 128 would blur a
        large mirror again)."""
        height = sized_height or self.scene.platelight.probe_height
        heights = {name: min(h, height) for name, h in DEFAULT_HEIGHTS.items()}
        if sized_height:
            heights["specular"] = sized_height
        return MapSettings(sampling=self.scene.platelight.sampling, heights=heights,
                           lobes=view_lobe.contract_lobes(self.scene.platelight.glossy_lobes))

    # ---- hashing
    def probe_hash(self, ob, origin, maps, owner, grid, behind=False):
        frame = self.scene.frame_current
        seen = sorted((o.name_full, self._describer.seen_digest(o, frame)) for o in self.scene.objects
                      if o is not ob and o is not self._renderer.camera and renderable(o, self.view_layer)
                      and self._in_range(origin, o))
        return probe_hash(self.scene, origin, maps, self._world_digest, seen, self.map_settings(),
                          self.heights.get(ob.name), owner, grid, behind)

    # ---- steps
    def start(self):
        self.validate()
        if self.static and self._queue and not self.check_only:
            self._warn_of_motion()
        self._world_digest = content_hash(world_description(self.scene))
        self._frame0 = self.scene.frame_current
        self._world_pending = bool(self.world_only)
        self._pending = list(self._queue)
        owners = {ob.name: ob for _, ob in self._queue}
        if len(owners) == 1 and not self.check_only:
            # No probe camera sees its owner (in every owner mode): one object's maps are unseen
            others = [o for o in self.scene.objects if o.name not in owners and renderable(o, self.view_layer)]
            detach_unseen_maps(self._state, owners.values(), others)

    def _warn_of_motion(self):
        """A single-frame probe holds the scene as it is now: say so where something in it moves."""
        cg, phantoms = classify_objects(self.scene)
        moving = motion.motions(self.scene, cg + phantoms)
        if moving:
            first = next(iter(moving.values()))
            more = f" (and {len(moving) - 1} more)" if len(moving) > 1 else ""
            self.warnings.append(f"{first.sentence()}{more}: these probes hold the scene as it is at frame "
                                 f"{self.scene.frame_current}; bake the frame range (Frame Range) for "
                                 "probes that follow what moves.")

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
        owner = owner_visibility(ob, self.scene.platelight.probe_owner_shadows)
        wants_grid = needs.wants_irradiance_grid(maps, self.scene.platelight.probe_diffuse_parallax)
        height = self.heights.get(ob.name)
        wants_behind = wants_behind_layer(ob, maps, self.scene.platelight, distance_height(
            height or self.scene.platelight.probe_height))
        digest = self.probe_hash(ob, origin, maps, owner, wants_grid, wants_behind)
        inputs = (maps, owner, wants_grid, wants_behind)
        record = layout.read_record(folder, key_frame) if self.use_cache else {}
        reused_from = record.get(REUSE_KEY)
        if self.use_cache and layout.is_cached(folder, key_frame, digest, maps, record) and self._reuse_holds(reused_from):
            self.reused.append((ob.name, frame))
            status = "baked (unchanged)"
            if not reused_from:
                self._remember_render(ob, frame, origin, digest, inputs)
        elif self.check_only:
            self.stale.append((ob.name, frame))
            ob.platelight.probe_status = "stale"
            return
        elif self._reuse_render(ob, frame, folder, origin, digest, inputs):
            status = "baked"
        else:
            # the glossy look-ups and the diffuse grid both see the scene through the distance map
            wants_distance = wants_grid or any(name != "diffuse" for name in maps)
            placed = {OWNER_RENDER_ARGUMENT[owner]: [ob]}
            points = (surface_points(ob, self.context.evaluated_depsgraph_get())
                      if wants_distance else None)
            reach = float(np.linalg.norm(points - origin, axis=1).max()) if wants_behind else None
            env = self.render_probe(origin, distance=wants_distance, height=height, behind=reach, **placed)
            settings = self.map_settings(height)
            result = compute_maps(env, settings, which=maps)
            self.warnings.extend(f"{ob.name}: {w}" for w in result.warnings)
            write_maps(folder, result.maps, frame=key_frame)
            sun, sunless_env = self._bake_lookup_maps(folder, env, settings, maps, key_frame)
            grid = {}
            if wants_distance:
                self.warnings.extend(f"{ob.name}: {w}" for w in write_probe_distance(
                    self._renderer.distance, folder, key_frame, points - origin))
            else:
                distance_maps.remove_distance(folder, key_frame)
            self._write_behind(folder, key_frame, settings)
            if wants_grid:
                grid = self._write_irradiance_grid(env if sunless_env is None else sunless_env, points,
                                                   origin, settings, folder, key_frame, sunless_env is not None)
            else:
                irradiance_grid.remove_grid(folder, key_frame)
            layout.remove_other_maps(folder, key_frame, keep=maps)
            layout.write_record(folder, key_frame, digest, maps, object=ob.name, scene_frame=frame,
                                origin=[float(x) for x in origin],
                                probe_size=[int(env.shape[1]), int(env.shape[0])], **grid, **sun)
            self.baked.append((ob.name, frame))
            self._remember_render(ob, frame, origin, digest, inputs)
            status = "baked"
        if self.check_only:
            if not any(name == ob.name for name, _ in self.stale):
                ob.platelight.probe_status = "up to date"
            return
        if not self.static:
            layout.remove_single_frame(folder)
        if self.scene.platelight.pack_maps:
            pack_maps(folder_rel, key_frame, maps, refresh=status == "baked")
        ob.platelight.probe_dir = folder_rel
        self._note_bound(ob, status == "baked")
        ob.platelight.probe_hash = digest
        ob.platelight.probe_status = status if self.static else f"{status} (frames {self.frames[0]}-{self.frames[-1]})"

    def _remember_render(self, ob, frame, origin, digest, inputs):
        """Keep what a later frame needs to reuse this frame's probe (probe_reuse.py)."""
        if self.static or self.scene.platelight.probe_reuse <= 0:
            return
        self._rendered[ob.name] = {
            "frame": frame, "origin": np.asarray(origin, dtype=np.float64), "digest": digest, "inputs": inputs,
            "points": surface_points(ob, self.context.evaluated_depsgraph_get()), "radius": self.bounds(ob)[1]}

    def _reuse_holds(self, reused_from) -> bool:
        """A frame that took another's probe (its record's ``reused_from``) stays valid only under
        the Probe Reuse it was made with."""
        return not reused_from or reused_from.get("tolerance") == self.scene.platelight.probe_reuse

    def _reuse_render(self, ob, frame, folder, origin, digest, inputs) -> bool:
        """Give this frame the last rendered probe of ``ob`` when the object has moved little since
        (Probe Reuse) and all else it sees is the same: the same inputs hash from that centre.
        The record keeps the rendered centre, where the panorama's look-ups start."""
        rendered = self._rendered.get(ob.name)
        if rendered is None or rendered["inputs"] != inputs:
            return False
        tolerance = self.scene.platelight.probe_reuse
        points = surface_points(ob, self.context.evaluated_depsgraph_get())
        if not probe_reuse.reusable(points, origin, rendered, rendered["radius"], tolerance):
            return False
        if self.probe_hash(ob, rendered["origin"], *inputs) != rendered["digest"]:
            return False                 # something else it sees has changed since
        source = rendered["frame"]
        layout.copy_frame(folder, source, frame)
        record = {k: v for k, v in layout.read_record(folder, source).items() if k not in ("hash", "maps")}
        record.update(scene_frame=frame, **{REUSE_KEY: {"frame": source, "tolerance": tolerance}})
        layout.write_record(folder, frame, digest, inputs[0], **record)
        self.reused_near.append((ob.name, frame, source))
        return True

    def _bake_lookup_maps(self, folder, env, settings, maps, key_frame):
        """The files the probe group reads beside the maps, each only when the scene asks for it:
        the sunless maps and the record's sun (Sun Highlight, sun_lobe.bake_sunless), and the
        view-dependent ladder's rungs (Glossy Lobes, view_lobe.bake), made without the sun where
        the bake split one. Returns (the record's entries, the probe without its sun where the
        record has one, else None); without either, the paper's files alone."""
        plate = self.scene.platelight
        ladder = view_lobe.in_use(plate.glossy_lobes, plate.sampling) and view_lobe.wanted(maps)
        record = {}
        found = None
        # split the sun only where a sunless map or the ladder will be made from the split
        splits = plate.probe_sun_lobe and (ladder or any(name in maps for name in sun_lobe.SUNLESS_MAPS))
        if splits or ladder:
            source = sun_lobe.bake_source(env)
            found = sun_lobe.split(source) if splits else (None, source)
        if plate.probe_sun_lobe:
            record.update(sun_lobe.bake_sunless(folder, env, settings, maps, key_frame, found))
        else:
            sun_lobe.remove_sunless(folder, key_frame)
        if ladder:
            # the rungs lose the sun exactly when the record keeps it (the shader adds it back)
            sunless = sun_lobe.RECORD_KEY in record
            rung_source = found[1] if sunless else source
            probe_rows = int(settings.heights.get("specular", DEFAULT_HEIGHTS["specular"]))
            heights = {name: min(height, probe_rows) for name, height in view_lobe.RUNG_HEIGHTS.items()}
            record.update(view_lobe.bake(folder, rung_source, heights, key_frame, sunless))
        else:
            view_lobe.remove(folder, key_frame)
        return record, (found[1] if sun_lobe.RECORD_KEY in record else None)

    def _write_behind(self, folder, key_frame, settings):
        """The layer behind the first surface (behind_render.py): its specular map and distance
        map beside the probe's, or neither (not wanted, or no near occluder's edge to pass)."""
        if self._renderer.behind is None:
            distance_maps.remove_behind(folder, key_frame)
            return
        env, (dist, _) = self._renderer.behind
        result = compute_maps(env, settings, which=("specular",))
        distance_maps.write_behind(folder, result.maps["specular"], dist, key_frame)

    def _write_irradiance_grid(self, env, points, origin, settings, folder, key_frame, sunless):
        """The diffuse maps of a grid of points over the object's bounding box, seen through its
        probe's distance map (addon/ibl/irradiance_grid.py), as one atlas; returns what the
        record keeps of it (the shader's box and grid size; ``sunless``: ``env`` is the probe
        without the record's sun, which the shader adds exactly)."""
        lo, hi = irradiance_grid.grid_box(points.min(axis=0), points.max(axis=0))
        count = irradiance_grid.DEFAULT_POINTS
        offsets = irradiance_grid.grid_points(lo, hi, count) - origin
        radiance, _ = prepare_environment(env)
        height = int(settings.heights["diffuse"])
        prefs = addon_preferences(self.context)
        maps = irradiance_grid.irradiance_maps(radiance, self._renderer.distance[0], offsets, height,
                                               DIFFUSE_LMAX_EXACT, workers=prefs.threads if prefs else None)
        irradiance_grid.write_grid(folder, irradiance_grid.atlas(maps), key_frame)
        return {irradiance_grid.RECORD_KEY: {"lo": [float(x) for x in lo], "hi": [float(x) for x in hi],
                                             "points": count, "height": height, "sunless": bool(sunless)}}

    def world_folder(self):
        return self.folder_for(layout.WORLD_FOLDER)

    def _bake_world(self):
        """The world's own maps: from the World Probe EXR, else the world's environment EXR,
        else a probe render of the world alone. Shared by every object that sees only the world."""
        scene = self.scene
        folder_rel = self.world_folder()
        folder = self.abspath(folder_rel)
        settings = self.map_settings()
        image = probe_image(scene)     # the world's EXR with its strength and Mapping rotation
        source = image.path if image is not None else None
        if image is not None:
            # Full-resolution maps from the image itself (not capped by the probe height).
            settings.heights = dict(DEFAULT_HEIGHTS)
        digest = world_maps_hash(scene, self._world_digest, image, settings)
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
            sun, _ = self._bake_lookup_maps(folder, env, settings, MAP_NAMES, None)
            layout.write_record(folder, None, digest, MAP_NAMES, source=source or "render", **sun)
            self.world_baked = True
        if scene.platelight.pack_maps:
            pack_maps(folder_rel, None, MAP_NAMES, refresh=not cached)
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
        from ...node_groups.sbrdf_material import follow_probe

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
        self._renderer.end()
        if getattr(self, "_frame0", None) is not None and scene.frame_current != self._frame0:
            scene.frame_set(self._frame0)
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
        if self.reused_near:
            parts.append(f"{len(self.reused_near)} frame(s) took the probe of a frame before (moved little)")
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
        more = True
        while more:
            done = job.progress[0]
            more = job.step()
            if progress and job.progress[0] > done:     # after every unit, the last one too
                progress(*job.progress)
    finally:
        job.end()
    return job
