"""bpy.ops.platelight.lights_from_probe(): sun lights that stand in for the world probe's light,
so phantoms get sharp, fast shadows (median cut + sun detection, addon/ibl/lights.py).

Two modes: SUN_SKY moves the probe's sun into a sun lamp (sharp shadow, no sampling noise from a
tiny bright texel blob) and gives the world the sun-less probe; LIGHTS replaces the world's
diffuse lighting by the sun and N median-cut lamps (the paper's shadow-casting lights).

The lights go into the collection "PlateLight Lights", which is rebuilt on every run; lights the
user placed by hand elsewhere are left alone and keep working (the paper's manual lights).
With ``replace_world_lighting`` the world stops lighting diffuse surfaces (the lights carry its
energy instead, no double counting) but is still seen in reflections.
"""
import dataclasses
import os

import bpy
import numpy as np
from bpy.props import BoolProperty, EnumProperty, IntProperty
from mathutils import Vector

from ..addon import names
from .common import data_folder, report_error
from .world_environment import SUNLESS_OF_KEY, probe_image, world_image


def create_sun_lights(scene, lights, name_prefix=names.LIGHT_PREFIX):
    """Replace the contents of the "PlateLight Lights" collection by sun lamps for ``lights``."""
    coll = bpy.data.collections.get(names.LIGHTS_COLLECTION) or bpy.data.collections.new(names.LIGHTS_COLLECTION)
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


def _sunless_probe_path(scene, probe_path):
    stem = os.path.splitext(os.path.basename(probe_path))[0]
    return os.path.join(data_folder(scene, "lights"), f"{stem}_nosun.exr")


class PLATELIGHT_OT_lights_from_probe(bpy.types.Operator):
    """Add sun lights that carry the world probe's light (its sun, sharp, plus median-cut sky lights)"""

    bl_idname = "platelight.lights_from_probe"
    bl_label = "Lights from Probe"
    bl_options = {"REGISTER", "UNDO"}

    mode: EnumProperty(
        name="Mode",
        items=(
            ("SUN_SKY", "Sun Lamp + Sky", "Move the sun into a sharp sun lamp; the world keeps the "
             "rest of the probe (needs an Environment Texture in the world)"),
            ("LIGHTS", "Lamps Only", "The sun and median-cut lamps replace the world's diffuse lighting"),
        ),
        default="LIGHTS",
    )
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
        if context.scene is None or probe_image(context.scene) is None:
            cls.poll_message_set("Needs a world probe: set Scene > PlateLight > World Probe, or make the "
                                 "world an EXR Environment Texture (a Mapping node may turn it)")
            return False
        return True

    def execute(self, context):
        from ..addon.errors import PlateLightError
        from ..addon.hdr_io import read_probe
        from ..addon.ibl.lights import probe_lights

        scene = context.scene
        image = probe_image(scene)
        if image is None or not os.path.isfile(image.path):
            self.report({"ERROR"}, f"World probe not found: {image.path if image else '(none set)'}.")
            return {"CANCELLED"}
        try:
            env = read_probe(image.path)
            if self.mode == "SUN_SKY":
                return self._sun_and_sky(scene, image, env)
            lights = [_in_world(image, light) for light in probe_lights(env, self.count, self.detect_sun)]
        except PlateLightError as err:
            report_error(self, err)
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
        self.report({"INFO"}, f"{len(made)} light(s) from {os.path.basename(image.path)}{extra}.")
        return {"FINISHED"}

    def _sun_and_sky(self, scene, probe, env):
        from ..addon.exr_io import write_exr
        from ..addon.ibl.lights import split_sun

        shown = world_image(scene.world)
        if shown is None:
            self.report({"ERROR"}, "Sun Lamp + Sky needs the world to show an EXR Environment Texture "
                        "(a Mapping node may turn it); use Lamps Only instead.")
            return {"CANCELLED"}
        # The sun-less probe goes into the world's Environment Texture: its strength and
        # rotation apply to the probe, so the sun lamp gets them too.
        probe = dataclasses.replace(shown, path=probe.path)
        sun, sky = split_sun(env)
        if sun is None:
            self.report({"WARNING"}, f"No sun found in {os.path.basename(probe.path)}; nothing changed.")
            return {"CANCELLED"}
        sun = _in_world(probe, sun)
        sky_path = _sunless_probe_path(scene, probe.path)
        write_exr(sky_path, sky.astype(np.float32))
        image = bpy.data.images.load(sky_path, check_existing=True)
        image.reload()
        image.colorspace_settings.name = "Linear Rec.709"
        image[SUNLESS_OF_KEY] = probe.path
        shown.node.image = image
        if not scene.platelight.world_probe:
            scene.platelight.world_probe = probe.path  # re-runs start from the probe with its sun
        create_sun_lights(scene, [sun])
        scene.world.cycles_visibility.diffuse = True
        scene.world.cycles_visibility.scatter = True
        self.report({"INFO"}, f"Sun moved into a lamp (elevation "
                    f"{np.degrees(np.arcsin(sun.direction[2])):.1f}°, {np.degrees(sun.angle):.2f}° wide); "
                    f"the world now shows {os.path.basename(sky_path)}.")
        return {"FINISHED"}


def _in_world(image, light):
    """A light found in ``image`` as the world shows it: turned by its Mapping, times its strength."""
    return dataclasses.replace(light, direction=image.to_world(light.direction),
                               rgb=light.rgb * image.strength)


classes = (PLATELIGHT_OT_lights_from_probe,)
