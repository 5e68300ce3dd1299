"""The probe's panorama: an equirectangular camera at the probe origin and the Cycles settings a
probe is rendered with, set up on the first render of a bake and removed at its end. The scene
settings changed on the way are recorded in the bake's SceneState (scene_state.py)."""
from __future__ import annotations

import math
import os
import shutil
import tempfile

import bpy
import numpy as np

from ... import compat
from ...addon import names
from ...node_groups.distance_material import remove_distance_material
from ...node_groups.probe_maps import map_nodes, unbaked_map
from ...node_groups.sbrdf_material import probe_groups
from ...addon.bake.probe_size import samples_for
from ...addon.errors import PlateLightError
from ...addon.exr_io import read_exr
from ...addon.ibl.distance import near_silhouette
from ...addon.ibl.equirect import downsample_area
from ..common import addon_preferences
from ..world_environment import world_image
from .behind_render import peeled, peeled_distance_material, remove as remove_peeled_material
from .distance_render import render_distance
from .pass_denoise import denoise_pass

# The PANO camera with this rotation renders the Environment Texture's layout (design.md).
PANO_ROTATION = (math.pi / 2, 0.0, -math.pi / 2)
PROBE_CLIP_START = 1e-3
# The multilayer EXR's layer (pass) that holds Cycles' shadow catcher ratio.
SHADOW_CATCHER_PASS = "Shadow Catcher"
# Cycles' Filter Glossy in every bake: its blur biases the light a mirror CG sends onto the floor
# (docs/decisions.md, "Bakes at Filter Glossy 0").
BAKE_FILTER_GLOSSY = 0.0
DENOISING_NORMAL_PASS = "Denoising Normal"
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
# A sharp reflector or a glossy metal is hidden from camera rays only (addon/bake/needs.owner_visibility).
SHADOW_ONLY_HIDDEN_RAYS = ("visible_camera", "visible_diffuse", "visible_glossy",
                           "visible_transmission", "visible_volume_scatter")


def render_key(cycles, diffuse_bounces=None) -> list:
    """The render settings a bake's pixels depend on, for its cache hash: the scene's bounce limits
    (``diffuse_bounces`` where the bake caps them) and the bake's own Filter Glossy."""
    diffuse = cycles.diffuse_bounces if diffuse_bounces is None else diffuse_bounces
    return [cycles.max_bounces, diffuse, cycles.glossy_bounces, cycles.transmission_bounces, BAKE_FILTER_GLOSSY]


def detach_unseen_maps(state, unseen, seen):
    """Point the SBRDF probe maps of the ``unseen`` objects at the black stand-in until ``state``
    is restored, but for maps a ``seen`` object's material reads too. Only camera rays read an
    SBRDF's maps (every other ray sees its Principled twin), so maps no render's camera sees
    change none of its pixels; bound as image sequences, Cycles reloaded them at every frame of a
    frame-range bake, which made a re-bake's panoramas about 5x slower (0.3 s to 1.7 s at 128x64)."""
    groups = probe_groups(unseen) - probe_groups(seen)
    stand_in = unbaked_map() if groups else None
    for tree in groups:
        for node in map_nodes(tree):
            if node.image is not stand_in:
                state.set(node, "image", stand_in)


