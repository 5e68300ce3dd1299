"""Chrome-ball exposure brackets -> probe EXR -> the world's environment texture
(bpy.ops.platelight.capture_probe(files=..., directory=...))."""
import os

import bpy
from bpy.props import CollectionProperty, EnumProperty, FloatProperty, IntProperty, StringProperty

from .. import compat
from ..addon import names
from ..addon.wording import worded
from .common import NeedsScene, report_error



def _numbers(text: str, what: str, count=None):
    from ..addon.errors import PlateLightError
    from ..addon.wording import typed_numbers

    try:
        values = typed_numbers(text)
    except ValueError:
        raise PlateLightError(f"The {what} must be comma-separated numbers, not '{text}'.") from None
    if count is not None and len(values) != count:
        raise PlateLightError(f"The {what} needs {count} comma-separated numbers, not '{text}'.")
    return values


def _show_candidates(result) -> None:
    """The ball photo with the finder's circles as a Blender image (replaced on each run)."""
    import numpy as np

    from ..addon.capture.probe import candidates_picture

    picture = candidates_picture(result.photo, result.candidates, result.ball)
    h, w = picture.shape[:2]
    image = bpy.data.images.get(names.BALL_CANDIDATES_IMAGE)
    if image is not None and tuple(image.size) != (w, h):
        bpy.data.images.remove(image)
        image = None
    if image is None:
        image = bpy.data.images.new(names.BALL_CANDIDATES_IMAGE, w, h)
    rgba = np.ones((h, w, 4), np.float32)
    rgba[..., :3] = picture[::-1, :, ::-1] / 255.0      # Blender's rows go up, RGB
    image.pixels.foreach_set(rgba.ravel())
    image.update()


def _ball(text: str):
    """The Ball Circle field: CX,CY,R or, for an elliptical outline, CX,CY,RX,RY."""
    from ..addon.capture.mirror_ball import Ball
    from ..addon.errors import PlateLightError

    values = _numbers(text, "ball circle")
    if len(values) not in (3, 4):
        raise PlateLightError(f"The ball circle needs 3 comma-separated numbers (CX,CY,R) or 4 "
                              f"(CX,CY,RX,RY), not '{text}'.")
    return Ball(*values)


# How this operator's fields answer what a probe error asks for (PlateLightError.worded).
PROBE_FIELDS = {
    "ball": "the Ball Circle field (CX,CY,R in pixels)",
    "exposures": "the Exposure Times field (seconds, one per bracket)",
    "focal": "focal length (the Photo Lens field)",
    "grey_card": "the Grey Card field",
}


