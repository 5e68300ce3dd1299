"""Panels: Object properties > PlateLight (per-object settings, probe status, bake) and
Scene properties > PlateLight (probe render settings, world probe, bake all)."""
import bpy

from .registration import register_classes, unregister_classes

BAKE_OP = "platelight.bake_probes"
CHECK_OP = "platelight.check_probes"


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
        if settings.phantom:
            layout.prop(settings, "phantom_surface")
        col = layout.column()
        col.active = settings.enabled and not settings.phantom
        col.prop(settings, "probe_origin")
        col.prop(settings, "probe_dir")
        status = settings.probe_status
        icon = ("CHECKMARK" if status.startswith("baked") or status.startswith("world")
                or status.startswith("up to date")
                else "ERROR" if status in {"cancelled", "stale"} else "INFO")
        col.label(text=f"Probe: {status}", icon=icon)
        row = col.row(align=True)
        row.operator(BAKE_OP, text="Bake Selected", icon="LIGHTPROBE_SPHERE").all_objects = False
        op = row.operator(BAKE_OP, text="Re-bake", icon="FILE_REFRESH")
        op.all_objects, op.force = False, True
        row.operator(CHECK_OP, text="Check", icon="VIEWZOOM").all_objects = False


class PLATELIGHT_PT_scene(bpy.types.Panel):
    bl_label = "PlateLight"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "scene"

    def draw(self, context):
        layout = self.layout
        settings = context.scene.platelight
        layout.use_property_split = True
        for name in ("world_probe", "maps_dir", "pack_maps"):
            layout.prop(settings, name)
        col = layout.column(heading="Probes")
        for name in ("probe_height", "probe_auto_size", "probe_max_height", "probe_samples", "probe_fast_world", "probe_owner_shadows", "probe_parallax", "probe_behind", "probe_diffuse_parallax", "probe_sun_lobe", "probe_distance", "probe_reuse", "sampling", "glossy_lobes"):
            col.prop(settings, name)
        col = layout.column(align=True)
        col.operator(BAKE_OP, text="Bake All Probes (Current Frame)",
                     icon="LIGHTPROBE_SPHERE").all_objects = True
        op = col.operator(BAKE_OP, text="Bake All Probes (Frame Range)", icon="RENDER_ANIMATION")
        op.all_objects, op.use_frame_range = True, True
        op.frame_start, op.frame_end = context.scene.frame_start, context.scene.frame_end
        col.operator(CHECK_OP, text="Check All Probes", icon="VIEWZOOM").all_objects = True


classes = (PLATELIGHT_PT_object, PLATELIGHT_PT_scene)


def register():
    register_classes(classes)


def unregister():
    unregister_classes(classes)
