"""Track a printed marker / ChArUco board through the plate into the scene camera, and put a
phantom plane where the target lies (bpy.ops.platelight.track_markers)."""
import os

import bpy
from bpy.props import EnumProperty, FloatProperty, IntProperty, StringProperty
from mathutils import Matrix

from ..addon import names
from ..addon.compositing.lens import has_distortion
from ..addon.errors import PlateLightError
from .common import NeedsScene, report_error
from .lens import apply_lens, set_pinhole


_DICTIONARIES = ("DICT_4X4_50", "DICT_4X4_100", "DICT_4X4_250", "DICT_5X5_50", "DICT_5X5_100",
                 "DICT_6X6_50", "DICT_6X6_250", "DICT_7X7_50", "DICT_ARUCO_ORIGINAL", "DICT_APRILTAG_36h11")


def _plate_path(context) -> str:
    """The active movie clip's file (the plate), if any."""
    clip = context.scene.active_clip or (bpy.data.movieclips[0] if bpy.data.movieclips else None)
    if clip is None:
        return ""
    path = bpy.path.abspath(clip.filepath)
    # an image-sequence clip names its first image; the tracker takes the folder
    return os.path.dirname(path) if clip.source == "SEQUENCE" else path


def _clear_transform_keys(obj):
    """Remove an earlier track's location/rotation keys (Blender 5 layered actions), keeping
    any other animation of the camera (focus, lens...)."""
    from bpy_extras.anim_utils import action_get_channelbag_for_slot   # 4.4 and later

    anim = obj.animation_data
    bag = action_get_channelbag_for_slot(anim.action, anim.action_slot) if anim and anim.action else None
    if bag is None:
        return
    for fc in [fc for fc in bag.fcurves if fc.data_path in ("location", "rotation_quaternion",
                                                            "rotation_euler")]:
        bag.fcurves.remove(fc)


# How this operator's fields answer what a tracking error asks for (PlateLightError.worded).
TRACK_FIELDS = {
    "focal": "focal length (the Focal Length field)",
    "calibration": "calibration file (the Calibration field)",
    "dictionary": "Dictionary",
}


