"""bpy.ops.platelight.match_grain(): measure the plate's grain on the current frame and give the
CG the same grain in the composite (addon/compositing/grain.py).

Blender 5.0's compositor has procedural texture nodes (White Noise evaluates there), but their
statistics and correlation would have to be rebuilt from uniform hashes and Blender's blur; an
image sequence made by numpy has exactly the measured statistics, is the same on every machine
that renders the shot (render farms), and is a plain input any compositor can read. So the grain
is written as ``<maps folder>/grain/grain_<frame>.exr`` (float32, one file per scene frame,
each written atomically), loaded as the image sequence "PlateLight Grain" and wired into the
"PlateLight Differential" group's Grain input with Grain Amount 1 and the measured level and
response. Re-running rewrites the files and reuses the image and node; platelight.setup_composite
wires an existing grain image again when it rebuilds the tree.
"""
import os
import re

import bpy
from bpy.props import IntProperty

from ..addon import names
from ..addon.footage import sequence_frame_path
from ..node_groups.compositor_tree import differential_node, wire_grain
from .common import NeedsScene, data_folder, find_plate_image, report_error

_GRAIN_FILE = re.compile(r"^grain_(\d+)\.exr$")


def grain_folder(scene):
    """<maps folder>/grain (common.data_folder)."""
    return data_folder(scene, "grain")


def plate_frame_pixels(image, scene):
    """The plate's pixels at the scene's current frame as float32 linear RGB (numpy)."""
    import cv2

    from ..addon.compositing.grain import linear_plate
    from ..addon.footage import read_image
    from ..addon.errors import PlateLightError

    path = bpy.path.abspath(image.filepath, library=image.library)
    file_frame = scene.frame_current + int(image.get(names.PLATE_FRAME_OFFSET_KEY, 0))
    srgb = image.colorspace_settings.name == "sRGB"
    if image.source == "MOVIE":
        cap = cv2.VideoCapture(path)
        try:
            cap.set(cv2.CAP_PROP_POS_FRAMES, max(file_frame - 1, 0))
            ok, pixels = cap.read()
        finally:
            cap.release()
        if not ok:
            raise PlateLightError(f"Cannot read frame {file_frame} of the plate movie {path}.")
        return linear_plate(pixels, srgb)
    if image.source == "SEQUENCE":
        path = sequence_frame_path(path, file_frame)
    if not os.path.isfile(path):
        raise PlateLightError(f"The plate file for frame {scene.frame_current} is missing: {path}")
    return linear_plate(read_image(path), srgb)


def _stale_files(folder, frames):
    if not os.path.isdir(folder):
        return []
    return [os.path.join(folder, f) for f in os.listdir(folder)
            if (m := _GRAIN_FILE.match(f)) and int(m.group(1)) not in frames]


class PLATELIGHT_OT_match_grain(NeedsScene, bpy.types.Operator):
    """Measure the plate's grain on this frame and add matching grain to the CG in the composite
    (writes a grain image sequence for the scene's frame range)"""

    bl_idname = "platelight.match_grain"
    bl_label = "Match Grain"
    bl_options = {"REGISTER", "UNDO"}

    seed: IntProperty(name="Seed", description="Random seed of the grain (each frame gets its own "
                      "grain from it)", default=0, min=0)

    def execute(self, context):
        from ..addon.compositing.grain import estimate_grain, make_grain
        from ..addon.errors import PlateLightError
        from ..addon.exr_io import write_exr

        scene = context.scene
        # --- check and compute everything before changing the scene
        diff = differential_node(scene)
        if diff is None:
            self.report({"ERROR"}, "The scene has no PlateLight composite; run Set Up Composite "
                        "(platelight.setup_composite) first.")
            return {"CANCELLED"}
        if "Grain" not in diff.inputs:
            self.report({"ERROR"}, "The PlateLight composite was made before grain matching; run "
                        "Set Up Composite (platelight.setup_composite) again first.")
            return {"CANCELLED"}
        plate = find_plate_image(scene)
        if plate is None:
            self.report({"ERROR"}, "No plate found; run Set Up Plate (platelight.setup_plate) first.")
            return {"CANCELLED"}
        render = scene.render
        width = render.resolution_x * render.resolution_percentage // 100
        height = render.resolution_y * render.resolution_percentage // 100
        frames = range(scene.frame_start, scene.frame_end + 1)
        folder = grain_folder(scene)
        try:
            stats = estimate_grain(plate_frame_pixels(plate, scene))
            window = context.window_manager
            window.progress_begin(0, len(frames))
            try:
                for i, frame in enumerate(frames):
                    grain = make_grain(stats, width, height, frame=frame, seed=self.seed)
                    write_exr(os.path.join(folder, f"grain_{frame:04d}.exr"), grain)
                    window.progress_update(i + 1)
            finally:
                window.progress_end()
            for path in _stale_files(folder, set(frames)):
                os.unlink(path)
        except PlateLightError as err:
            report_error(self, err)
            return {"CANCELLED"}

        # --- the image sequence, updated in place, and its wiring
        first = os.path.join(folder, f"grain_{frames[0]:04d}.exr")
        stored = bpy.path.relpath(first) if bpy.data.filepath else first
        image = bpy.data.images.get(names.GRAIN_IMAGE)
        if image is None:
            image = bpy.data.images.load(first, check_existing=False)
            image.name = names.GRAIN_IMAGE
        image.filepath = stored
        image.source = "SEQUENCE" if len(frames) > 1 else "FILE"
        image.colorspace_settings.name = "Linear Rec.709"
        image.reload()
        image[names.GRAIN_SETTINGS_KEY] = {"amount": 1.0, "level": [float(v) for v in stats.level],
                               "response": [float(v) for v in stats.response]}
        wire_grain(scene)
        sigma = ", ".join(f"{s:.4g}" for s in stats.sigma)
        level = ", ".join(f"{v:.3g}" for v in stats.level)
        self.report({"INFO"}, f"Grain matched: sigma ({sigma}) at level ({level}), size "
                    f"{stats.size:.2f} px; {len(frames)} frame(s) written to {folder}.")
        return {"FINISHED"}


classes = (PLATELIGHT_OT_match_grain,)