class PLATELIGHT_OT_capture_probe(NeedsScene, bpy.types.Operator):
    """Merge exposure brackets of a chrome ball into an HDR lat-long probe and light the world with it"""
    bl_idname = "platelight.capture_probe"
    bl_label = "Capture Probe"
    bl_options = {"REGISTER", "UNDO"}

    files: CollectionProperty(type=bpy.types.OperatorFileListElement, options={"HIDDEN", "SKIP_SAVE"})
    directory: StringProperty(subtype="DIR_PATH", options={"HIDDEN", "SKIP_SAVE"})
    filter_image: bpy.props.BoolProperty(default=True, options={"HIDDEN", "SKIP_SAVE"})
    exposures: StringProperty(name="Exposure Times",
                              description="Seconds per bracket in file-name order, e.g. 1/500,1/125,1/30 "
                                          "(empty: read from EXIF)", default="")
    ball: StringProperty(name="Ball Circle", description="CX,CY,R in pixels, or CX,CY,RX,RY for an elliptical "
                         "outline (empty: found automatically)",
                         default="")
    height: IntProperty(name="Probe Height", default=256, min=8, soft_max=2048)
    reflectance: FloatProperty(name="Ball Reflectance", default=1.0, min=0.01, max=1.0)
    rotate_z: FloatProperty(name="Rotation", description="Turn the probe about +Z to align it with the scene",
                            default=0.0, subtype="ANGLE")
    grey_card: StringProperty(name="Grey Card", description="X0,Y0,X1,Y1 pixel box of a grey card in the "
                              "photos: repairs light clipped in every bracket (e.g. the sun)", default="")
    card_albedo: FloatProperty(name="Card Albedo", default=0.18, min=0.01, max=1.0)
    align_marker_size: FloatProperty(name="Align Marker", description="Side of an ArUco marker (DICT_4X4_50) "
                                     "seen in the photos to align the probe with (0: off)",
                                     default=0.0, min=0.0, unit="LENGTH")
    photo_focal_mm: FloatProperty(name="Photo Lens", description="Focal length of the ball photos (for alignment)",
                                  default=50.0, min=1.0)
    photo_sensor_mm: FloatProperty(name="Photo Sensor", description="Sensor width of the ball photos",
                                   default=36.0, min=1.0)
    fill: EnumProperty(name="Unseen Directions", description="Where the frame cuts the ball, the directions "
                       "no pixel shows", items=(("nearest", "Nearest", "Copied from the nearest seen directions"),
                                                ("black", "Black", "Left black")), default="nearest")
    output: StringProperty(name="Probe File", description="Where the EXR goes (empty: probe.exr beside the brackets)",
                           default="", subtype="FILE_PATH")

    def invoke(self, context, event):
        context.window_manager.fileselect_add(self)
        return {"RUNNING_MODAL"}

    def execute(self, context):
        import math

        from ..addon.capture.probe import make_probe
        from ..addon.errors import PlateLightError
        from ..addon.exr_io import write_exr

        folder = bpy.path.abspath(self.directory)
        paths = [os.path.join(folder, f.name) for f in self.files if f.name]
        if not paths:
            self.report({"ERROR"}, "Select a photo of the chrome ball, or its exposure brackets.")
            return {"CANCELLED"}
        out = bpy.path.abspath(self.output) if self.output else os.path.join(folder, "probe.exr")
        wm = context.window_manager
        wm.progress_begin(0, 3)
        try:
            exposures = _numbers(self.exposures, "exposure times") if self.exposures.strip() else None
            ball = _ball(self.ball) if self.ball.strip() else None
            card = _numbers(self.grey_card, "grey card box", 4) if self.grey_card.strip() else None
            align, intrinsics = None, None
            if self.align_marker_size > 0:
                from ..addon.capture.intrinsics import Intrinsics
                from ..addon.capture.targets import MarkerTarget
                from ..addon.footage import read_image

                align = MarkerTarget("DICT_4X4_50", self.align_marker_size)
                if os.path.isfile(paths[0]):
                    h, w = read_image(paths[0]).shape[:2]
                    intrinsics = Intrinsics.from_lens(self.photo_focal_mm, self.photo_sensor_mm, w, h)
            wm.progress_update(1)
            result = make_probe(sorted(paths), exposures=exposures, ball=ball, height=self.height,
                                rotate_z_deg=math.degrees(self.rotate_z), reflectance=self.reflectance,
                                card_box=card, card_albedo=self.card_albedo, align_target=align,
                                intrinsics=intrinsics, fill=self.fill)
            wm.progress_update(2)
            write_exr(out, result.probe)
        except PlateLightError as err:
            report_error(self, err, PROBE_FIELDS)
            seen = getattr(err, "candidates", ())       # the finder's circles: to type into Ball Circle
            if ball is None and seen:
                seen = "; ".join(f"{f.cx:.0f},{f.cy:.0f},{f.radius:.0f} ({f.confidence:.2f})" for f in seen[:3])
                self.report({"INFO"}, f"Circles the finder saw (CX,CY,R and confidence): {seen}.")
            return {"CANCELLED"}
        finally:
            wm.progress_end()
        self._set_world(context, out)
        for warning in result.warnings:
            self.report({"WARNING"}, worded(warning, PROBE_FIELDS))
        from ..addon.capture.ball_finder import UNSURE_CONFIDENCE

        if result.ball.confidence is not None and result.ball.confidence < UNSURE_CONFIDENCE:
            _show_candidates(result)
            self.report({"WARNING"}, f"The circles the finder saw are drawn in the image "
                        f"'{names.BALL_CANDIDATES_IMAGE}' (Image Editor): the one used in green; set "
                        "Ball Circle in the operator's panel to use another.")
        b = result.ball
        self.report({"INFO"}, f"Probe from {len(paths)} photo(s) (ball at {b.cx:.0f}, {b.cy:.0f}, "
                              f"r {b.radius:.0f} px) -> {out}")
        return {"FINISHED"}

    def _set_world(self, context, path):
        scene = context.scene
        world = scene.world
        if world is None:
            world = compat.new_world(names.WORLD)
            scene.world = world
        nt = compat.node_tree(world)      # a 4.5 world made without nodes gets them
        background = next((n for n in nt.nodes if n.type == "BACKGROUND"), None) or nt.nodes.new("ShaderNodeBackground")
        output = next((n for n in nt.nodes if n.type == "OUTPUT_WORLD"), None) or nt.nodes.new("ShaderNodeOutputWorld")
        if not background.outputs["Background"].links:
            nt.links.new(background.outputs["Background"], output.inputs["Surface"])
        env = nt.nodes.get(names.WORLD_PROBE_NODE)
        if env is None:
            env = nt.nodes.new("ShaderNodeTexEnvironment")
            env.name = env.label = names.WORLD_PROBE_NODE
            env.location = (background.location.x - 300, background.location.y)
        image = bpy.data.images.load(path, check_existing=True)
        image.reload()
        image.colorspace_settings.name = "Linear Rec.709"
        env.image = image
        nt.links.new(env.outputs["Color"], background.inputs["Color"])
        scene.platelight.world_probe = path


classes = (PLATELIGHT_OT_capture_probe,)


def _menu_entry(self, context):
    self.layout.operator(PLATELIGHT_OT_capture_probe.bl_idname, text="Chrome Ball Brackets (PlateLight Probe)")


def register_extra():
    bpy.types.TOPBAR_MT_file_import.append(_menu_entry)


def unregister_extra():
    bpy.types.TOPBAR_MT_file_import.remove(_menu_entry)
