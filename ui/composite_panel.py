"""Scene properties > PlateLight Compositing: the plate and its camera track, the light probe,
lights from the probe, the composite; and the same tracking in the Movie Clip editor's sidebar."""
import bpy

from .. import compat
from ..addon import names
from .registration import register_classes, unregister_classes


class PLATELIGHT_PT_compositing(bpy.types.Panel):
    bl_label = "PlateLight Compositing"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "scene"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = self.layout
        scene = context.scene
        plate = bpy.data.images.get(names.PLATE_IMAGE)
        col = layout.column(align=True)
        col.label(text=f"Plate: {plate.filepath if plate else 'none'}", icon="IMAGE_DATA")
        col.operator("platelight.setup_plate", icon="FILE_MOVIE")
        col.operator("platelight.track_markers", text="Track Markers (ArUco / ChArUco)", icon="TRACKER")
        col.operator("platelight.setup_lens", text="Lens Distortion from Calibration", icon="CAMERA_DATA")
        col = layout.column(align=True)
        probe = scene.platelight.world_probe
        col.label(text=f"Light probe: {bpy.path.basename(probe) if probe else 'world texture'}",
                  icon="WORLD")
        col.operator("platelight.capture_probe", text="Probe from Chrome-Ball Brackets", icon="SHADING_RENDERED")
        col = layout.column(align=True)
        col.label(text="Shadows from the probe", icon="LIGHT_SUN")
        row = col.row(align=True)
        row.operator("platelight.lights_from_probe", text="Sun Lamp + Sky").mode = "SUN_SKY"
        row.operator("platelight.lights_from_probe", text="Lamps Only").mode = "LIGHTS"
        col = layout.column(align=True)
        tree = compat.compositor_tree(scene)
        col.label(text=f"Composite: {tree.name if tree else 'not set up'}", icon="NODE_COMPOSITING")
        col.prop(scene.platelight, "phantom_surface")
        col.operator("platelight.setup_composite", text="Set Up Composite", icon="NODE_COMPOSITING")
        row = col.row(align=True)
        row.operator("platelight.setup_composite", text="Shadow Catcher").method = "CATCHER"
        row.operator("platelight.setup_composite", text="Differential").method = "DIFFERENTIAL"
        row = col.row(align=True)      # a still CG under a moving camera: shadows baked once
        row.operator("platelight.bake_shadows", text="Bake Shadows", icon="LIGHT_SUN")
        row.operator("platelight.setup_composite", text="Baked Shadows").method = "BAKED"
        col.operator("platelight.match_grain", text="Match Grain", icon="MOD_NOISE")
        layout.operator("platelight.export_farm_job", icon="NETWORK_DRIVE")


class PLATELIGHT_PT_clip_tracking(bpy.types.Panel):
    bl_label = "PlateLight"
    bl_space_type = "CLIP_EDITOR"
    bl_region_type = "UI"
    bl_category = "Track"

    def draw(self, context):
        col = self.layout.column(align=True)
        col.operator("platelight.track_markers", text="Track Markers (ArUco / ChArUco)", icon="TRACKER")
        col.operator("platelight.setup_plate", text="Use as Plate", icon="FILE_MOVIE")


classes = (PLATELIGHT_PT_compositing, PLATELIGHT_PT_clip_tracking)


def register():
    register_classes(classes)


def unregister():
    unregister_classes(classes)
