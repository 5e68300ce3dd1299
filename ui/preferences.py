"""Global PlateLight preferences (Edit > Preferences > Add-ons > PlateLight)."""
import bpy
from bpy.props import BoolProperty, IntProperty

from .registration import register_classes, unregister_classes


class PlateLightPreferences(bpy.types.AddonPreferences):
    # The extension's module name ("bl_ext.<repo>.platelight"): the root package.
    bl_idname = __package__.rsplit(".addon", 1)[0]

    cache_bakes: BoolProperty(
        name="Skip Unchanged Bakes",
        description="Reuse a probe when nothing that affects it changed since the last bake",
        default=True,
    )
    threads: IntProperty(
        name="Bake Threads",
        description="Threads for probe renders and the bake's irradiance grids (0: all cores)",
        default=0, min=0, max=1024,
    )

    def draw(self, context):
        layout = self.layout
        layout.prop(self, "cache_bakes")
        layout.prop(self, "threads")


classes = (PlateLightPreferences,)


def register():
    register_classes(classes)


def unregister():
    unregister_classes(classes)
