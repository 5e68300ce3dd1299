"""Small helpers shared by PlateLight's operators (bpy)."""
import os
import tempfile

import bpy

from ..addon import names


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


def addon_preferences(context):
    """PlateLight's add-on preferences (ui/preferences.py), or None when it is not enabled as an
    add-on (a script that registered the classes itself)."""
    addon = context.preferences.addons.get(__package__.rsplit(".", 1)[0])
    return addon.preferences if addon is not None else None


def data_folder(scene, name):
    """<maps folder>/<name> (scene.platelight.maps_dir, next to the .blend by default): where
    PlateLight writes the files it makes for a scene; a temporary folder when the maps folder is
    relative and the file is unsaved."""
    maps_dir = scene.platelight.maps_dir
    if maps_dir and (bpy.data.filepath or not maps_dir.startswith("//")):
        folder = bpy.path.abspath(maps_dir)
    else:
        folder = os.path.join(tempfile.gettempdir(), "platelight")
    return os.path.join(folder, name)


class NeedsScene:
    """Operator mixin: available whenever there is a scene (says so when there is none)."""

    @classmethod
    def poll(cls, context):
        if context.scene is None:
            cls.poll_message_set("Needs a scene.")
            return False
        return True
