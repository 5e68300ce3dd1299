"""Lens distortion in the scene (bpy.ops.platelight.setup_lens, and track_markers with a
distorted calibration): the plate keeps its own lens, the CG is rendered through a pinhole that
sees the whole distorted frame, and the compositor redistorts the rendered layers onto the plate.

- the plate's Movie Clip ("PlateLight Plate") carries the calibration in its camera (Blender's
  'BROWN' model), so the Clip Editor and Movie Distortion nodes show the same lens;
- the scene camera gets the overscan pinhole (addon/compositing/lens.py ``render_frame``);
- "PlateLight Lens ST-Map" (an EXR) tells a Map UV node, for every plate pixel, where the
  render shows that point; ``wire_redistortion`` puts one Map UV after each Render Layers output
  of the composite tree (node_groups/redistortion.py);
- "PlateLight Plate Undistorted" (the plate seen by the render camera) is the camera's
  background image, so phantoms are placed on the plate as the render will see them.
"""
import json
import os

import bpy
from bpy.props import StringProperty

from ..addon import names
from ..addon.compositing import lens
from ..addon.errors import PlateLightError
from .common import NeedsScene, data_folder, find_plate_image, report_error



def set_pinhole(scene, cam, fx, fy, cx, cy, width, height):
    """Lens, shift and pixel aspect of camera data ``cam`` for an OpenCV pinhole."""
    fields = lens.blender_camera_fields(fx, fy, cx, cy, width, height, cam.sensor_width)
    cam.lens, cam.shift_x, cam.shift_y = fields["lens"], fields["shift_x"], fields["shift_y"]
    scene.render.pixel_aspect_x = fields["pixel_aspect_x"]
    scene.render.pixel_aspect_y = fields["pixel_aspect_y"]


def scene_lens(scene):
    """(fx, fy, cx, cy, dist, width, height) stored by apply_lens, or None."""
    text = scene.get(names.LENS_KEY)
    if not text:
        return None
    d = json.loads(text)
    return d["fx"], d["fy"], d["cx"], d["cy"], tuple(d["dist"]), d["width"], d["height"]


def _frame_files(image, scene):
    """(scene frame, file) of the plate's frames on disk."""
    from ..addon.footage import sequence_frame_path

    path = bpy.path.abspath(image.filepath)
    if image.source != "SEQUENCE":
        return [(scene.frame_start, path)]
    offset = int(image.get(names.PLATE_FRAME_OFFSET_KEY, 0))
    return [(f, sequence_frame_path(path, f + offset)) for f in range(scene.frame_start, scene.frame_end + 1)]


def _read_any(path):
    import cv2

    from ..addon.exr_io import read_exr

    if path.lower().endswith(".exr"):
        return read_exr(path, "RGBA")
    image = cv2.imread(path, cv2.IMREAD_UNCHANGED)
    if image is None:
        raise PlateLightError(f"OpenCV cannot read the plate frame {path} to undistort it.")
    return image


def _write_like(path, image):
    import cv2

    from ..addon.exr_io import write_exr

    if path.lower().endswith(".exr"):
        write_exr(path, image)
    elif not cv2.imwrite(path, image):
        raise PlateLightError(f"Cannot write the undistorted plate frame {path}.")


def _undistorted_plate(scene, plate, calib, frame, folder, progress=None):
    """Write the plate's frames as the render camera sees them; return the first file or None
    (movies and files OpenCV cannot read keep the distorted plate in the viewport)."""
    fx, fy, cx, cy, dist, width, height = calib
    source = bpy.path.abspath(plate.filepath)
    ext = os.path.splitext(source)[1].lower()
    if plate.source == "MOVIE" or ext not in {".png", ".tif", ".tiff", ".jpg", ".jpeg", ".exr"}:
        return None
    out_ext = ".exr" if ext == ".exr" else (".png" if ext in {".jpg", ".jpeg"} else ext)
    written = []
    for done, (number, path) in enumerate(_frame_files(plate, scene)):
        if progress:
            progress(done)
        pixels = lens.undistort_to_render(_read_any(path), fx, fy, cx, cy, dist, frame)
        target = os.path.join(folder, f"undistorted_{number:04d}{out_ext}")
        _write_like(target, pixels)
        written.append(target)
    return written[0]


def _update_clip(plate, calib):
    """The plate's Movie Clip, with the calibration in its tracking camera."""
    fx, fy, cx, cy, dist, width, height = calib
    path = bpy.path.abspath(plate.filepath)
    clip = bpy.data.movieclips.get(names.PLATE_CLIP)
    if clip is None or bpy.path.abspath(clip.filepath) != path:
        if clip is not None:
            bpy.data.movieclips.remove(clip)
        clip = bpy.data.movieclips.load(path)
        clip.name = names.PLATE_CLIP
    camera = clip.tracking.camera
    for name, value in lens.clip_camera_settings(fx, fy, cx, cy, dist, width, height).items():
        setattr(camera, name, value)
    return clip


