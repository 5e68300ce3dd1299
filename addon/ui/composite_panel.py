"""Scene properties > PlateLight Compositing: the plate, lights from the probe, the composite."""
import bpy

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
        plate = bpy.data.images.get("PlateLight Plate")
        col = layout.column(align=True)
        col.label(text=f"Plate: {plate.filepath if plate else 'none'}", icon="IMAGE_DATA")
        col.operator("platelight.setup_plate", icon="FILE_MOVIE")
        col = layout.column(align=True)
        col.label(text="Shadows from the probe", icon="LIGHT_SUN")
        row = col.row(align=True)
        row.operator("platelight.lights_from_probe", text="Sun Lamp + Sky").mode = "SUN_SKY"
        row.operator("platelight.lights_from_probe", text="Lamps Only").mode = "LIGHTS"
        col = layout.column(align=True)
        tree = scene.compositing_node_group
        col.label(text=f"Composite: {tree.name if tree else 'not set up'}", icon="NODE_COMPOSITING")
        row = col.row(align=True)
        row.operator("platelight.setup_composite", text="Shadow Catcher").method = "CATCHER"
        row.operator("platelight.setup_composite", text="Differential").method = "DIFFERENTIAL"


classes = (PLATELIGHT_PT_compositing,)


def register():
    register_classes(classes)


def unregister():
    unregister_classes(classes)