class PLATELIGHT_OT_track_markers(NeedsScene, bpy.types.Operator):
    """Track a printed ArUco marker or ChArUco board in the plate: key the scene camera and add a phantom plane on the marker"""
    bl_idname = "platelight.track_markers"
    bl_label = "Track Markers"
    bl_options = {"REGISTER", "UNDO"}

    filepath: StringProperty(name="Frames", description="Image folder or video file (default: the active movie clip)",
                             default="", subtype="FILE_PATH")
    target: EnumProperty(name="Target", items=(("MARKER", "Marker", "One square ArUco marker"),
                                               ("CHARUCO", "ChArUco Board", "A ChArUco board")), default="MARKER")
    dictionary: EnumProperty(name="Dictionary", items=[(d, d, "") for d in _DICTIONARIES], default="DICT_4X4_50")
    marker_size: FloatProperty(name="Marker Size", description="Printed marker side (black border)",
                               default=0.1, min=0.001, unit="LENGTH")
    square_size: FloatProperty(name="Square Size", description="ChArUco square side", default=0.04, min=0.001,
                               unit="LENGTH")
    squares_x: IntProperty(name="Squares X", default=5, min=2)
    squares_y: IntProperty(name="Squares Y", default=7, min=2)
    focal_mm: FloatProperty(name="Focal Length", description="Lens in mm (0: the scene camera's lens)",
                            default=0.0, min=0.0)
    sensor_mm: FloatProperty(name="Sensor Width", description="Sensor width in mm (0: the scene camera's)",
                             default=0.0, min=0.0)
    calibration: StringProperty(name="Calibration", description="Intrinsics file (JSON or OpenCV YAML); overrides the lens",
                                default="", subtype="FILE_PATH")
    lost: EnumProperty(name="Lost Frames", items=(("interpolate", "Interpolate", "Key interpolated poses"),
                                                  ("skip", "Leave Unkeyed", "No key where tracking is lost")),
                       default="interpolate")
    smooth: FloatProperty(name="Smoothing", description="Gaussian smoothing of the path, sigma in frames",
                          default=0.0, min=0.0, soft_max=10.0)

    def execute(self, context):
        from ..addon.capture.intrinsics import load_calibration
        from ..addon.capture.targets import CharucoTarget, MarkerTarget
        from ..addon.capture.tracking import track

        scene = context.scene
        source = bpy.path.abspath(self.filepath) if self.filepath else _plate_path(context)
        if not source:
            self.report({"ERROR"}, "No frames given and the scene has no movie clip to track.")
            return {"CANCELLED"}
        cam_data = scene.camera.data if scene.camera and scene.camera.type == "CAMERA" else None
        lens = self.focal_mm or (cam_data.lens if cam_data else 50.0)
        sensor = self.sensor_mm or (cam_data.sensor_width if cam_data else 36.0)
        wm = context.window_manager
        wm.progress_begin(0, 100)
        try:
            if self.target == "CHARUCO":
                target = CharucoTarget(self.dictionary, (self.squares_x, self.squares_y), self.square_size,
                                       self.marker_size)
            else:
                target = MarkerTarget(self.dictionary, self.marker_size)
            intrinsics = load_calibration(bpy.path.abspath(self.calibration)) if self.calibration else None
            result = track(source, target, intrinsics=intrinsics, lens_mm=lens, sensor_width_mm=sensor,
                           smooth_sigma=self.smooth, lost=self.lost,
                           progress=lambda i: wm.progress_update(i % 100))
        except PlateLightError as err:
            report_error(self, err, TRACK_FIELDS)
            return {"CANCELLED"}
        finally:
            wm.progress_end()

        # Only now, with every frame solved, is the scene changed.
        camera = self._camera(context, sensor)
        self._apply(scene, camera, result, sensor)
        intr = result.intrinsics
        if has_distortion(intr.dist_array()):
            try:   # the render camera sees the whole distorted frame; the compositor redistorts
                apply_lens(scene, camera, intr.fx, intr.fy, intr.cx, intr.cy, intr.dist_array(),
                           *result.image_size)
            except PlateLightError as err:
                self.report({"WARNING"}, f"The lens distortion is not carried into the scene: {err}")
        self._phantom_plane(context, result.target_extent)
        for warning in result.warnings:
            self.report({"WARNING"}, warning)
        self.report({"INFO"}, f"Tracked {result.tracked_count} of {len(result.frames)} frames into "
                              f"'{camera.name}' ({camera.data.lens:.1f} mm).")
        return {"FINISHED"}

    def _camera(self, context, sensor):
        scene = context.scene
        if scene.camera and scene.camera.type == "CAMERA":
            return scene.camera
        data = bpy.data.cameras.new(names.TRACK_CAMERA)
        camera = bpy.data.objects.new(names.TRACK_CAMERA, data)
        scene.collection.objects.link(camera)
        scene.camera = camera
        return camera

    def _apply(self, scene, camera, result, sensor):
        width, height = result.image_size
        intr = result.intrinsics
        scene.render.resolution_x, scene.render.resolution_y = width, height
        scene.render.resolution_percentage = 100
        cam = camera.data
        cam.type = "PERSP"
        cam.sensor_fit = "HORIZONTAL"
        cam.sensor_width = sensor
        set_pinhole(scene, cam, intr.fx, intr.fy, intr.cx, intr.cy, width, height)
        camera.rotation_mode = "QUATERNION"
        _clear_transform_keys(camera)
        first = scene.frame_start
        for entry in result.frames:
            if entry["camera_to_world"] is None:
                continue
            frame = first + entry["frame"] - 1
            camera.matrix_world = Matrix(entry["camera_to_world"])
            camera.keyframe_insert("location", frame=frame)
            camera.keyframe_insert("rotation_quaternion", frame=frame)
        scene.frame_end = first + len(result.frames) - 1
        scene.frame_set(first)

    def _phantom_plane(self, context, extent):
        scene = context.scene
        w, h = extent
        verts = [(-w / 2, -h / 2, 0), (w / 2, -h / 2, 0), (w / 2, h / 2, 0), (-w / 2, h / 2, 0)]
        plane = bpy.data.objects.get(names.MARKER_PLANE)
        if plane is None or plane.type != "MESH":
            mesh = bpy.data.meshes.new(names.MARKER_PLANE)
            plane = bpy.data.objects.new(names.MARKER_PLANE, mesh)
        else:
            mesh = plane.data
            mesh.clear_geometry()
        mesh.from_pydata(verts, [], [(0, 1, 2, 3)])
        mesh.update()
        if plane.name not in scene.collection.objects and not plane.users_collection:
            scene.collection.objects.link(plane)
        plane.matrix_world = Matrix.Identity(4)
        plane.platelight.phantom = True
        return plane

    def invoke(self, context, event):
        if not self.filepath and _plate_path(context):
            return self.execute(context)
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        for name in ("target", "dictionary", "marker_size"):
            layout.prop(self, name)
        if self.target == "CHARUCO":
            for name in ("square_size", "squares_x", "squares_y"):
                layout.prop(self, name)
        for name in ("focal_mm", "sensor_mm", "calibration", "lost", "smooth"):
            layout.prop(self, name)


classes = (PLATELIGHT_OT_track_markers,)


def _menu_entry(self, context):
    self.layout.operator(PLATELIGHT_OT_track_markers.bl_idname, text="PlateLight: Track Markers")


_MENUS = ("CLIP_MT_track", "VIEW3D_MT_view_cameras")


def register_extra():
    for name in _MENUS:
        getattr(bpy.types, name).append(_menu_entry)


def unregister_extra():
    for name in _MENUS:
        getattr(bpy.types, name).remove(_menu_entry)
