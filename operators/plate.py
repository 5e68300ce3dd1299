"""bpy.ops.platelight.setup_plate(filepath=...): load a movie or an image sequence as the plate and
match the scene to it (size, frame range, frame rate, camera background, colour management).

Re-running it updates the one plate image ("PlateLight Plate") instead of adding another.
Colour spaces are explicit: taken from the file where it says (operators/plate_colour.py) or set
by the user (colorspace=...); with the Standard view transform the plate comes out as it went in.
"""
import os

import bpy
from bpy.props import BoolProperty, FloatProperty, StringProperty

from ..addon import names
from ..addon.errors import PlateLightError
from ..addon.footage import MOVIE_EXTENSIONS, frame_rate_pair, scan_sequence
from .common import NeedsScene, report_error, set_plate_colour_management
from .plate_colour import apply_plate_colour_space, check_colour_space, search_colour_spaces


def _camera_is_animated(camera):
    data = camera.animation_data
    return bool((data and data.action) or camera.constraints or camera.parent)


class PLATELIGHT_OT_setup_plate(NeedsScene, bpy.types.Operator):
    """Load a movie clip or an image sequence as the plate and match the scene to it"""

    bl_idname = "platelight.setup_plate"
    bl_label = "Set Up Plate"
    bl_options = {"REGISTER", "UNDO"}

    filepath: StringProperty(name="Plate", description="A movie file, or one image of a numbered sequence",
                             subtype="FILE_PATH")
    match_scene: BoolProperty(
        name="Adopt Plate Settings",
        description="Set the scene's resolution, frame range and frame rate to the plate's; off: "
        "refuse a plate that disagrees with the scene",
        default=True,
    )
    fps: FloatProperty(name="Frame Rate", description="Frame rate of an image sequence (0: keep the "
                       "scene's)", default=0.0, min=0.0, max=1000.0)
    colorspace: StringProperty(name="Colour Space", description="How the plate's pixels are encoded "
                               "(empty: as its file says; e.g. sRGB, Linear Rec.709, ACEScg, a camera log)",
                               default="", search=search_colour_spaces)

    def invoke(self, context, event):
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}

    def _load(self, path):
        """(image, (width, height), first, count, fps or None, colour-space reason) without touching
        the scene."""
        ext = os.path.splitext(path)[1].lower()
        if ext in MOVIE_EXTENSIONS:
            clip = bpy.data.movieclips.load(path)
            try:
                count, fps, size = clip.frame_duration, clip.fps, tuple(clip.size)
            finally:
                bpy.data.movieclips.remove(clip)
            if count < 1 or size[0] == 0:
                raise PlateLightError(f"Blender cannot read frames from the movie {path}.")
            source, first = "MOVIE", 1
        else:
            first, _, count = scan_sequence(path)
            source, fps = ("SEQUENCE" if count > 1 else "FILE"), None
        try:
            image = bpy.data.images.load(path, check_existing=False)
        except RuntimeError:
            raise PlateLightError(f"Blender cannot read {path} as an image or movie.") from None
        # read the size as a still first: a sequence reports 0×0 until a frame is shown
        size = tuple(image.size)
        image.source = source
        if size[0] == 0 or size[1] == 0:
            bpy.data.images.remove(image)
            raise PlateLightError(f"Blender cannot read {path} as an image or movie.")
        colour_reason = apply_plate_colour_space(image, path, self.colorspace)
        return image, size, first, count, fps, colour_reason

    def execute(self, context):
        scene = context.scene
        path = bpy.path.abspath(self.filepath)
        if not self.filepath or not os.path.isfile(path):
            self.report({"ERROR"}, f"Plate file not found: {self.filepath or '(no file given)'}.")
            return {"CANCELLED"}
        bad_colour_space = check_colour_space(self.colorspace)
        if bad_colour_space:
            self.report({"ERROR"}, bad_colour_space)
            return {"CANCELLED"}
        try:
            image, (width, height), first, count, clip_fps, colour_reason = self._load(path)
        except PlateLightError as err:
            report_error(self, err)
            return {"CANCELLED"}
        fps = clip_fps or self.fps or None
        fps_pair = frame_rate_pair(fps) if fps else None
        if fps:
            fps = fps_pair[0] / fps_pair[1]
        render = scene.render
        scene_fps = render.fps / render.fps_base
        mismatch = []
        if (render.resolution_x, render.resolution_y) != (width, height) or render.resolution_percentage != 100:
            mismatch.append(f"the plate is {width}×{height} but the scene renders "
                            f"{render.resolution_x * render.resolution_percentage // 100}×"
                            f"{render.resolution_y * render.resolution_percentage // 100}")
        if fps and abs(fps - scene_fps) > 1e-3:
            mismatch.append(f"the plate runs at {fps:g} fps but the scene at {scene_fps:g} fps")
        if mismatch and not self.match_scene:
            bpy.data.images.remove(image)
            self.report({"ERROR"}, "; ".join(mismatch).capitalize() + "; run again with "
                        "'Adopt Plate Settings' (match_scene=True) to adopt the plate's.")
            return {"CANCELLED"}

        # --- one plate image, updated in place (compositor nodes and backgrounds keep it)
        old = bpy.data.images.get(names.PLATE_IMAGE)
        if old is not None:
            old.user_remap(image)
            bpy.data.images.remove(old)
        image.name = names.PLATE_IMAGE
        image[names.PLATE_FRAME_OFFSET_KEY] = first - 1
        render.resolution_x, render.resolution_y = width, height
        render.resolution_percentage = 100
        render.pixel_aspect_x = render.pixel_aspect_y = 1.0
        scene.frame_start, scene.frame_end = 1, count
        if fps:
            render.fps, render.fps_base = fps_pair
        set_plate_colour_management(scene)

        camera = scene.camera
        if camera is not None and camera.type == "CAMERA":
            camera.data.show_background_images = True
            backgrounds = camera.data.background_images
            background = next((b for b in backgrounds if b.image == image), None) or backgrounds.new()
            background.source = "IMAGE"
            background.image = image
            background.image_user.frame_start = 1
            background.image_user.frame_duration = count
            background.image_user.frame_offset = first - 1
        kind = f"{image.colorspace_settings.name}: {colour_reason}"
        self.report({"INFO"}, f"Plate: {count} frame(s) of {width}×{height} ({kind})"
                    + (f"; adopted: {'; '.join(mismatch)}" if mismatch else "") + ".")
        if camera is None:
            self.report({"WARNING"}, "The scene has no camera yet: track the plate or add one.")
        elif count > 1 and not _camera_is_animated(camera):
            self.report({"WARNING"}, f"The camera '{camera.name}' is not animated but the plate has "
                        f"{count} frames: track it or key it, unless the shot was locked off.")
        return {"FINISHED"}


classes = (PLATELIGHT_OT_setup_plate,)
