"""Small helpers shared by PlateLight's operators (bpy)."""
import os
import tempfile

import bpy

PLATE_IMAGE_NAME = "PlateLight Plate"
# On the plate image: file frame number = scene frame + this (a sequence may start at 1001).
PLATE_FRAME_OFFSET_KEY = "platelight_frame_offset"


def find_plate_image(scene):
    """The plate: the image set up by platelight.setup_plate, else the camera's background image."""
    image = bpy.data.images.get(PLATE_IMAGE_NAME)
    if image is not None:
        return image
    camera = scene.camera
    if camera is not None and camera.type == "CAMERA":
        for background in camera.data.background_images:
            if background.source == "IMAGE" and background.image is not None:
                return background.image
    return None


def output_folder(scene, name):
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
