"""Small helpers shared by PlateLight's operators (bpy): the plate and its colour management,
object kinds, where data for the scene goes, the add-on preferences, error reports in Blender's
words, the NeedsScene poll. (What the world shows: world_environment.py.)"""
import os

import bpy

from ..addon import names

# Object types that render a surface or volume: what can be CG, a phantom, or own a probe.
GEOMETRY_TYPES = frozenset({"MESH", "CURVE", "SURFACE", "META", "FONT", "CURVES", "POINTCLOUD", "VOLUME"})


def find_plate_image(scene):
    """The plate: the image set up by platelight.setup_plate, else the camera's background image."""
    image = bpy.data.images.get(names.PLATE_IMAGE)
    if image is not None:
        return image
    camera = scene.camera
    if camera is not None and camera.type == "CAMERA":
        for background in camera.data.background_images:
            if background.source == "IMAGE" and background.image is not None:
                return background.image
    return None


def set_plate_colour_management(scene):
    """Plates pass through unchanged: no view transform, look, exposure or gamma."""
    view = scene.view_settings
    view.view_transform = "Standard"
    view.look = "None"
    view.exposure = 0.0
    view.gamma = 1.0
    view.use_curve_mapping = False
    scene.render.dither_intensity = 0.0  # dither noise would change 8-bit plates
    scene.sequencer_colorspace_settings.name = "Linear Rec.709"


def data_folder(scene, name):
    """Where PlateLight keeps data it makes for the scene (grain frames, a sun-less probe): the
    folder ``name`` in the Maps Folder (next to the .blend by default). An unsaved file with a
    relative Maps Folder keeps it beside Blender's own temporary files (bpy.app.tempdir, one per
    Blender session, removed when Blender quits), never in a folder shared with other runs."""
    maps_dir = scene.platelight.maps_dir
    if maps_dir and (bpy.data.filepath or not maps_dir.startswith("//")):
        return os.path.join(bpy.path.abspath(maps_dir), name)
    return os.path.join(bpy.app.tempdir, "platelight", name)


def addon_preferences(context):
    """PlateLight's add-on preferences (ui/preferences.py), or None when it is not enabled as an
    add-on (a script that registered the classes itself)."""
    addon = context.preferences.addons.get(__package__.rsplit(".", 1)[0])
    return addon.preferences if addon is not None else None


# How operators name what an engine error asks for (PlateLightError.worded); an operator adds
# its own fields with report_error(..., fields).
FIELDS = {
    "maps_folder": "in Scene > PlateLight > Maps Folder",
}


def report_error(operator, err, fields=None):
    """Report a PlateLightError in Blender's words: fields and buttons, not command-line flags."""
    operator.report({"ERROR"}, err.worded({**FIELDS, **(fields or {})}))


class NeedsScene:
    """Operator mixin: available whenever there is a scene (says so when there is none)."""

    @classmethod
    def poll(cls, context):
        if context.scene is None:
            cls.poll_message_set("Needs a scene.")
            return False
        return True


def classify_objects(scene):
    """(cg, phantoms): renderable objects of the scene, split by object.platelight.phantom."""
    cg, phantoms = [], []
    for ob in scene.objects:
        if ob.type not in GEOMETRY_TYPES or ob.hide_render:
            continue
        (phantoms if ob.platelight.phantom else cg).append(ob)
    return cg, phantoms
