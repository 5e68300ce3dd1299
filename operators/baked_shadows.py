"""bpy.ops.platelight.bake_shadows(): the shot's shadow panorama for setup_composite's BAKED method
(addon/compositing/baked_shadows.py says why a matte phantom's shadow can be baked once).

Two renders from one point above the CG (the probe renderer's equirectangular camera, denoised,
one seed): with the CG there but unseen by camera rays (it still shadows and lights the
phantoms), and without it. Their ratio is what Cycles' catcher pass holds for each point the
panorama sees; a distance panorama tells those points from hidden ones. The scene is restored
exactly, as after a probe bake."""
from __future__ import annotations

import os
import time

import bpy
import numpy as np
from bpy.props import IntProperty

from ..addon import names
from ..addon.bake.layout import DEFAULT_MAPS_DIR
from ..addon.compositing import baked_shadows as engine
from ..addon.errors import PlateLightError
from ..addon.ibl import distance as distance_maps
from ..node_groups.baked_shadow import baked_shadow_material
from .bake.inputs import point_inside, world_bounds
from .bake.probe_render import ProbeRenderer
from .bake.scene_state import SceneState
from .composite import classify_objects

STATIC_SAMPLE_FRAMES = 48


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


def check_still(scene, objects):
    """Raise unless every object keeps its place over the scene's range (sampled frames)."""
    start, end = scene.frame_start, scene.frame_end
    frames = np.unique(np.linspace(start, end, min(end - start + 1, STATIC_SAMPLE_FRAMES)).round().astype(int))
    frame0 = scene.frame_current
    here = {ob.name: np.array(ob.matrix_world) for ob in objects}
    try:
        for frame in frames:
            scene.frame_set(int(frame))
            for ob in objects:
                if not np.allclose(np.array(ob.matrix_world), here[ob.name], atol=1e-6):
                    raise PlateLightError(
                        f"'{ob.name}' moves during the shot (frame {frame}); baked shadows need CG "
                        "objects and phantoms that stand still: use the Shadow Catcher method.")
    finally:
        scene.frame_set(frame0)


def panorama_centre(cg):
    """Above the CG's footprint centre, one bounding radius over its top."""
    boxes = np.array([[ob.matrix_world @ _vec(c) for c in ob.bound_box] for ob in cg], dtype=np.float64)
    low, high = boxes.reshape(-1, 3).min(axis=0), boxes.reshape(-1, 3).max(axis=0)
    radius = max(float(np.linalg.norm(high - low)) / 2, 1e-3)
    return np.array([(low[0] + high[0]) / 2, (low[1] + high[1]) / 2, high[2] + radius])


def _vec(c):
    from mathutils import Vector

    return Vector(c)


def bake_shadows(context, height: int = 512, samples: int = 16) -> dict:
    """Bake the shot's shadow panorama and (re)build the override material; returns a summary."""
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
    check_still(scene, cg + phantoms)
    centre = panorama_centre(cg)
    depsgraph = context.evaluated_depsgraph_get()
    for ob in phantoms:
        if point_inside(ob, depsgraph, centre):
            raise PlateLightError(f"The point above the CG lies inside '{ob.name}', so the shadows "
                                  "cannot be seen from there; use the Shadow Catcher method.")
    t0 = time.perf_counter()
    state = SceneState()
    renderer = ProbeRenderer(context, state, None, denoise=True, samples=samples)
    try:
        # with: the CG shadows and lights the phantoms but is not seen; without: gone
        lit_with = renderer.render(centre, camera_hidden=cg, height=height, distance=True)
        distance, warnings = renderer.distance
        lit_without = renderer.render(centre, hidden=cg, height=height)
    finally:
        errors = state.restore()
        renderer.end()
    ratio = engine.shadow_ratio(lit_with, lit_without)
    ratio_path = engine.write_baked(folder, engine.ratio_to_texture(ratio), centre, height, samples)
    distance_path = distance_maps.write_distance(folder, distance)
    baked_shadow_material(ratio_path, distance_path, centre)
    return {"seconds": time.perf_counter() - t0, "folder": folder, "centre": centre,
            "warnings": list(warnings) + list(errors or [])}


class PLATELIGHT_OT_bake_shadows(bpy.types.Operator):
    """Render the shot's CG shadows on the phantoms once, from above, for the Baked Shadows
    composite (CG and phantoms must stand still; the camera may move)"""

    bl_idname = "platelight.bake_shadows"
    bl_label = "Bake Shadows"
    bl_options = {"REGISTER", "UNDO"}

    height: IntProperty(name="Resolution", description="Height of the shadow panorama in pixels "
                        "(width twice)", default=512, min=16, max=8192)
    samples: IntProperty(name="Samples", description="Cycles samples of each of the two renders "
                         "(denoised)", default=16, min=1, max=65536)

    @classmethod
    def poll(cls, context):
        if context.scene is None or context.scene.world is None:
            cls.poll_message_set("The scene needs a world (its environment lights the phantoms)")
            return False
        return True

    def execute(self, context):
        try:
            summary = bake_shadows(context, self.height, self.samples)
        except PlateLightError as exc:
            self.report({"ERROR"}, str(exc))
            return {"CANCELLED"}
        for warning in summary["warnings"]:
            self.report({"WARNING"}, str(warning))
        self.report({"INFO"}, f"Shadows baked in {summary['seconds']:.1f} s into {summary['folder']}.")
        return {"FINISHED"}


classes = (PLATELIGHT_OT_bake_shadows,)
