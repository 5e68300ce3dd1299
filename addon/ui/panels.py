"""Panels: Object properties > PlateLight (per-object settings) and Scene properties > PlateLight."""
import bpy

from .registration import register_classes, unregister_classes


class PLATELIGHT_PT_object(bpy.types.Panel):
    bl_label = "PlateLight"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "object"

    @classmethod
    def poll(cls, context):
        return context.object is not None

    def draw(self, context):
        layout = self.layout
        settings = context.object.platelight
        layout.use_property_split = True
        layout.prop(settings, "enabled")
        layout.prop(settings, "phantom")
        col = layout.column()
        col.active = settings.enabled
        col.prop(settings, "probe_origin")
        col.prop(settings, "probe_dir")
        col.label(text=f"Probe: {settings.probe_status}")


class PLATELIGHT_PT_scene(bpy.types.Panel):
    bl_label = "PlateLight"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "scene"

    def draw(self, context):
        layout = self.layout
        settings = context.scene.platelight
        layout.use_property_split = True
        for name in ("world_probe", "maps_dir", "probe_height", "probe_samples", "sampling"):
            layout.prop(settings, name)


classes = (PLATELIGHT_PT_object, PLATELIGHT_PT_scene)


def register():
    register_classes(classes)


def unregister():
    unregister_classes(classes)
