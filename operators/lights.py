"""bpy.ops.platelight.lights_from_probe(): sun lights that stand in for the world probe's light,
so phantoms get sharp, fast shadows (median cut + sun detection, addon/ibl/lights.py).

The lights go into the collection "PlateLight Lights", which is rebuilt on every run; lights the
user placed by hand elsewhere are left alone and keep working (the paper's manual lights).
With ``replace_world_lighting`` the world stops lighting diffuse surfaces (the lights carry its
energy instead, no double counting) but is still seen in reflections.
"""
import os

import bpy
import numpy as np
from bpy.props import BoolProperty, IntProperty
from mathutils import Vector

LIGHTS_COLLECTION = "PlateLight Lights"


def world_probe_path(scene):
    """The probe file: scene.platelight.world_probe, else the world's Environment Texture image."""
    if scene.platelight.world_probe:
        return bpy.path.abspath(scene.platelight.world_probe)
    world = scene.world
    if world is not None and world.node_tree is not None:
        for node in world.node_tree.nodes:
            if node.type == "TEX_ENVIRONMENT" and node.image is not None:
                return bpy.path.abspath(node.image.filepath, library=node.image.library)
    return ""


def create_sun_lights(scene, lights, name_prefix="PlateLight"):
    """Replace the contents of the "PlateLight Lights" collection by sun lamps for ``lights``."""
    coll = bpy.data.collections.get(LIGHTS_COLLECTION) or bpy.data.collections.new(LIGHTS_COLLECTION)
    if coll.name not in scene.collection.children:
        scene.collection.children.link(coll)
    for ob in list(coll.objects):
        data = ob.data
        bpy.data.objects.remove(ob)
        if data is not None and data.users == 0:
            bpy.data.lights.remove(data)
    made = []
    for index, light in enumerate(lights):
        name = f"{name_prefix} Sun" if light.is_sun else f"{name_prefix} Sky {index:02d}"
        data = bpy.data.lights.new(name, "SUN")
        data.energy = light.strength
        data.color = tuple(float(c) for c in light.color)
        data.angle = float(light.angle)
        ob = bpy.data.objects.new(name, data)
        # a sun shines along its local -Z: point local +Z at the light
        ob.rotation_euler = Vector(light.direction).to_track_quat("Z", "Y").to_euler()
        coll.objects.link(ob)
        made.append(ob)
    return made


class PLATELIGHT_OT_lights_from_probe(bpy.types.Operator):
    """Add sun lights that carry the world probe's light (its sun, sharp, plus median-cut sky lights)"""

    bl_idname = "platelight.lights_from_probe"
    bl_label = "Lights from Probe"
    bl_options = {"REGISTER", "UNDO"}

    count: IntProperty(name="Sky Lights", description="Number of median-cut lights for the sky",
                       default=16, min=1, max=1024)
    detect_sun: BoolProperty(name="Find Sun", description="Give the sun its own light with a sharp "
                             "shadow", default=True)
    replace_world_lighting: BoolProperty(
        name="Replace World Lighting",
        description="Stop the world lighting diffuse surfaces (the lights carry its energy); it stays "
        "visible in reflections",
        default=True,
    )

    @classmethod
    def poll(cls, context):
        if context.scene is None or not world_probe_path(context.scene):
            cls.poll_message_set("Needs a world probe: set Scene > PlateLight > World Probe or an "
                                 "Environment Texture in the world")
            return False
        return True

    def execute(self, context):
        from ..addon.errors import PlateLightError
        from ..addon.exr_io import read_exr
        from ..addon.ibl.lights import probe_lights

        scene = context.scene
        path = world_probe_path(scene)
        if not path or not os.path.isfile(path):
            self.report({"ERROR"}, f"World probe not found: {path or '(none set)'}.")
            return {"CANCELLED"}
        try:
            env = read_exr(path)
            lights = probe_lights(env, self.count, self.detect_sun)
        except PlateLightError as err:
            self.report({"ERROR"}, str(err))
            return {"CANCELLED"}
        made = create_sun_lights(scene, lights)
        if self.replace_world_lighting:
            # lights light diffuse surfaces, the world is what glossy surfaces reflect: each
            # light path sees the probe's energy once
            for ob in made:
                ob.visible_glossy = False
                ob.visible_transmission = False
        if self.replace_world_lighting and scene.world is not None:
            scene.world.cycles_visibility.diffuse = False
            scene.world.cycles_visibility.scatter = False
        sun = next((light for light in lights if light.is_sun), None)
        extra = (f"; sun at elevation {np.degrees(np.arcsin(sun.direction[2])):.1f}°" if sun
                 else "; no sun found")
        self.report({"INFO"}, f"{len(made)} light(s) from {os.path.basename(path)}{extra}.")
        return {"FINISHED"}


classes = (PLATELIGHT_OT_lights_from_probe,)
