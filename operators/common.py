"""Small helpers shared by PlateLight's operators (bpy)."""
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


class NeedsScene:
    """Operator mixin: available whenever there is a scene (says so when there is none)."""

    @classmethod
    def poll(cls, context):
        if context.scene is None:
            cls.poll_message_set("Needs a scene.")
            return False
        return True