class ProbeRenderer:
    """Renders probes for one bake: ``render()`` sets everything up the first time (so a bake of
    cache hits never touches the render settings), ``end()`` removes the camera, the render
    results and the temporary folder (the bake restores the recorded settings before)."""

    def __init__(self, context, state, world_map_resolution, denoise=False, samples=None, view_layer=None,
                 catcher_denoiser="CYCLES"):
        self.context = context
        self.denoise = denoise               # OpenImageDenoise on the panorama (baked shadows)
        # Who denoises a catcher render's pass: CYCLES (with Combined and the matte) or the
        # COMPOSITOR's Denoise node (that pass alone, pass_denoise.py)
        self.catcher_denoiser = catcher_denoiser
        self.samples = samples               # None: the scene's Probe Samples
        self.scene = context.scene
        self.view_layer = view_layer or context.view_layer     # the layer rendered
        self.world_map_resolution = world_map_resolution      # None: leave the world's setting
        self._state = state
        self.camera = None
        self._tmpdir = None
        self._render_results = None
        self.distance = None
        self.behind = None                   # (panorama, (distance map, warnings)) behind the first surface
        self._world = None                   # the world's image when the world is exactly one
        self._world_maps = {}                # height -> that image area-averaged to the probe

    def begin(self):
        """Set up rendering for probes; every setting changed here is recorded in the state."""
        scene, state = self.scene, self._state
        self._render_results = {im.name for im in bpy.data.images if im.type == "RENDER_RESULT"}
        self._tmpdir = tempfile.mkdtemp(prefix="platelight-probe-")
        cam_data = bpy.data.cameras.new(names.PROBE_CAMERA)
        cam_data.type = "PANO"
        cam_data.panorama_type = "EQUIRECTANGULAR"
        cam_data.clip_start = PROBE_CLIP_START
        cam_data.clip_end = scene.platelight.probe_distance
        self.camera = bpy.data.objects.new(names.PROBE_CAMERA, cam_data)
        self.camera.rotation_euler = PANO_ROTATION
        scene.collection.objects.link(self.camera)
        height = scene.platelight.probe_height
        render, cycles = scene.render, scene.cycles
        state.set(scene, "camera", self.camera)
        state.set(render, "engine", "CYCLES")
        state.set(render, "resolution_x", 2 * height)
        state.set(render, "resolution_y", height)
        state.set(render, "resolution_percentage", 100)
        state.set(render, "use_border", False)
        self._world = self._exact_world()
        state.set(render, "film_transparent", self._world is not None)
        state.set(render, "use_compositing", False)
        state.set(render, "use_sequencer", False)
        state.set(render, "use_persistent_data", True)      # scene sync once, not per probe
        state.set(render, "use_motion_blur", False)
        # Only the probe's view layer: compositing setups add layers that hold things out. The
        # others are switched off rather than the render told to do one layer: a single-layer
        # render keeps the other layers of the render before in its result when the size is
        # unchanged, and the EXR took the first of them (the shadow bake's 256-row panorama came
        # back as the 256-row distance map of the probe baked before it).
        state.set(render, "use_single_layer", False)
        for layer in scene.view_layers:
            if layer != self.view_layer and layer.use:
                state.set(layer, "use", False)
        # ...and enabled: Cycles ignores a disabled layer's material override, so the distance
        # map's render showed the surfaces' own shading (headless, the context's layer is the
        # first one, which setup_composite turns off).
        state.set(self.view_layer, "use", True)
        # the phantoms as path-traced surfaces seen by the probe's camera, not the composite's
        # holdout or filmed plate: a probe is rendered before the shadows it would show are baked
        for key in names.PHANTOM_LAYER_KEYS:
            state.set_item(self.view_layer, key, 0.0)
        state.set(render, "filepath", os.path.join(self._tmpdir, "probe.exr"))
        fmt = render.image_settings
        # Recorded first so put back last, once the user's format is back: a PNG's 8 bits set
        # while the format is still EXR became 16 (the state restores in reverse order).
        state.set(fmt, "color_depth", fmt.color_depth)
        for attr, value in compat.still_image_format():
            state.set(fmt, attr, value)
        state.set(fmt, "file_format", "OPEN_EXR")
        state.set(fmt, "color_mode", "RGBA" if self._world is not None else "RGB")
        state.set(fmt, "color_depth", "32")
        state.set(cycles, "device", "CPU")
        state.set(cycles, "samples", self.samples or scene.platelight.probe_samples)
        state.set(cycles, "use_adaptive_sampling", False)
        state.set(cycles, "blur_glossy", BAKE_FILTER_GLOSSY)
        # glass shows the sky it refracts (a transparent-glass film would lay the unrefracted sky there)
        state.set(cycles, "film_transparent_glass", False)
        state.set(cycles, "use_denoising", self.denoise)
        # a probe holds the scene's radiance: the camera's exposure applies once, to the CG layer
        state.set(cycles, "film_exposure", 1.0)
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
        prefs = addon_preferences(self.context)
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

    def render(self, origin, hidden=(), shadow_only=(), distance=False, height=None, camera_hidden=(),
               behind=None, rows=None, catchers=()):
        """Render the panorama seen from ``origin`` (world space), ``height`` px high (default the
        scene's Probe Height), with ``hidden`` objects hidden
        and ``shadow_only`` objects invisible to every ray but shadow rays (an owner that still
        shades the floor under itself), ``camera_hidden`` ones to camera rays only; returns float32 (H, 2H, 3), first row the top (the
        Environment Texture's layout). With ``distance`` the distance map is rendered too
        (``self.distance``: (map, warnings), distance_render.py); with ``behind`` (the object's
        reach from ``origin``) also the layer behind the first surface when the distance map
        shows a near occluder's edge (``self.behind``: (panorama, (map, warnings)), else None;
        behind_render.py). ``rows`` (first, last + 1 of ``height``; the first row the top):
        render only that band (a render border; the other rows come back black, the distance
        map's as sky). ``catchers``: objects rendered as Cycles shadow catchers, and what comes
        back is their Shadow Catcher pass (H, 2H, 4): per texel the light with the other objects
        over the light without them, alpha the Combined pass's (0 where a catcher is seen, 1 the
        sky)."""
        if self.camera is None:            # set up on the first render: cache hits never need it
            self.begin()
        self.camera.location = tuple(float(x) for x in origin)
        height = int(height or self.scene.platelight.probe_height)
        # begin() recorded the user's samples; a small probe gets more (probe_size.samples_for)
        self.scene.cycles.samples = self.samples or samples_for(self.scene.platelight.probe_samples, height)
        render = self.scene.render
        render.resolution_x, render.resolution_y = 2 * height, height   # begin() recorded the user's
        restore = []
        if rows is not None:
            first, last = rows
            for attr, value in (("use_border", True), ("use_crop_to_border", False), ("border_min_x", 0.0),
                                ("border_max_x", 1.0), ("border_min_y", 1.0 - last / height),
                                ("border_max_y", 1.0 - first / height)):
                restore.append((render, attr, getattr(render, attr)))
                setattr(render, attr, value)
        try:
            for ob in hidden:
                if not ob.hide_render:
                    restore.append((ob, "hide_render", False))
                    ob.hide_render = True
            for ob, flags in [(ob, SHADOW_ONLY_HIDDEN_RAYS) for ob in shadow_only] + \
                    [(ob, ("visible_camera",)) for ob in camera_hidden]:
                for flag in flags:
                    if getattr(ob, flag):
                        restore.append((ob, flag, True))
                        setattr(ob, flag, False)
            caught = self._set(self._catcher_settings(catchers)) if catchers else []
            try:
                env = self._render_panorama(origin, height, catcher=bool(catchers), rows=rows)
            finally:                         # before the distance map: it must see the catchers
                for owner, attr, value in caught:
                    setattr(owner, attr, value)
            self.distance = (render_distance(self.scene, self.view_layer, self._tmpdir,
                                                             self.camera.data.clip_end)
                             if distance else None)
            self.behind = None
            if behind and self.distance and near_silhouette(self.distance[0], behind):
                with peeled(self.scene):
                    behind_env = self._render_panorama(origin, height)
                self.behind = (behind_env, render_distance(
                    self.scene, self.view_layer, self._tmpdir, self.camera.data.clip_end,
                    peeled_distance_material()))
        finally:
            for ob, flag, value in restore:
                setattr(ob, flag, value)
        return env

    @property
    def _compositor_denoises(self) -> bool:
        """A catcher render is denoised by the compositor (its pass alone), not by Cycles."""
        return self.denoise and self.catcher_denoiser == "COMPOSITOR"

    def _catcher_settings(self, catchers):
        """(owner, attribute, value) that render ``catchers`` as shadow catchers into a multilayer
        EXR with their pass. The sky is rendered, not transparent: a catcher is transparent in the
        Combined pass, so only an opaque sky tells the two apart there."""
        fmt = self.scene.render.image_settings
        by_compositor = []
        if self._compositor_denoises:
            by_compositor = [(self.scene.cycles, "use_denoising", False),
                             (self.view_layer.cycles, "denoising_store_passes", True)]
        return by_compositor + ([(ob, "is_shadow_catcher", True) for ob in catchers] +
                [(self.view_layer.cycles, "use_pass_shadow_catcher", True),
                 (self.scene.render, "film_transparent", False)] +
                [(fmt, attr, value) for attr, value in compat.multilayer_exr_format()] +
                [(fmt, "color_mode", "RGBA"), (fmt, "color_depth", "32")])

    @staticmethod
    def _set(settings):
        """Apply (owner, attribute, value) in order; the old values, in the order to put them back
        (the same: a 5.x file format is only valid after its media type)."""
        old = [(owner, attr, getattr(owner, attr)) for owner, attr, _ in settings]
        for owner, attr, value in settings:
            setattr(owner, attr, value)
        return old

    def _render_panorama(self, origin, height, catcher=False, rows=None):
        """One render of the panorama as set up now: float32 (H, 2H, 3), the sky laid under; with
        ``catcher`` the Shadow Catcher pass and the Combined pass's alpha (H, 2H, 4), the pass
        denoised in its ``rows`` when the compositor denoises it."""
        global render_count
        try:
            bpy.ops.render.render(write_still=True)
        except RuntimeError as exc:
            reason = str(exc).strip().splitlines()[-1] if str(exc).strip() else "unknown error"
            raise PlateLightError(f"Cycles could not render the probe at {tuple(round(float(x), 3) for x in origin)}: "
                                  f"{reason}") from None
        render_count += 1
        if catcher:
            path = self.scene.render.filepath
            alpha = read_exr(path, "RGBA")[..., 3:]
            caught = read_exr(path, "RGB", layer=SHADOW_CATCHER_PASS)
            if self._compositor_denoises:
                first, last = rows or (0, height)     # as Cycles, only the render border's rows
                normal = read_exr(path, "RGB", layer=DENOISING_NORMAL_PASS)
                caught[first:last] = denoise_pass(
                    caught[first:last], normal[first:last], self.scene.cycles,
                    os.path.join(self._tmpdir, "denoised.exr"))
            return np.concatenate([caught, alpha], axis=-1)
        if self._world is None:
            return read_exr(self.scene.render.filepath, "RGB")
        rgba = read_exr(self.scene.render.filepath, "RGBA")
        return rgba[..., :3] + (1.0 - rgba[..., 3:4]) * self._world_map(height)

    def _exact_world(self):
        """The world as an array (in world axes, times its strength) when it is exactly an
        equirectangular image that reads; else None, and the sky is path-traced as before.

        That image, area-averaged, is laid under the render's alpha (film transparent) rather than
        path-traced: a camera ray finds a small sun in 16 samples of a 128x64 texel with about 30 %
        noise. The city HDRI's sun came out 9 % weak, which left a diffuse sphere 3-5 % too dark
        (docs/decisions.md)."""
        found = world_image(self.scene.world)
        if found is None:
            return None
        try:
            return found.read()
        except PlateLightError:
            return None                      # Cycles shows what it can of it; so does the render

    def _world_map(self, height):
        if height not in self._world_maps:
            self._world_maps[height] = downsample_area(self._world, height)
        return self._world_maps[height]

    def end(self):
        """Remove the probe camera, the probe renders' results (not the user's) and the
        temporary folder; call after the bake's SceneState was restored."""
        if self.camera is not None:
            cam_data = self.camera.data
            bpy.data.objects.remove(self.camera, do_unlink=True)
            bpy.data.cameras.remove(cam_data, do_unlink=True)
            self.camera = None
        for image in [im for im in bpy.data.images if im.type == "RENDER_RESULT"]:
            if self._render_results is not None and image.name not in self._render_results:
                bpy.data.images.remove(image)
        self._render_results = None
        remove_distance_material()
        remove_peeled_material()
        if self._tmpdir:
            shutil.rmtree(self._tmpdir, ignore_errors=True)
            self._tmpdir = None