def apply_lens(scene, camera, fx, fy, cx, cy, dist, width, height, progress=None):
    """Put a calibrated lens into the scene (see the module docstring); raises PlateLightError
    before changing anything when the calibration cannot be used. Returns the RenderFrame.
    ``progress(i)`` is called before the i-th plate frame is undistorted."""
    import numpy as np

    from ..addon.exr_io import write_exr

    dist = tuple(float(v) for v in np.asarray(dist, np.float64).reshape(-1))
    frame = lens.render_frame(fx, fy, cx, cy, dist, width, height)    # checks the model first
    calib = (fx, fy, cx, cy, dist, width, height)
    plate = find_plate_image(scene)
    folder = data_folder(scene, "lens")
    os.makedirs(folder, exist_ok=True)
    stmap_path = os.path.join(folder, "lens_stmap.exr")
    write_exr(stmap_path, lens.st_map(fx, fy, cx, cy, dist, width, height, frame))
    undistorted = _undistorted_plate(scene, plate, calib, frame, folder, progress) if plate is not None else None

    scene[names.LENS_KEY] = json.dumps({"fx": fx, "fy": fy, "cx": cx, "cy": cy, "dist": list(dist),
                                  "width": width, "height": height})
    stmap = bpy.data.images.get(names.LENS_STMAP_IMAGE)
    if stmap is not None:
        bpy.data.images.remove(stmap)
    stmap = bpy.data.images.load(stmap_path, check_existing=False)
    stmap.name = names.LENS_STMAP_IMAGE
    stmap.colorspace_settings.name = "Non-Color"
    set_pinhole(scene, camera.data, *frame.intrinsics(fx, fy, cx, cy), width, height)
    if plate is not None:
        scene.active_clip = _update_clip(plate, calib)
    if undistorted:
        _show_undistorted(scene, camera, plate, undistorted)
    return frame


def _show_undistorted(scene, camera, plate, first_file):
    old = bpy.data.images.get(names.PLATE_UNDISTORTED_IMAGE)
    image = bpy.data.images.load(first_file, check_existing=False)
    if old is not None:
        old.user_remap(image)
        bpy.data.images.remove(old)
    image.name = names.PLATE_UNDISTORTED_IMAGE
    image.colorspace_settings.name = plate.colorspace_settings.name
    count = scene.frame_end - scene.frame_start + 1
    image.source = "SEQUENCE" if plate.source == "SEQUENCE" else "FILE"
    backgrounds = camera.data.background_images
    background = next((b for b in backgrounds if b.image in (plate, image)), None) or backgrounds.new()
    camera.data.show_background_images = True
    background.source = "IMAGE"
    background.image = image
    background.image_user.frame_start = scene.frame_start
    background.image_user.frame_duration = count
    background.image_user.frame_offset = scene.frame_start - 1


class PLATELIGHT_OT_setup_lens(NeedsScene, bpy.types.Operator):
    """Carry a lens calibration (OpenCV k1, k2, p1, p2, k3) into the scene: the plate's movie-clip
    camera, an overscan render camera, the undistorted plate behind the camera, and the
    compositor's redistortion of the CG"""

    bl_idname = "platelight.setup_lens"
    bl_label = "Set Up Lens Distortion"
    bl_options = {"REGISTER", "UNDO"}

    filepath: StringProperty(name="Calibration", description="Intrinsics file: JSON (fx, fy, cx, cy, "
                             "dist) or OpenCV YAML/XML (camera_matrix, distortion_coefficients)",
                             subtype="FILE_PATH")

    def invoke(self, context, event):
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}

    def execute(self, context):
        from ..addon.capture.intrinsics import load_calibration

        scene = context.scene
        camera = scene.camera
        if camera is None or camera.type != "CAMERA":
            self.report({"ERROR"}, "The scene has no camera; set up the plate and track it first.")
            return {"CANCELLED"}
        plate = find_plate_image(scene)
        if plate is None:
            self.report({"ERROR"}, "No plate found; run Set Up Plate (platelight.setup_plate) first.")
            return {"CANCELLED"}
        width, height = scene.render.resolution_x, scene.render.resolution_y
        wm = context.window_manager
        wm.progress_begin(0, max(1, scene.frame_end - scene.frame_start + 1))
        try:
            k = load_calibration(bpy.path.abspath(self.filepath))
            size = _calibration_size(bpy.path.abspath(self.filepath))
            if size and size != (width, height):
                raise PlateLightError(f"The calibration is for {size[0]}×{size[1]} images but the plate is "
                                      f"{width}×{height}; calibrate at the plate's size.")
            frame = apply_lens(scene, camera, k.fx, k.fy, k.cx, k.cy, k.dist, width, height,
                               progress=wm.progress_update)
        except PlateLightError as err:
            report_error(self, err)
            return {"CANCELLED"}
        finally:
            wm.progress_end()
        self.report({"INFO"}, f"Lens set: the CG is rendered with {100 * (1 / frame.scale - 1):.1f} % "
                    "overscan and redistorted onto the plate; run Set Up Composite to wire it.")
        return {"FINISHED"}


def _calibration_size(path):
    """(width, height) an OpenCV calibration file names, or None."""
    if path.lower().endswith(".json"):
        try:
            with open(path, encoding="utf-8") as fh:
                size = json.load(fh).get("image_size")
            return tuple(int(v) for v in size) if size else None
        except (OSError, ValueError, TypeError, AttributeError):
            return None
    import cv2

    fs = cv2.FileStorage(path, cv2.FILE_STORAGE_READ)
    w, h = fs.getNode("image_width"), fs.getNode("image_height")
    return (int(w.real()), int(h.real())) if not w.empty() and not h.empty() else None


classes = (PLATELIGHT_OT_setup_lens,)
